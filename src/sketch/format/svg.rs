//! `sketch.svg`: a polyline per curve and an ellipse per base, read back exactly.

use super::json::{json_of, FORMAT_NAME};
use super::*;

fn fmt_list<T: std::fmt::Display>(v: impl IntoIterator<Item = T>) -> String {
    v.into_iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(" ")
}

/// Lead-in and lead-out half steps around the centres: every curve draws at least 3
/// points (the importer needs 2), and the first segment gives the first axis.
fn curve_points(c: &Curve) -> Vec<[f32; 2]> {
    let mut pts = Vec::with_capacity(c.prims.len() + 2);
    let half = 0.5 * STEP;
    let (f, l) = (&c.prims[0], &c.prims[c.prims.len() - 1]);
    let [fx, fy] = on_chain(f);
    pts.push([fx - half * f.axis.cos(), fy - half * f.axis.sin()]);
    // The chain's points: an occluding line's offsets off it are in `data-shift`.
    pts.extend(c.prims.iter().map(on_chain));
    let [lx, ly] = on_chain(l);
    pts.push([lx + half * l.axis.cos(), ly + half * l.axis.sin()]);
    pts
}

/// `sketch.svg` of the quantised sketch: one `<polyline>` per curve (class `cz-a`..`cz-e`,
/// points the lead-in, the primitive centres and the lead-out; `data-dirs` the labels,
/// `data-sides` each primitive's side angles in degrees, `data-rho` its contrast), one
/// `<ellipse>` per shading base (1σ, `data-amp` its amplitude), the rest on the root
/// element's `data-*` attributes.
pub fn to_svg(s: &Sketch) -> String {
    let c = codes(s);
    let q = decode(&c);
    let j = json_of(&c);
    let (w, h) = (q.width, q.height);
    let mut out = String::new();
    out.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    out.push_str(&format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"{w}\" \
         height=\"{h}\" viewBox=\"0 0 {w} {h}\"\n     data-cz-format=\"{FORMAT_NAME}\" \
         data-cz-version=\"{VERSION}\" data-seed=\"{}\"\n     data-rho-off=\"{}\"\n     \
         data-shading-mean=\"{}\"\n     data-colour=\"{}\"{}>\n",
        q.seed,
        fmt_list(
            q.rho_off
                .weight
                .iter()
                .chain(&q.rho_off.mean)
                .chain(&q.rho_off.sigma)
        ),
        q.shading.mean,
        fmt_list(q.colour.uv.iter().flatten()),
        q.along_across
            .map(|t| format!("\n     data-along-across=\"{t}\""))
            .unwrap_or_default(),
    ));
    out.push_str(
        "  <title>coif sketch (Chen and Zhu 2006): curves a-e, shading ellipses</title>\n  \
         <style>\n    polyline { fill: none; stroke-width: 1.5; stroke-linejoin: round; }\n    \
         .cz-a { stroke: #1f77b4; } .cz-b { stroke: #2ca02c; } .cz-c { stroke: #d62728; }\n    \
         .cz-d { stroke: #9467bd; } .cz-e { stroke: #ff7f0e; }\n    \
         ellipse { fill: none; stroke-width: 0.75; stroke-dasharray: 3 2; }\n    \
         .cz-highlight { stroke: #bbbbbb; } .cz-shadow { stroke: #444444; }\n    \
         .cz-region { fill: #f3e9d8; stroke: #c8b89a; stroke-width: 0.5; }\n  </style>\n",
    );
    if !q.region.is_empty() {
        // The region under everything else; an editor may reshape it (polygons are read back
        // through M/L/H/V/C/Z commands and transforms, snapped to whole pixels).
        out.push_str(&format!(
            "  <path id=\"cz-region\" class=\"cz-region\" fill-rule=\"evenodd\" d=\"{}\"/>\n",
            q.region
                .iter()
                .map(|poly| {
                    let pts: Vec<String> =
                        poly.iter().map(|p| format!("{},{}", p[0], p[1])).collect();
                    format!("M {} Z", pts.join(" L "))
                })
                .collect::<Vec<_>>()
                .join(" ")
        ));
    }
    out.push_str("  <g id=\"cz-shading\">\n");
    for (b, jb) in q.shading.bases.iter().zip(&j.shading.bases) {
        out.push_str(&format!(
            "    <ellipse class=\"{}\" cx=\"{}\" cy=\"{}\" rx=\"{}\" ry=\"{}\" \
             transform=\"rotate({} {} {})\" data-amp=\"{}\"/>\n",
            if b.amp >= 0.0 {
                "cz-highlight"
            } else {
                "cz-shadow"
            },
            b.x,
            b.y,
            b.sx,
            b.sy,
            jb.theta,
            b.x,
            b.y,
            b.amp
        ));
    }
    out.push_str("  </g>\n  <g id=\"cz-curves\">\n");
    for (cv, jc) in q.curves.iter().zip(&j.curves) {
        // Version 4: an occluding line off its chain lists each primitive's offset.
        let shift = if cv.prims.iter().any(|p| p.shift != 0.0) {
            format!(
                " data-shift=\"{}\"",
                fmt_list(cv.prims.iter().map(|p| p.shift))
            )
        } else {
            String::new()
        };
        out.push_str(&format!(
            "    <polyline class=\"cz-{}\" data-dirs=\"{} {}\" data-sides=\"{}\" \
             data-rho=\"{}\"{shift}\n      points=\"{}\"/>\n",
            cv.kind.letter(),
            cv.dirs[0],
            cv.dirs[1],
            jc.prims
                .iter()
                .map(|p| format!("{},{}", p.sides[0], p.sides[1]))
                .collect::<Vec<_>>()
                .join(" "),
            fmt_list(cv.prims.iter().map(|p| p.rho)),
            curve_points(cv)
                .iter()
                .map(|p| format!("{},{}", p[0], p[1]))
                .collect::<Vec<_>>()
                .join(" "),
        ));
    }
    out.push_str("  </g>\n</svg>\n");
    out
}

