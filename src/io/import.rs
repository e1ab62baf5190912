//! Strokes drawn in other tools, converted to `strokes.json` ([`Strokes`]).
//!
//! * labelme JSON: `linestrip` and `line` shapes become strokes, points in drawing order;
//!   label "background" (any case) gives a background stroke, every other label a direction
//!   stroke. Other shape types (polygons, rectangles, points ...) are skipped with a warning.
//! * SVG: `<polyline>` and `<path>` elements made of straight segments. `class` containing
//!   `background` or `data-kind="background"` gives a background stroke; `data-kind` may
//!   also name any other stroke kind (direction, comb, cut); the default is direction. Each
//!   subpath of a `<path>` is one stroke. `transform` attributes on the element and its
//!   ancestors are applied, as is the root `viewBox` when the root also gives a pixel
//!   `width` and `height`. Curves are rejected: resample them to line segments first.
//!
//! Coordinates are taken as image pixels (top-left origin, x right, y down), which is what
//! both tools use when the drawing is made over the image at its natural size.

use crate::error::{Error, Result};
use crate::io::annot::{Stroke, StrokeKind, Strokes};
use std::path::Path;

/// Imports a labelme (`.json`) or SVG (`.svg`) file, chosen by extension.
pub fn import_strokes(path: &Path) -> Result<Strokes> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("json") => strokes_from_labelme(path),
        Some("svg") => strokes_from_svg(path),
        _ => Err(Error::bad_file(
            path,
            "cannot tell the stroke format: expected a .json (labelme) or .svg file",
        )),
    }
}

/// Strokes for an image of `size`: a `strokes.json` (version 1), or strokes drawn elsewhere,
/// an `.svg` or a labelme `.json` (told apart from `strokes.json` by its "shapes"). The
/// file is read once, so a pipe (`/dev/stdin`, `<(...)`) works; without a `.svg` or `.json`
/// extension, text starting with `<` is taken as SVG.
pub fn load_strokes(path: &Path, size: (u32, u32)) -> Result<Strokes> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    // Not text (a PNG given as strokes) is a bad file, not a failed read.
    let text = read_text(path)?;
    let svg = ext == "svg"
        || (ext != "json"
            && text
                .trim_start_matches('\u{feff}')
                .trim_start()
                .starts_with('<'));
    let imported = if svg {
        Some(svg_strokes_from_str(&text, path)?)
    } else {
        let labelme = serde_json::from_str::<serde_json::Value>(&text)
            .ok()
            .is_some_and(|v| v.get("shapes").is_some() && v.get("strokes").is_none());
        if labelme {
            Some(labelme_from_str(&text, path)?)
        } else {
            None
        }
    };
    match imported {
        Some(s) => {
            s.validate(Some(size))
                .map_err(|m| Error::bad_file(path, m))?;
            Ok(s)
        }
        None => Strokes::parse(&text, path, Some(size)),
    }
}

fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    String::from_utf8(bytes).map_err(|e| {
        Error::bad_file(
            path,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

/// Checks a finished stroke list: at least one stroke, all coordinates finite in f32.
fn finish(path: &Path, strokes: Vec<Stroke>, none_msg: &str) -> Result<Strokes> {
    if strokes.is_empty() {
        return Err(Error::bad_file(path, none_msg));
    }
    let s = Strokes::new(strokes);
    s.validate(None).map_err(|m| Error::bad_file(path, m))?;
    Ok(s)
}

// ----------------------------------------------------------------------------------------
// labelme

/// Reads the line strips of a labelme annotation file.
pub fn strokes_from_labelme(path: &Path) -> Result<Strokes> {
    labelme_from_str(&read_text(path)?, path)
}

/// Parses labelme annotation text; `path` names the file in errors.
pub fn labelme_from_str(text: &str, path: &Path) -> Result<Strokes> {
    let bad = |m: String| Error::bad_file(path, m);
    let v: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        let mut m = format!("malformed JSON: {e}");
        // Python's json module writes NaN/Infinity, which JSON (and serde) reject.
        let line = text.lines().nth(e.line().saturating_sub(1)).unwrap_or("");
        if line.contains("NaN") || line.contains("Infinity") {
            m.push_str(" (coordinates must be finite: NaN and Infinity are not JSON)");
        }
        bad(m)
    })?;
    let shapes = v
        .get("shapes")
        .and_then(|s| s.as_array())
        .ok_or_else(|| bad("not a labelme file: no \"shapes\" array at the top level".into()))?;
    let mut out = Vec::new();
    let mut skipped: Vec<String> = Vec::new();
    for (i, sh) in shapes.iter().enumerate() {
        let label = sh.get("label").and_then(|l| l.as_str()).unwrap_or("");
        let what = format!("shape {i} (label \"{label}\")");
        // labelme omits shape_type for polygons in old files.
        let ty = sh
            .get("shape_type")
            .and_then(|t| t.as_str())
            .unwrap_or("polygon");
        if ty != "linestrip" && ty != "line" {
            skipped.push(format!("{i} ({ty})"));
            continue;
        }
        let pts = sh
            .get("points")
            .and_then(|p| p.as_array())
            .ok_or_else(|| bad(format!("{what}: no \"points\" array")))?;
        let mut points = Vec::with_capacity(pts.len());
        for (j, p) in pts.iter().enumerate() {
            let xy = p
                .as_array()
                .filter(|a| a.len() == 2)
                .and_then(|a| Some([a[0].as_f64()?, a[1].as_f64()?]))
                .ok_or_else(|| bad(format!("{what}, point {j}: expected [x, y], found {p}")))?;
            let q = [xy[0] as f32, xy[1] as f32];
            if !q[0].is_finite() || !q[1].is_finite() {
                return Err(bad(format!(
                    "{what}, point {j}: [{}, {}] is not a finite 32-bit number",
                    xy[0], xy[1]
                )));
            }
            points.push(q);
        }
        if points.len() < 2 {
            return Err(bad(format!(
                "{what} has {} point(s); a stroke needs at least 2",
                points.len()
            )));
        }
        let kind = if label.eq_ignore_ascii_case("background") {
            StrokeKind::Background
        } else {
            StrokeKind::Direction
        };
        out.push(Stroke::new(kind, points));
    }
    if !skipped.is_empty() {
        log::warn!(
            "{}: skipped shapes that are not line strips: {}",
            path.display(),
            skipped.join(", ")
        );
    }
    finish(
        path,
        out,
        "no usable shapes: strokes must be labelme \"linestrip\" or \"line\" shapes",
    )
}

// ----------------------------------------------------------------------------------------
// SVG

/// 2-D affine map [a c e; b d f] as in SVG's `matrix(a b c d e f)`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Affine([f64; 6]);

impl Affine {
    const ID: Affine = Affine([1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);

    /// `self` after `o`: (self * o)(p) = self(o(p)).
    fn then_inner(self, o: Affine) -> Affine {
        let [a, b, c, d, e, f] = self.0;
        let [a2, b2, c2, d2, e2, f2] = o.0;
        Affine([
            a * a2 + c * b2,
            b * a2 + d * b2,
            a * c2 + c * d2,
            b * c2 + d * d2,
            a * e2 + c * f2 + e,
            b * e2 + d * f2 + f,
        ])
    }

    fn apply(self, p: [f64; 2]) -> [f64; 2] {
        let [a, b, c, d, e, f] = self.0;
        [a * p[0] + c * p[1] + e, b * p[0] + d * p[1] + f]
    }
}

/// Where an element is, for messages: `<path id="x"> (line 12)`.
fn describe(doc: &roxmltree::Document, n: roxmltree::Node) -> String {
    let pos = doc.text_pos_at(n.range().start);
    match n.attribute("id") {
        Some(id) => format!("<{} id=\"{id}\"> (line {})", n.tag_name().name(), pos.row),
        None => format!("<{}> (line {})", n.tag_name().name(), pos.row),
    }
}

/// Splits an SVG number list ("1,2 3-4.5.5e1") into numbers.
fn parse_numbers(s: &str) -> std::result::Result<Vec<f64>, String> {
    let mut out = Vec::new();
    let b = s.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_whitespace() || b[i] == b',' {
            i += 1;
            continue;
        }
        let (v, len) = scan_number(&s[i..]).ok_or_else(|| {
            format!(
                "expected a number at \"{}\"",
                s[i..].chars().take(12).collect::<String>()
            )
        })?;
        out.push(v);
        i += len;
    }
    Ok(out)
}

/// The longest SVG number at the start of `s`: sign, digits, one '.', exponent.
fn scan_number(s: &str) -> Option<(f64, usize)> {
    let b = s.as_bytes();
    let mut i = 0;
    if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
        i += 1;
    }
    let mut digits = 0;
    while i < b.len() && b[i].is_ascii_digit() {
        i += 1;
        digits += 1;
    }
    if i < b.len() && b[i] == b'.' {
        i += 1;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
            digits += 1;
        }
    }
    if digits == 0 {
        return None;
    }
    if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
        let mut j = i + 1;
        if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
            j += 1;
        }
        let start = j;
        while j < b.len() && b[j].is_ascii_digit() {
            j += 1;
        }
        if j > start {
            i = j;
        }
    }
    s[..i].parse().ok().map(|v| (v, i))
}