fn numbers(s: &str, what: &str) -> std::result::Result<Vec<f64>, String> {
    s.split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{what}: \"{t}\" is not a number"))
        })
        .collect()
}

fn attr<'a>(
    n: roxmltree::Node<'a, '_>,
    name: &str,
    at: &str,
) -> std::result::Result<&'a str, String> {
    n.attribute(name)
        .ok_or_else(|| format!("{at} has no {name} attribute"))
}

fn counted(s: &str, what: &str, n: usize) -> std::result::Result<Vec<f64>, String> {
    let v = numbers(s, what)?;
    if v.len() != n {
        return Err(format!("{what} has {} numbers, expected {n}", v.len()));
    }
    Ok(v)
}

/// Nearest 15° step of the direction from `a` to `b`.
fn step_of(a: [f64; 2], b: [f64; 2]) -> i64 {
    let ang = (b[1] - a[1]).atan2(b[0] - a[0]);
    (ang / (PI / 12.0)).round() as i64
}

/// An affine map (a, b, c, d, e, f): (x, y) → (a x + c y + e, b x + d y + f), as SVG's.
type Affine = [f64; 6];

fn compose(m: &Affine, n: &Affine) -> Affine {
    [
        m[0] * n[0] + m[2] * n[1],
        m[1] * n[0] + m[3] * n[1],
        m[0] * n[2] + m[2] * n[3],
        m[1] * n[2] + m[3] * n[3],
        m[0] * n[4] + m[2] * n[5] + m[4],
        m[1] * n[4] + m[3] * n[5] + m[5],
    ]
}

fn apply(m: &Affine, p: [f64; 2]) -> [f64; 2] {
    [
        m[0] * p[0] + m[2] * p[1] + m[4],
        m[1] * p[0] + m[3] * p[1] + m[5],
    ]
}

/// Parses an SVG transform list (matrix, translate, scale, rotate, skewX, skewY).
fn parse_transform(t: &str) -> std::result::Result<Affine, String> {
    let mut m: Affine = [1.0, 0.0, 0.0, 1.0, 0.0, 0.0];
    let mut rest = t.trim();
    while !rest.is_empty() {
        let open = rest
            .find('(')
            .ok_or_else(|| format!("transform \"{t}\": expected name(numbers)"))?;
        let close = rest[open..]
            .find(')')
            .ok_or_else(|| format!("transform \"{t}\": missing ')'"))?
            + open;
        let name = rest[..open].trim().trim_start_matches(',').trim();
        let v = numbers(&rest[open + 1..close], &format!("transform \"{t}\""))?;
        let bad = || format!("transform \"{t}\": {name} with {} numbers", v.len());
        let rad = |a: f64| a * PI / 180.0;
        let op: Affine = match (name, v.len()) {
            ("matrix", 6) => [v[0], v[1], v[2], v[3], v[4], v[5]],
            ("translate", 1) => [1.0, 0.0, 0.0, 1.0, v[0], 0.0],
            ("translate", 2) => [1.0, 0.0, 0.0, 1.0, v[0], v[1]],
            ("scale", 1) => [v[0], 0.0, 0.0, v[0], 0.0, 0.0],
            ("scale", 2) => [v[0], 0.0, 0.0, v[1], 0.0, 0.0],
            ("rotate", 1 | 3) => {
                let (s, c) = rad(v[0]).sin_cos();
                let r = [c, s, -s, c, 0.0, 0.0];
                if v.len() == 3 {
                    let to = [1.0, 0.0, 0.0, 1.0, v[1], v[2]];
                    let back = [1.0, 0.0, 0.0, 1.0, -v[1], -v[2]];
                    compose(&compose(&to, &r), &back)
                } else {
                    r
                }
            }
            ("skewX", 1) => [1.0, 0.0, rad(v[0]).tan(), 1.0, 0.0, 0.0],
            ("skewY", 1) => [1.0, rad(v[0]).tan(), 0.0, 1.0, 0.0, 0.0],
            _ => return Err(bad()),
        };
        m = compose(&m, &op);
        rest = rest[close + 1..].trim();
    }
    Ok(m)
}

/// The transform from an element's coordinates to the root's (its own and its ancestors',
/// as an editor's moves leave them).
fn transform_of(n: roxmltree::Node) -> std::result::Result<Affine, String> {
    let mut m: Affine = [1.0, 0.0, 0.0, 1.0, 0.0, 0.0];
    let chain: Vec<roxmltree::Node> = n.ancestors().filter(|a| a.is_element()).collect();
    // Outermost first; the root <svg> has no transform attribute.
    for a in chain.iter().rev() {
        if let Some(t) = a.attribute("transform") {
            m = compose(&m, &parse_transform(t)?);
        }
    }
    Ok(m)
}