/// Parses a `transform` attribute (a list, applied right to left as SVG specifies).
fn parse_transform(s: &str) -> std::result::Result<Affine, String> {
    let mut m = Affine::ID;
    let mut rest = s.trim();
    while !rest.is_empty() {
        let open = rest
            .find('(')
            .ok_or_else(|| format!("malformed transform \"{s}\""))?;
        let close = rest[open..]
            .find(')')
            .map(|c| c + open)
            .ok_or_else(|| format!("malformed transform \"{s}\": missing ')'"))?;
        let name = rest[..open].trim().trim_start_matches(',').trim();
        let args =
            parse_numbers(&rest[open + 1..close]).map_err(|e| format!("transform \"{s}\": {e}"))?;
        let bad_args = || format!("transform \"{s}\": wrong number of arguments to {name}");
        let t = match (name, args.len()) {
            ("matrix", 6) => Affine([args[0], args[1], args[2], args[3], args[4], args[5]]),
            ("translate", 1) => Affine([1.0, 0.0, 0.0, 1.0, args[0], 0.0]),
            ("translate", 2) => Affine([1.0, 0.0, 0.0, 1.0, args[0], args[1]]),
            ("scale", 1) => Affine([args[0], 0.0, 0.0, args[0], 0.0, 0.0]),
            ("scale", 2) => Affine([args[0], 0.0, 0.0, args[1], 0.0, 0.0]),
            ("rotate", 1 | 3) => {
                let (sn, cs) = args[0].to_radians().sin_cos();
                let r = Affine([cs, sn, -sn, cs, 0.0, 0.0]);
                if args.len() == 3 {
                    let (cx, cy) = (args[1], args[2]);
                    Affine([1.0, 0.0, 0.0, 1.0, cx, cy])
                        .then_inner(r)
                        .then_inner(Affine([1.0, 0.0, 0.0, 1.0, -cx, -cy]))
                } else {
                    r
                }
            }
            ("skewX", 1) => Affine([1.0, 0.0, args[0].to_radians().tan(), 1.0, 0.0, 0.0]),
            ("skewY", 1) => Affine([1.0, args[0].to_radians().tan(), 0.0, 1.0, 0.0, 0.0]),
            ("matrix" | "translate" | "scale" | "rotate" | "skewX" | "skewY", _) => {
                return Err(bad_args())
            }
            _ => return Err(format!("transform \"{s}\": unknown function \"{name}\"")),
        };
        m = m.then_inner(t);
        rest = rest[close + 1..].trim_start();
    }
    Ok(m)
}

/// A length in user units: plain number or "px". Other units cannot be mapped to pixels.
fn parse_px(s: &str) -> Option<f64> {
    let t = s.trim();
    let t = t.strip_suffix("px").unwrap_or(t).trim();
    t.parse().ok()
}