fn parse_svg(text: &str) -> std::result::Result<Sketch, String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| format!("malformed XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "svg" {
        return Err(format!(
            "not an SVG file: the root element is <{}>",
            root.tag_name().name()
        ));
    }
    if root.attribute("data-cz-format") != Some(FORMAT_NAME) {
        return Err(
            "not a coif sketch: the <svg> element has no data-cz-format=\"coif-sketch\"".into(),
        );
    }
    let version = root.attribute("data-cz-version").unwrap_or("");
    if !(1..=VERSION).any(|v| version == v.to_string()) {
        return Err(format!(
            "unsupported sketch version \"{version}\" (this build reads 1 to {VERSION})"
        ));
    }
    let int = |name: &str| -> std::result::Result<u64, String> {
        let t = attr(root, name, "<svg>")?;
        t.trim()
            .parse::<u64>()
            .map_err(|_| format!("<svg> {name}=\"{t}\" is not a whole number"))
    };
    let (w, h, seed) = (int("width")?, int("height")?, int("data-seed")?);
    if w == 0 || h == 0 || w > u32::MAX as u64 || h > u32::MAX as u64 {
        return Err(format!("<svg> has an unusable size {w}x{h}"));
    }
    let (w, h) = (w as u32, h as u32);
    let r = counted(attr(root, "data-rho-off", "<svg>")?, "data-rho-off", 6)?;
    let mean = counted(
        attr(root, "data-shading-mean", "<svg>")?,
        "data-shading-mean",
        1,
    )?[0];
    let col = counted(
        attr(root, "data-colour", "<svg>")?,
        "data-colour",
        2 * COLOUR_BINS,
    )?;
    // Optional (version 3): absent, no grain.
    let along_across = match root.attribute("data-along-across") {
        None => None,
        Some(t) => match t.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Some(v as f32),
            _ => {
                return Err(format!(
                    "<svg> data-along-across=\"{t}\" is not a positive number"
                ))
            }
        },
    };
    let mut curves = Vec::new();
    let mut bases = Vec::new();
    let mut region = Vec::new();
    for n in root.descendants().filter(|n| n.is_element()) {
        match n.tag_name().name() {
            "path"
                if n.attribute("class")
                    .is_some_and(|c| c.split_whitespace().any(|c| c == "cz-region")) =>
            {
                let at = format!("the region (line {})", doc.text_pos_at(n.range().start).row);
                let m = transform_of(n).map_err(|e| format!("{at}: {e}"))?;
                for poly in path_polygons(attr(n, "d", &at)?).map_err(|e| format!("{at}: {e}"))? {
                    let mut out = Vec::with_capacity(poly.len());
                    for p in poly {
                        let q = apply(&m, p);
                        if !(q[0].is_finite() && q[1].is_finite())
                            || q[0] < -0.5
                            || q[1] < -0.5
                            || q[0] > w as f64 + 0.5
                            || q[1] > h as f64 + 0.5
                        {
                            return Err(format!(
                                "{at}: the point ({}, {}) lies outside the {w}x{h} image",
                                q[0], q[1]
                            ));
                        }
                        out.push([q[0].round().max(0.0) as u32, q[1].round().max(0.0) as u32]);
                    }
                    region.push(out);
                }
            }
            "polyline" => {
                let at = format!(
                    "curve {} (line {})",
                    curves.len(),
                    doc.text_pos_at(n.range().start).row
                );
                let class = attr(n, "class", &at)?;
                let kind = class
                    .split_whitespace()
                    .find_map(|c| {
                        c.strip_prefix("cz-")
                            .filter(|k| k.len() == 1)
                            .and_then(|k| k.chars().next())
                            .and_then(Kind::from_letter)
                    })
                    .ok_or_else(|| format!("{at}: class \"{class}\" names no kind cz-a..cz-e"))?;
                let m = transform_of(n).map_err(|e| format!("{at}: {e}"))?;
                let d = counted(attr(n, "data-dirs", &at)?, &format!("{at}: data-dirs"), 2)?;
                let dirs = [d[0], d[1]].map(|v| v.signum() as i8 * (v != 0.0) as i8);
                let pts = numbers(attr(n, "points", &at)?, &format!("{at}: points"))?;
                if pts.len() % 2 != 0 || pts.len() < 6 {
                    return Err(format!(
                        "{at}: points needs a lead-in point, the centres and a lead-out point \
                         ({} numbers)",
                        pts.len()
                    ));
                }
                let pts: Vec<[f64; 2]> = pts.chunks(2).map(|c| apply(&m, [c[0], c[1]])).collect();
                let np = pts.len() - 2;
                let sides = counted(
                    attr(n, "data-sides", &at)?,
                    &format!("{at}: data-sides"),
                    2 * np,
                )?;
                let rho = counted(attr(n, "data-rho", &at)?, &format!("{at}: data-rho"), np)?;
                // Optional (version 4): absent, on the chain.
                let shift = match n.attribute("data-shift") {
                    None => vec![0.0; np],
                    Some(_) if kind != Kind::Occluding => {
                        return Err(format!(
                            "{at}: data-shift on a curve of kind {}; only occluding lines \
                             (cz-c) lie off their chains",
                            kind.letter()
                        ))
                    }
                    Some(t) => counted(t, &format!("{at}: data-shift"), np)?,
                };
                let mut prims = Vec::new();
                let mut prev = 0i64;
                for k in 0..np {
                    let a = step_of(pts[k], pts[k + 1]);
                    if k > 0 {
                        let t = (a - prev).rem_euclid(24);
                        if t != 0 && t != 1 && t != 23 {
                            return Err(format!(
                                "{at}, primitive {k}: the curve turns by {}°; it turns by \
                                 −15°, 0 or +15° per primitive",
                                if t > 12 { t - 24 } else { t } * 15
                            ));
                        }
                    }
                    prev = a;
                    let code = exact_shift_code(shift[k]).map_err(|e| {
                        format!("{at}, primitive {k}: data-shift {}: {e}", shift[k])
                    })?;
                    let axis = axis_of(a.rem_euclid(24) as u8);
                    let [x, y] = off_chain(pts[k + 1][0] as f32, pts[k + 1][1] as f32, axis, code);
                    prims.push(Primitive {
                        shift: shift_of(code),
                        x,
                        y,
                        axis,
                        rho: rho[k] as f32,
                        side: [deg_to_rad(sides[2 * k]), deg_to_rad(sides[2 * k + 1])],
                    });
                }
                curves.push(Curve { kind, prims, dirs });
            }
            "ellipse" => {
                let at = format!(
                    "shading base {} (line {})",
                    bases.len(),
                    doc.text_pos_at(n.range().start).row
                );
                let num = |name: &str| -> std::result::Result<f64, String> {
                    Ok(counted(attr(n, name, &at)?, &format!("{at}: {name}"), 1)?[0])
                };
                let m = transform_of(n).map_err(|e| format!("{at}: {e}"))?;
                let (cx, cy) = (num("cx")?, num("cy")?);
                let c = apply(&m, [cx, cy]);
                // The ellipse's own axes through the transforms: θ along its x axis.
                let ax = [m[0], m[1]];
                let ay = [m[2], m[3]];
                let theta = ax[1].atan2(ax[0]).rem_euclid(PI);
                bases.push(Base {
                    x: c[0] as f32,
                    y: c[1] as f32,
                    theta: theta as f32,
                    sx: (num("rx")? * ax[0].hypot(ax[1])) as f32,
                    sy: (num("ry")? * ay[0].hypot(ay[1])) as f32,
                    amp: num("data-amp")? as f32,
                });
            }
            _ => {}
        }
    }
    let sketch = Sketch {
        width: w,
        height: h,
        seed,
        curves,
        rho_off: RhoPrior {
            weight: [r[0] as f32, r[1] as f32],
            mean: [r[2] as f32, r[3] as f32],
            sigma: [r[4] as f32, r[5] as f32],
        },
        shading: Shading {
            mean: mean as f32,
            bases,
        },
        colour: ColourMap {
            uv: col.chunks(2).map(|c| [c[0] as f32, c[1] as f32]).collect(),
        },
        region,
        along_across,
    };
    Ok(quantise(&sketch))
}