/// The map from root user space (the viewBox) to image pixels.
fn root_transform(root: roxmltree::Node) -> std::result::Result<Affine, String> {
    let Some(vb) = root.attribute("viewBox") else {
        return Ok(Affine::ID);
    };
    let v = parse_numbers(vb).map_err(|e| format!("viewBox \"{vb}\": {e}"))?;
    if v.len() != 4 || v[2] <= 0.0 || v[3] <= 0.0 {
        return Err(format!(
            "viewBox \"{vb}\" must be four numbers with positive width and height"
        ));
    }
    let (w, h) =
        match (root.attribute("width"), root.attribute("height")) {
            // Without a viewport size the viewBox is the pixel frame itself.
            (None, None) => return Ok(Affine([1.0, 0.0, 0.0, 1.0, 0.0, 0.0])),
            (Some(w), Some(h)) => match (parse_px(w), parse_px(h)) {
                (Some(w), Some(h)) if w > 0.0 && h > 0.0 => (w, h),
                _ => {
                    return Err(format!(
                        "width=\"{w}\" height=\"{h}\" with a viewBox: only pixel sizes \
                     (plain numbers or px) can be mapped to image pixels"
                    ))
                }
            },
            _ => return Err(
                "a viewBox with only one of width/height is not supported; give both or neither"
                    .into(),
            ),
        };
    let (sx, sy) = (w / v[2], h / v[3]);
    let par = root
        .attribute("preserveAspectRatio")
        .unwrap_or("xMidYMid meet")
        .trim();
    match par {
        "none" => Ok(Affine([sx, 0.0, 0.0, sy, -v[0] * sx, -v[1] * sy])),
        "xMidYMid" | "xMidYMid meet" => {
            let s = sx.min(sy);
            let tx = (w - v[2] * s) / 2.0 - v[0] * s;
            let ty = (h - v[3] * s) / 2.0 - v[1] * s;
            Ok(Affine([s, 0.0, 0.0, s, tx, ty]))
        }
        _ => Err(format!(
            "preserveAspectRatio=\"{par}\" is not supported (use the default or \"none\")"
        )),
    }
}

/// Subpaths of a path `d` made of straight segments, in user units.
fn parse_path(d: &str) -> std::result::Result<Vec<Vec<[f64; 2]>>, String> {
    let mut subpaths: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut cur: Vec<[f64; 2]> = Vec::new();
    let mut pos = [0.0f64; 2];
    let mut start = [0.0f64; 2];
    let mut started = false;
    // After Z, `cur` holds only the implicit start of a possible next subpath.
    let mut after_z = false;
    let b = d.as_bytes();
    let mut i = 0;
    let mut nums: Vec<f64> = Vec::new();
    // Reads the numbers after a command letter (up to the next letter).
    let read_args = |i: &mut usize, nums: &mut Vec<f64>| -> std::result::Result<(), String> {
        nums.clear();
        while *i < b.len() {
            let c = b[*i];
            if c.is_ascii_whitespace() || c == b',' {
                *i += 1;
            } else if c.is_ascii_alphabetic() && c != b'e' && c != b'E' {
                break;
            } else {
                let (v, len) = scan_number(&d[*i..]).ok_or_else(|| {
                    format!(
                        "expected a number at \"{}\"",
                        d[*i..].chars().take(12).collect::<String>()
                    )
                })?;
                nums.push(v);
                *i += len;
            }
        }
        Ok(())
    };
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_whitespace() || c == b',' {
            i += 1;
            continue;
        }
        if !c.is_ascii_alphabetic() {
            return Err(format!(
                "expected a command letter at \"{}\"",
                d[i..].chars().take(12).collect::<String>()
            ));
        }
        i += 1;
        read_args(&mut i, &mut nums)?;
        let rel = c.is_ascii_lowercase();
        let up = c.to_ascii_uppercase();
        if !started && up != b'M' {
            return Err(format!(
                "path data must start with M, found '{}'",
                c as char
            ));
        }
        started = true;
        if after_z && up == b'M' {
            cur.clear();
        }
        after_z = false;
        match up {
            b'M' | b'L' => {
                if nums.is_empty() || !nums.len().is_multiple_of(2) {
                    return Err(format!(
                        "'{}' needs coordinate pairs, found {} number(s)",
                        c as char,
                        nums.len()
                    ));
                }
                for (k, xy) in nums.chunks(2).enumerate() {
                    let p = if rel {
                        [pos[0] + xy[0], pos[1] + xy[1]]
                    } else {
                        [xy[0], xy[1]]
                    };
                    if up == b'M' && k == 0 {
                        // A new subpath; pairs after the first are implicit line-tos.
                        if !cur.is_empty() {
                            subpaths.push(std::mem::take(&mut cur));
                        }
                        start = p;
                    }
                    cur.push(p);
                    pos = p;
                }
            }
            b'H' | b'V' => {
                if nums.is_empty() {
                    return Err(format!("'{}' needs at least one number", c as char));
                }
                for &v in &nums {
                    let axis = (up == b'V') as usize;
                    pos[axis] = if rel { pos[axis] + v } else { v };
                    cur.push(pos);
                }
            }
            b'Z' => {
                if !nums.is_empty() {
                    return Err("'Z' takes no numbers".into());
                }
                if !cur.is_empty() && cur.last() != Some(&start) {
                    cur.push(start);
                }
                // Drawing may continue from the start point without a new M.
                if !cur.is_empty() {
                    subpaths.push(std::mem::take(&mut cur));
                }
                pos = start;
                cur.push(start);
                after_z = true;
            }
            b'C' | b'S' | b'Q' | b'T' | b'A' => {
                return Err(format!(
                    "curve command '{}' is not supported; convert curves to line segments \
                     (e.g. Inkscape: Extensions > Modify Path > Flatten Beziers)",
                    c as char
                ));
            }
            _ => return Err(format!("unknown path command '{}'", c as char)),
        }
    }
    if !cur.is_empty() && !after_z {
        subpaths.push(cur);
    }
    Ok(subpaths)
}