/// The closed polygons of an SVG path's `d`: M/L/H/V/C/Z in absolute or relative form
/// (what Inkscape writes for an edited polygon); a cubic is flattened to 8 chords. Each
/// subpath is one polygon, closed whether or not it ends with Z.
fn path_polygons(d: &str) -> std::result::Result<Vec<Vec<[f64; 2]>>, String> {
    let mut toks: Vec<String> = Vec::new();
    let mut cur = String::new();
    for ch in d.chars() {
        let starts_number = (ch == '-' || ch == '+') && !cur.ends_with(['e', 'E']);
        if ch.is_ascii_alphabetic() && ch != 'e' && ch != 'E' {
            if !cur.is_empty() {
                toks.push(std::mem::take(&mut cur));
            }
            toks.push(ch.to_string());
        } else if ch == ',' || ch.is_whitespace() {
            if !cur.is_empty() {
                toks.push(std::mem::take(&mut cur));
            }
        } else if starts_number && !cur.is_empty()
            || ch == '.' && cur.contains('.') && !cur.ends_with(['e', 'E'])
        {
            toks.push(std::mem::take(&mut cur));
            cur.push(ch);
        } else {
            cur.push(ch);
        }
    }
    if !cur.is_empty() {
        toks.push(cur);
    }
    let mut polys: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut poly: Vec<[f64; 2]> = Vec::new();
    let (mut pos, mut start) = ([0.0f64; 2], [0.0f64; 2]);
    let mut cmd = ' ';
    let mut i = 0;
    let num = |i: &mut usize| -> std::result::Result<f64, String> {
        let t = toks
            .get(*i)
            .ok_or("the path ends in the middle of a command")?;
        *i += 1;
        t.parse::<f64>()
            .map_err(|_| format!("\"{t}\" in the path is not a number"))
    };
    let close = |poly: &mut Vec<[f64; 2]>, polys: &mut Vec<Vec<[f64; 2]>>| {
        if poly.len() >= 3 {
            polys.push(std::mem::take(poly));
        } else {
            poly.clear();
        }
    };
    while i < toks.len() {
        if let Some(c) = toks[i].chars().next().filter(|c| c.is_ascii_alphabetic()) {
            cmd = c;
            i += 1;
            if c == 'Z' || c == 'z' {
                close(&mut poly, &mut polys);
                pos = start;
                continue;
            }
        } else if cmd == ' ' {
            return Err("the path does not start with a command".into());
        }
        let rel = cmd.is_ascii_lowercase();
        let base = if rel { pos } else { [0.0, 0.0] };
        match cmd.to_ascii_uppercase() {
            'M' => {
                close(&mut poly, &mut polys);
                pos = [base[0] + num(&mut i)?, base[1] + num(&mut i)?];
                start = pos;
                poly.push(pos);
                // Pairs after a moveto are linetos.
                cmd = if rel { 'l' } else { 'L' };
            }
            'L' => {
                pos = [base[0] + num(&mut i)?, base[1] + num(&mut i)?];
                poly.push(pos);
            }
            'H' => {
                pos[0] = if rel { pos[0] } else { 0.0 } + num(&mut i)?;
                poly.push(pos);
            }
            'V' => {
                pos[1] = if rel { pos[1] } else { 0.0 } + num(&mut i)?;
                poly.push(pos);
            }
            'C' => {
                let mut c = [[0.0; 2]; 3];
                for p in &mut c {
                    *p = [base[0] + num(&mut i)?, base[1] + num(&mut i)?];
                }
                let p0 = pos;
                for k in 1..=8 {
                    let t = k as f64 / 8.0;
                    let u = 1.0 - t;
                    let b = [u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t];
                    poly.push([0, 1].map(|a| {
                        b[0] * p0[a] + b[1] * c[0][a] + b[2] * c[1][a] + b[3] * c[2][a]
                    }));
                }
                pos = c[2];
            }
            other => {
                return Err(format!(
                    "the region path uses the command '{other}'; it must be made of straight \
                     lines and cubic curves (M, L, H, V, C, Z): convert it with Path > Object to Path"
                ))
            }
        }
    }
    close(&mut poly, &mut polys);
    Ok(polys)
}

/// Reads `sketch.svg` text; `path` names it in errors. Curves are read from the polylines'
/// points through any transforms an editor added (snapped to the lattice, so a curve moved
/// in Inkscape moves), their labels, side angles and contrasts from the data attributes;
/// bases from the ellipses' geometry and `data-amp`. The sketch is checked by [`validate`].
pub fn from_svg(text: &str, path: &Path) -> Result<Sketch> {
    let s = parse_svg(text).map_err(|m| Error::bad_file(path, m))?;
    validate(&s, path)?;
    Ok(s)
}