/// Kind from `data-kind` or `class`; `data-kind` wins when both are present.
fn svg_kind(n: roxmltree::Node) -> std::result::Result<StrokeKind, String> {
    if let Some(k) = n.attribute("data-kind") {
        let k = k.trim().to_ascii_lowercase();
        return StrokeKind::ALL
            .iter()
            .copied()
            .find(|s| s.name() == k)
            .ok_or_else(|| {
                format!("data-kind=\"{k}\" is not one of direction, background, comb, cut")
            });
    }
    let bg = n.attribute("class").is_some_and(|c| {
        c.split_whitespace()
            .any(|t| t.eq_ignore_ascii_case("background"))
    });
    Ok(if bg {
        StrokeKind::Background
    } else {
        StrokeKind::Direction
    })
}

/// Containers whose content is never drawn directly.
const NOT_RENDERED: [&str; 7] = [
    "defs", "clipPath", "mask", "symbol", "pattern", "marker", "metadata",
];

/// Reads the straight-segment polylines and paths of an SVG drawing.
pub fn strokes_from_svg(path: &Path) -> Result<Strokes> {
    svg_strokes_from_str(&read_text(path)?, path)
}

/// Parses SVG text into strokes; `path` names the file in errors.
pub fn svg_strokes_from_str(text: &str, path: &Path) -> Result<Strokes> {
    let bad = |m: String| Error::bad_file(path, m);
    let doc = roxmltree::Document::parse(text).map_err(|e| bad(format!("malformed XML: {e}")))?;
    let root = doc.root_element();
    if root.tag_name().name() != "svg" {
        return Err(bad(format!(
            "not an SVG file: the root element is <{}>",
            root.tag_name().name()
        )));
    }
    let base = root_transform(root).map_err(|m| bad(format!("<svg>: {m}")))?;
    let mut out = Vec::new();
    let mut ignored = 0usize;
    for n in root.descendants().filter(|n| n.is_element()) {
        let name = n.tag_name().name();
        if name != "polyline" && name != "path" {
            if matches!(
                name,
                "line" | "polygon" | "rect" | "circle" | "ellipse" | "use"
            ) {
                ignored += 1;
            }
            continue;
        }
        if n.ancestors()
            .any(|a| NOT_RENDERED.contains(&a.tag_name().name()))
        {
            continue;
        }
        // A coif sketch's hair region is an area, not a stroke.
        if n.attribute("class")
            .is_some_and(|c| c.split_whitespace().any(|c| c == "cz-region"))
        {
            continue;
        }
        let at = describe(&doc, n);
        if n.ancestors()
            .skip(1)
            .any(|a| a.is_element() && a.tag_name().name() == "svg" && a != root)
        {
            return Err(bad(format!(
                "{at}: nested <svg> elements are not supported"
            )));
        }
        // Current transform: root viewBox, then each ancestor's transform, outermost first.
        let mut m = base;
        let chain: Vec<roxmltree::Node> = n.ancestors().collect();
        for a in chain.iter().rev() {
            if let Some(t) = a.attribute("transform") {
                let t =
                    parse_transform(t).map_err(|e| bad(format!("{}: {e}", describe(&doc, *a))))?;
                m = m.then_inner(t);
            }
        }
        let kind = svg_kind(n).map_err(|e| bad(format!("{at}: {e}")))?;
        let parts: Vec<Vec<[f64; 2]>> = if name == "polyline" {
            let pts = n.attribute("points").unwrap_or("");
            let v = parse_numbers(pts).map_err(|e| bad(format!("{at}: points: {e}")))?;
            if !v.len().is_multiple_of(2) {
                return Err(bad(format!(
                    "{at}: points has an odd count of numbers ({})",
                    v.len()
                )));
            }
            vec![v.chunks(2).map(|c| [c[0], c[1]]).collect()]
        } else {
            let d = n.attribute("d").unwrap_or("");
            parse_path(d).map_err(|e| bad(format!("{at}: {e}")))?
        };
        if parts.is_empty() {
            return Err(bad(format!("{at} has no points")));
        }
        for (k, part) in parts.iter().enumerate() {
            let sub = if parts.len() > 1 {
                format!(" subpath {}", k + 1)
            } else {
                String::new()
            };
            if part.len() < 2 {
                return Err(bad(format!(
                    "{at}{sub} has {} point(s); a stroke needs at least 2",
                    part.len()
                )));
            }
            let mut points = Vec::with_capacity(part.len());
            for (j, p) in part.iter().enumerate() {
                let q = m.apply(*p);
                let q = [q[0] as f32, q[1] as f32];
                if !q[0].is_finite() || !q[1].is_finite() {
                    return Err(bad(format!(
                        "{at}{sub}, point {j}: [{}, {}] is not a finite 32-bit number",
                        q[0], q[1]
                    )));
                }
                points.push(q);
            }
            out.push(Stroke::new(kind, points));
        }
    }
    if ignored > 0 {
        log::warn!(
            "{}: ignored {ignored} element(s) other than <polyline> and <path>",
            path.display()
        );
    }
    finish(
        path,
        out,
        "no usable strokes: found no <polyline> or <path> elements",
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn data(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name)
    }

    fn err_of(r: Result<Strokes>, path: &Path) -> String {
        let m = r.unwrap_err().to_string();
        assert!(m.starts_with(&path.display().to_string()), "{m}");
        m
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn close(a: [f32; 2], b: [f32; 2]) -> bool {
        (a[0] - b[0]).abs() < 1e-3 && (a[1] - b[1]).abs() < 1e-3
    }

    #[test]
    fn labelme_file() {
        let s = import_strokes(&data("labelme_strokes.json")).unwrap();
        // polygon and point shapes are skipped; linestrips and a line stay, in file order.
        assert_eq!(s.version, crate::io::annot::FORMAT_VERSION);
        let kinds: Vec<StrokeKind> = s.strokes.iter().map(|s| s.kind).collect();
        assert_eq!(
            kinds,
            [
                StrokeKind::Direction,
                StrokeKind::Direction,
                StrokeKind::Background,
                StrokeKind::Background
            ]
        );
        assert_eq!(
            s.strokes[0].points,
            vec![[200.0, 40.0], [230.5, 30.0], [260.0, 45.25]]
        );
        assert_eq!(s.strokes[1].points, vec![[150.0, 60.0], [140.0, 120.0]]);
        assert_eq!(s.strokes[3].points.len(), 3);
        // Saved and reloaded, it is a valid strokes.json.
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("strokes.json");
        s.save(&out).unwrap();
        assert_eq!(Strokes::load(&out, Some((512, 512))).unwrap(), s);
    }

    #[test]
    fn labelme_errors() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let shape = |pts: &str| {
            format!(
                r#"{{"version":"5.4.1","shapes":[{{"label":"hair","shape_type":"linestrip","points":{pts}}}]}}"#
            )
        };
        let p = write(d, "a.json", "{\"shapes\": [");
        assert!(err_of(strokes_from_labelme(&p), &p).contains("malformed JSON"));
        let p = write(d, "b.json", r#"{"imagePath":"x.png"}"#);
        assert!(err_of(strokes_from_labelme(&p), &p).contains("no \"shapes\""));
        let p = write(
            d,
            "c.json",
            r#"{"shapes":[{"label":"x","shape_type":"polygon","points":[[0,0],[1,1],[2,0]]}]}"#,
        );
        assert!(err_of(strokes_from_labelme(&p), &p).contains("no usable shapes"));
        let p = write(d, "d.json", &shape("[[1,2]]"));
        let m = err_of(strokes_from_labelme(&p), &p);
        assert!(m.contains("shape 0 (label \"hair\") has 1 point(s)"), "{m}");
        let p = write(d, "e.json", &shape("[[1,NaN],[3,4]]"));
        let m = err_of(strokes_from_labelme(&p), &p);
        assert!(m.contains("malformed JSON") && m.contains("NaN"), "{m}");
        let p = write(d, "f.json", &shape("[[1,2],[3,1e300]]"));
        let m = err_of(strokes_from_labelme(&p), &p);
        assert!(m.contains("point 1") && m.contains("not a finite"), "{m}");
        let p = write(d, "g.json", &shape("[[1,2],[3]]"));
        let m = err_of(strokes_from_labelme(&p), &p);
        assert!(m.contains("point 1: expected [x, y]"), "{m}");
    }

    #[test]
    fn svg_file() {
        let s = import_strokes(&data("svg_strokes.svg")).unwrap();
        let got: Vec<(StrokeKind, Vec<[f32; 2]>)> = s
            .strokes
            .iter()
            .map(|s| (s.kind, s.points.clone()))
            .collect();
        let want: Vec<(StrokeKind, Vec<[f32; 2]>)> = vec![
            // polyline, no transform
            (
                StrokeKind::Direction,
                vec![[200.0, 40.0], [230.0, 30.0], [260.0, 45.0]],
            ),
            // path with implicit lineto after M, then relative l, h, v
            (
                StrokeKind::Direction,
                vec![
                    [100.0, 100.0],
                    [110.0, 120.0],
                    [120.0, 140.0],
                    [130.0, 140.0],
                    [130.0, 150.0],
                ],
            ),
            // class="stroke background", inside <g transform="translate(10,20)">
            (StrokeKind::Background, vec![[20.0, 30.0], [60.0, 30.0]]),
            // data-kind="background", scale(2) inside the translated group
            (StrokeKind::Background, vec![[12.0, 24.0], [14.0, 28.0]]),
            // relative m with implicit relative lineto and Z: two subpaths
            (
                StrokeKind::Direction,
                vec![
                    [300.0, 300.0],
                    [310.0, 300.0],
                    [310.0, 310.0],
                    [300.0, 300.0],
                ],
            ),
            (StrokeKind::Direction, vec![[300.0, 300.0], [290.0, 290.0]]),
            // matrix transform
            (StrokeKind::Direction, vec![[5.0, 7.0], [5.0, 9.0]]),
        ];
        assert_eq!(got.len(), want.len(), "{got:?}");
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!(g.0, w.0, "stroke {i}");
            assert_eq!(g.1.len(), w.1.len(), "stroke {i}: {:?}", g.1);
            for (a, b) in g.1.iter().zip(&w.1) {
                assert!(close(*a, *b), "stroke {i}: {:?} vs {:?}", g.1, w.1);
            }
        }
    }

    #[test]
    fn svg_viewbox_maps_to_pixels() {
        let dir = tempfile::tempdir().unwrap();
        // A 100x50 user space shown in a 200x100 px viewport: everything doubles.
        let p = write(
            dir.path(),
            "v.svg",
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="200px" height="100" viewBox="10 0 100 50">
               <polyline points="10,0 60,25"/></svg>"#,
        );
        let s = strokes_from_svg(&p).unwrap();
        assert_eq!(s.strokes[0].points, vec![[0.0, 0.0], [100.0, 50.0]]);
        // Non-uniform fit is centred (xMidYMid meet): scale 1, 50 px margin in x.
        let p = write(
            dir.path(),
            "w.svg",
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="200" height="100" viewBox="0 0 100 100">
               <polyline points="0,0 100,100"/></svg>"#,
        );
        let s = strokes_from_svg(&p).unwrap();
        assert_eq!(s.strokes[0].points, vec![[50.0, 0.0], [150.0, 100.0]]);
        let p = write(
            dir.path(),
            "x.svg",
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="20cm" height="10cm" viewBox="0 0 100 50">
               <polyline points="0,0 1,1"/></svg>"#,
        );
        let m = err_of(strokes_from_svg(&p), &p);
        assert!(m.contains("only pixel sizes"), "{m}");
    }

    #[test]
    fn svg_errors() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let svg = |body: &str| {
            format!(
                r#"<svg xmlns="http://www.w3.org/2000/svg" width="64" height="64">{body}</svg>"#
            )
        };
        let p = write(d, "a.svg", "<svg><path d='M0 0 L1 1'></svg>");
        assert!(err_of(strokes_from_svg(&p), &p).contains("malformed XML"));
        let p = write(
            d,
            "b.svg",
            &svg(r#"<rect x="0" y="0" width="5" height="5"/>"#),
        );
        assert!(err_of(strokes_from_svg(&p), &p).contains("no usable strokes"));
        let p = write(
            d,
            "c.svg",
            &svg("\n<path id=\"curl\" d=\"M 0 0 C 10 0 10 10 20 20\"/>"),
        );
        let m = err_of(strokes_from_svg(&p), &p);
        assert!(
            m.contains("<path id=\"curl\"> (line 2)") && m.contains("curve command 'C'"),
            "{m}"
        );
        for (cmd, d_attr) in [
            ('q', "M0 0 q 5 5 10 0"),
            ('A', "M0 0 A 5 5 0 0 1 10 0"),
            ('s', "M0 0 s 5 5 10 0"),
            ('T', "M0 0 T 10 0"),
        ] {
            let p = write(d, "d.svg", &svg(&format!("<path d=\"{d_attr}\"/>")));
            let m = err_of(strokes_from_svg(&p), &p);
            assert!(m.contains(&format!("curve command '{cmd}'")), "{m}");
        }
        let p = write(d, "e.svg", &svg(r#"<polyline points="1,2"/>"#));
        let m = err_of(strokes_from_svg(&p), &p);
        assert!(m.contains("<polyline> (line 1) has 1 point(s)"), "{m}");
        let p = write(d, "f.svg", &svg(r#"<polyline points="1,2 3"/>"#));
        assert!(err_of(strokes_from_svg(&p), &p).contains("odd count"));
        let p = write(d, "g.svg", &svg(r#"<polyline points="1,2 3,NaN"/>"#));
        let m = err_of(strokes_from_svg(&p), &p);
        assert!(m.contains("expected a number at \"NaN\""), "{m}");
        let p = write(d, "h.svg", &svg(r#"<polyline points="1,2 3,4e300"/>"#));
        let m = err_of(strokes_from_svg(&p), &p);
        assert!(m.contains("point 1") && m.contains("not a finite"), "{m}");
        let p = write(
            d,
            "i.svg",
            &svg(r#"<g transform="shear(2)"><polyline points="1,2 3,4"/></g>"#),
        );
        let m = err_of(strokes_from_svg(&p), &p);
        assert!(
            m.contains("<g> (line 1)") && m.contains("unknown function \"shear\""),
            "{m}"
        );
        let p = write(d, "j.svg", &svg(r#"<path d="L 1 1 2 2"/>"#));
        assert!(err_of(strokes_from_svg(&p), &p).contains("must start with M"));
        let p = write(d, "k.svg", &svg(r#"<path d="M 1 1 M 2 2 L 3 3"/>"#));
        let m = err_of(strokes_from_svg(&p), &p);
        assert!(m.contains("subpath 1 has 1 point(s)"), "{m}");
        let p = write(
            d,
            "l.svg",
            &svg(r#"<polyline data-kind="hair" points="1,2 3,4"/>"#),
        );
        assert!(err_of(strokes_from_svg(&p), &p).contains("data-kind=\"hair\""));
        let p = write(d, "m.xml", "<html/>");
        assert!(err_of(import_strokes(&p), &p).contains("expected a .json"));
        let p = write(d, "n.svg", "<html/>");
        assert!(err_of(strokes_from_svg(&p), &p).contains("root element is <html>"));
    }

    #[test]
    fn svg_skips_unrendered_and_supports_rotate() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            dir.path(),
            "r.svg",
            r#"<svg xmlns="http://www.w3.org/2000/svg">
                 <defs><path id="tpl" d="M 0 0 C 1 1 2 2 3 3"/></defs>
                 <polyline transform="rotate(90 10 10)" points="10,10 20,10"/>
               </svg>"#,
        );
        let s = strokes_from_svg(&p).unwrap();
        assert_eq!(s.strokes.len(), 1, "the curve in <defs> is not drawn");
        assert!(close(s.strokes[0].points[0], [10.0, 10.0]));
        // x right, y down: rotating +x by 90 degrees points down the image.
        assert!(
            close(s.strokes[0].points[1], [10.0, 20.0]),
            "{:?}",
            s.strokes[0].points
        );
    }

    #[test]
    fn number_scanning() {
        assert_eq!(
            parse_numbers("1,2 3-4.5.5e1 -.5E-1").unwrap(),
            vec![1.0, 2.0, 3.0, -4.5, 5.0, -0.05]
        );
        assert!(parse_numbers("1 x").is_err());
        let p = parse_path("M1-2l3.5.5zm1 1").unwrap();
        assert_eq!(p[0], vec![[1.0, -2.0], [4.5, -1.5], [1.0, -2.0]]);
        assert_eq!(p[1], vec![[2.0, -1.0]]);
    }
}
