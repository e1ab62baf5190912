//! User annotation files: direction strokes (`strokes.json`) and face landmarks
//! (`landmarks.json`), both format version 1. JSON Schemas live in `schemas/`.
//!
//! Coordinates are image pixels with the origin at the top-left corner, x to the right and
//! y down. Pixel (i, j) covers [i, i+1) x [j, j+1), so its centre is (i + 0.5, j + 0.5) and
//! a point is inside a W x H image when 0 <= x <= W and 0 <= y <= H.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// The only format version this build reads and writes.
pub const FORMAT_VERSION: u32 = 1;

/// What a stroke tells. Only `Direction` is used today; the others are reserved so that files
/// written by later tools still load.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StrokeKind {
    /// Hair growth direction, points ordered root -> tip.
    Direction,
    Background,
    Comb,
    Cut,
}

impl StrokeKind {
    pub const ALL: [StrokeKind; 4] = [
        StrokeKind::Direction,
        StrokeKind::Background,
        StrokeKind::Comb,
        StrokeKind::Cut,
    ];

    pub fn name(self) -> &'static str {
        match self {
            StrokeKind::Direction => "direction",
            StrokeKind::Background => "background",
            StrokeKind::Comb => "comb",
            StrokeKind::Cut => "cut",
        }
    }
}

impl std::fmt::Display for StrokeKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One polyline; for `Direction` the points run from root to tip.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stroke {
    pub kind: StrokeKind,
    pub points: Vec<[f32; 2]>,
    /// The brush's radius in pixels, for segmentation (the pixels within it of the polyline
    /// are sure hair or sure background); absent: the segmentation's default (4 px). A thin
    /// brush lets a corrective stroke fit a narrow strip the mask got wrong.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    /// A direction stroke's pixels are hair as drawn, even where the colour models call
    /// them background (segmentation otherwise leaves the pixels of a stroke that mostly
    /// looks like background to the models, taking it for a slip of the hand). For a
    /// corrective stroke on hair the mask missed, whose colours no other stroke shows.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub sure: bool,
}

/// The largest brush radius a stroke may carry, px.
pub const MAX_STROKE_RADIUS: f32 = 64.0;

impl Stroke {
    /// A stroke with the default brush.
    pub fn new(kind: StrokeKind, points: Vec<[f32; 2]>) -> Stroke {
        Stroke {
            kind,
            points,
            radius: None,
            sure: false,
        }
    }
}

/// Contents of `strokes.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Strokes {
    pub version: u32,
    pub strokes: Vec<Stroke>,
}

/// The landmark names every `landmarks.json` must have (left/right as seen in the image).
pub const REQUIRED_LANDMARKS: [&str; 6] = [
    "left_eye",
    "right_eye",
    "nose_tip",
    "mouth_left",
    "mouth_right",
    "chin",
];

/// Contents of `landmarks.json`: the six required points plus any extra named ones.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Landmarks {
    pub version: u32,
    pub landmarks: BTreeMap<String, [f32; 2]>,
}

impl Strokes {
    pub fn new(strokes: Vec<Stroke>) -> Self {
        Strokes {
            version: FORMAT_VERSION,
            strokes,
        }
    }

    /// Reads and validates a strokes file; with `image_size` = (width, height), points must
    /// lie inside the image.
    pub fn load(path: &Path, image_size: Option<(u32, u32)>) -> Result<Strokes> {
        let text = read_text(path)?;
        Self::parse(&text, path, image_size)
    }

    /// Parses and validates strokes JSON; `path` only names the source in messages.
    pub fn parse(text: &str, path: &Path, image_size: Option<(u32, u32)>) -> Result<Strokes> {
        let bad = |m: String| Error::bad_file(path, m);
        let value = parse_value(text).map_err(bad)?;
        check_version(&value).map_err(bad)?;
        // Name the stroke for an unknown kind; serde alone would give only a line number.
        if let Some(list) = value.get("strokes").and_then(|s| s.as_array()) {
            for (i, s) in list.iter().enumerate() {
                if let Some(k) = s.get("kind").and_then(|k| k.as_str()) {
                    if !StrokeKind::ALL.iter().any(|v| v.name() == k) {
                        return Err(bad(format!(
                            "stroke {i}: unknown kind \"{k}\" (expected one of {})",
                            kind_list()
                        )));
                    }
                }
            }
        }
        let s: Strokes = serde_json::from_str(text).map_err(|e| bad(json_error(text, &e)))?;
        s.validate(image_size).map_err(bad)?;
        Ok(s)
    }

    /// Checks stroke lengths, finiteness and (optionally) the image bounds.
    pub fn validate(&self, image_size: Option<(u32, u32)>) -> std::result::Result<(), String> {
        if self.version != FORMAT_VERSION {
            return Err(version_msg(self.version as u64));
        }
        for (i, s) in self.strokes.iter().enumerate() {
            if s.points.len() < 2 {
                return Err(format!(
                    "stroke {i} ({}) has {} point(s); a stroke needs at least 2",
                    s.kind,
                    s.points.len()
                ));
            }
            for (j, p) in s.points.iter().enumerate() {
                check_point(p, image_size).map_err(|m| format!("stroke {i}, point {j}: {m}"))?;
            }
            if let Some(r) = s.radius {
                if !(r.is_finite() && r > 0.0 && r <= MAX_STROKE_RADIUS) {
                    return Err(format!(
                        "stroke {i} ({}): radius {r} is not a brush radius (a number of \
                         pixels above 0 and at most {MAX_STROKE_RADIUS})",
                        s.kind
                    ));
                }
            }
            // A stroke within one pixel gives no direction on the pixel grid it is drawn on.
            let len: f64 = s
                .points
                .windows(2)
                .map(|q| f64::from(q[1][0] - q[0][0]).hypot(f64::from(q[1][1] - q[0][1])))
                .sum();
            if len < 1.0 {
                let why = if len == 0.0 {
                    format!("zero length: all its {} points are equal", s.points.len())
                } else {
                    format!("only {len:.3} px long")
                };
                return Err(format!(
                    "stroke {i} ({}) is degenerate ({why}); a stroke must span at least 1 pixel",
                    s.kind
                ));
            }
        }
        Ok(())
    }

    /// Writes the strokes as pretty JSON (one point per line pair), atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        self.validate(None)
            .map_err(|m| Error::Invalid(format!("cannot save {}: {m}", path.display())))?;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{{\n  \"version\": {},\n  \"strokes\": [",
            self.version
        );
        for (i, s) in self.strokes.iter().enumerate() {
            let pts: Vec<String> = s.points.iter().map(|p| fmt_point(*p)).collect();
            // The optional fields, only where set: files without them stay as they were.
            let mut extra = s
                .radius
                .map(|r| format!(",\n      \"radius\": {r}"))
                .unwrap_or_default();
            if s.sure {
                extra.push_str(",\n      \"sure\": true");
            }
            let _ = write!(
                out,
                "    {{\n      \"kind\": \"{}\",\n      \"points\": [{}]{extra}\n    }}{}\n",
                s.kind,
                pts.join(", "),
                if i + 1 < self.strokes.len() { "," } else { "" }
            );
        }
        out.push_str("  ]\n}\n");
        crate::io::write_atomic(path, out.as_bytes())
    }
}

impl Landmarks {
    pub fn new(landmarks: BTreeMap<String, [f32; 2]>) -> Self {
        Landmarks {
            version: FORMAT_VERSION,
            landmarks,
        }
    }

    /// The named point, if present.
    pub fn get(&self, name: &str) -> Option<[f32; 2]> {
        self.landmarks.get(name).copied()
    }

    /// Reads and validates a landmarks file; with `image_size` = (width, height), points must
    /// lie inside the image.
    pub fn load(path: &Path, image_size: Option<(u32, u32)>) -> Result<Landmarks> {
        let text = read_text(path)?;
        Self::parse(&text, path, image_size)
    }

    /// Parses and validates landmarks JSON; `path` only names the source in messages.
    pub fn parse(text: &str, path: &Path, image_size: Option<(u32, u32)>) -> Result<Landmarks> {
        let bad = |m: String| Error::bad_file(path, m);
        let value = parse_value(text).map_err(bad)?;
        check_version(&value).map_err(bad)?;
        let l: Landmarks = serde_json::from_str(text).map_err(|e| bad(json_error(text, &e)))?;
        l.validate(image_size).map_err(bad)?;
        Ok(l)
    }

    /// Checks that the required names are present and all points are finite (and inside the
    /// image when its size is given).
    pub fn validate(&self, image_size: Option<(u32, u32)>) -> std::result::Result<(), String> {
        if self.version != FORMAT_VERSION {
            return Err(version_msg(self.version as u64));
        }
        let missing: Vec<&str> = REQUIRED_LANDMARKS
            .iter()
            .copied()
            .filter(|n| !self.landmarks.contains_key(*n))
            .collect();
        if !missing.is_empty() {
            return Err(format!(
                "missing landmark(s): {} (required: {})",
                missing.join(", "),
                REQUIRED_LANDMARKS.join(", ")
            ));
        }
        for (name, p) in &self.landmarks {
            check_point(p, image_size).map_err(|m| format!("landmark \"{name}\": {m}"))?;
        }
        Ok(())
    }

    /// Writes the landmarks as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        self.validate(None)
            .map_err(|m| Error::Invalid(format!("cannot save {}: {m}", path.display())))?;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{{\n  \"version\": {},\n  \"landmarks\": {{",
            self.version
        );
        let n = self.landmarks.len();
        for (i, (name, p)) in self.landmarks.iter().enumerate() {
            let key = serde_json::to_string(name).unwrap_or_default();
            let comma = if i + 1 < n { "," } else { "" };
            let _ = writeln!(out, "    {key}: {}{comma}", fmt_point(*p));
        }
        out.push_str("  }\n}\n");
        crate::io::write_atomic(path, out.as_bytes())
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

fn kind_list() -> String {
    StrokeKind::ALL
        .iter()
        .map(|k| k.name())
        .collect::<Vec<_>>()
        .join(", ")
}

fn fmt_point(p: [f32; 2]) -> String {
    // serde_json prints the shortest text that reads back to the same f32.
    let x = serde_json::to_string(&p[0]).unwrap_or_default();
    let y = serde_json::to_string(&p[1]).unwrap_or_default();
    format!("[{x}, {y}]")
}

fn version_msg(v: u64) -> String {
    format!("version {v} is not supported; this coif reads version {FORMAT_VERSION}")
}

fn parse_value(text: &str) -> std::result::Result<serde_json::Value, String> {
    let v: serde_json::Value = serde_json::from_str(text).map_err(|e| json_error(text, &e))?;
    if !v.is_object() {
        return Err("expected a JSON object at the top level".into());
    }
    Ok(v)
}

fn check_version(v: &serde_json::Value) -> std::result::Result<(), String> {
    match v.get("version") {
        None => Err(format!(
            "missing \"version\"; this coif reads version {FORMAT_VERSION}"
        )),
        Some(x) => match x.as_u64() {
            Some(n) if n == FORMAT_VERSION as u64 => Ok(()),
            Some(n) => Err(version_msg(n)),
            None => Err(format!(
                "\"version\" must be the integer {FORMAT_VERSION}, found {x}"
            )),
        },
    }
}

/// serde_json's message (it carries line and column), plus a hint where JSON's lack of
/// NaN/Infinity literals is the likely cause.
fn json_error(text: &str, e: &serde_json::Error) -> String {
    let mut msg = format!("malformed JSON: {e}");
    if e.is_syntax() || e.is_data() {
        let line = text.lines().nth(e.line().saturating_sub(1)).unwrap_or("");
        let col = e.column().saturating_sub(1).min(line.len());
        // Look around the error position for a non-finite literal.
        let (lo, hi) = (col.saturating_sub(12), (col + 12).min(line.len()));
        let near = String::from_utf8_lossy(&line.as_bytes()[lo..hi]).to_ascii_lowercase();
        if near.contains("nan") || near.contains("inf") || msg.contains("out of range") {
            msg.push_str(
                " (coordinates must be finite numbers: JSON has no NaN or Infinity, \
                 and values must fit in 32-bit floats)",
            );
        }
    }
    msg
}

fn check_point(p: &[f32; 2], image_size: Option<(u32, u32)>) -> std::result::Result<(), String> {
    if !p[0].is_finite() || !p[1].is_finite() {
        return Err(format!(
            "coordinates [{}, {}] are not finite numbers",
            p[0], p[1]
        ));
    }
    if let Some((w, h)) = image_size {
        if p[0] < 0.0 || p[1] < 0.0 || p[0] > w as f32 || p[1] > h as f32 {
            return Err(format!(
                "[{}, {}] is outside the {w}x{h} image (x in [0, {w}], y in [0, {h}])",
                p[0], p[1]
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const STROKES_SCHEMA: &str = include_str!("../../schemas/strokes.v1.schema.json");
    const LANDMARKS_SCHEMA: &str = include_str!("../../schemas/landmarks.v1.schema.json");

    fn strokes_err(text: &str, size: Option<(u32, u32)>) -> String {
        let e = Strokes::parse(text, Path::new("dir/strokes.json"), size).unwrap_err();
        let m = e.to_string();
        assert!(m.starts_with("dir/strokes.json: "), "{m}");
        m
    }

    fn landmarks_err(text: &str, size: Option<(u32, u32)>) -> String {
        let e = Landmarks::parse(text, Path::new("lm.json"), size).unwrap_err();
        let m = e.to_string();
        assert!(m.starts_with("lm.json: "), "{m}");
        m
    }

    const GOOD_STROKES: &str = r#"{"version":1,"strokes":[
        {"kind":"direction","points":[[10,20],[30.5,40]]},
        {"kind":"comb","points":[[0,0],[64,48],[1,1]]}]}"#;

    const GOOD_LANDMARKS: &str = r#"{"version":1,"landmarks":{
        "left_eye":[20,30],"right_eye":[40,30],"nose_tip":[30,40],
        "mouth_left":[24,50],"mouth_right":[36,50],"chin":[30,62],"forehead":[30,10]}}"#;

    #[test]
    fn good_files_load() {
        let s = Strokes::parse(GOOD_STROKES, Path::new("s"), Some((64, 64))).unwrap();
        assert_eq!(s.strokes.len(), 2);
        assert_eq!(s.strokes[0].kind, StrokeKind::Direction);
        assert_eq!(s.strokes[1].kind, StrokeKind::Comb);
        assert_eq!(s.strokes[0].points[1], [30.5, 40.0]);
        let l = Landmarks::parse(GOOD_LANDMARKS, Path::new("l"), Some((64, 64))).unwrap();
        assert_eq!(l.get("chin"), Some([30.0, 62.0]));
        assert_eq!(l.get("forehead"), Some([30.0, 10.0]));
    }

    #[test]
    fn save_load_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let s = Strokes::new(vec![
            Stroke::new(
                StrokeKind::Direction,
                vec![[1.25, 2.0], [3.1, 4.7], [0.1, 1e-3]],
            ),
            Stroke::new(StrokeKind::Cut, vec![[5.0, 6.0], [7.0, 8.0]]),
        ]);
        let p = dir.path().join("strokes.json");
        s.save(&p).unwrap();
        assert_eq!(Strokes::load(&p, None).unwrap(), s);
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("\"kind\": \"direction\""), "{text}");

        let l = Landmarks::parse(GOOD_LANDMARKS, Path::new("l"), None).unwrap();
        let p = dir.path().join("landmarks.json");
        l.save(&p).unwrap();
        assert_eq!(Landmarks::load(&p, Some((64, 64))).unwrap(), l);

        let empty = Strokes::new(vec![]);
        empty.save(&p).unwrap();
        assert_eq!(Strokes::load(&p, None).unwrap(), empty);
    }

    /// A stroke's own brush radius and its "sure" mark survive a save and a load; strokes
    /// without them are written as before, with neither key.
    #[test]
    fn radius_and_sure_round_trip_and_are_checked() {
        let dir = tempfile::tempdir().unwrap();
        let mut thin = Stroke::new(StrokeKind::Direction, vec![[1.0, 2.0], [3.0, 4.0]]);
        thin.radius = Some(1.5);
        thin.sure = true;
        let plain = Stroke::new(StrokeKind::Background, vec![[5.0, 6.0], [7.0, 8.0]]);
        let s = Strokes::new(vec![thin, plain]);
        let p = dir.path().join("strokes.json");
        s.save(&p).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(Strokes::load(&p, None).unwrap(), s, "{text}");
        assert_eq!(text.matches("\"radius\"").count(), 1, "{text}");
        assert_eq!(text.matches("\"sure\"").count(), 1, "{text}");
        let json = serde_json::to_string(&s).unwrap();
        assert_eq!(
            Strokes::parse(&json, Path::new("j"), None).unwrap(),
            s,
            "{json}"
        );
        for bad in ["0", "-2", "65", "1e9"] {
            let m = strokes_err(
                &format!(
                    r#"{{"version":1,"strokes":[{{"kind":"direction","points":[[0,0],[9,9]]}},
                       {{"kind":"background","points":[[0,0],[9,9]],"radius":{bad}}}]}}"#
                ),
                None,
            );
            assert!(
                m.contains("stroke 1 (background): radius") && m.contains("at most 64"),
                "{bad}: {m}"
            );
        }
        let m = strokes_err(
            r#"{"version":1,"strokes":[{"kind":"direction","points":[[0,0],[9,9]],"sure":"yes"}]}"#,
            None,
        );
        assert!(m.contains("expected a boolean"), "{m}");
    }

    #[test]
    fn save_refuses_non_finite() {
        let dir = tempfile::tempdir().unwrap();
        let s = Strokes::new(vec![Stroke::new(
            StrokeKind::Direction,
            vec![[1.0, f32::NAN], [3.0, 4.0]],
        )]);
        let e = s.save(&dir.path().join("x.json")).unwrap_err().to_string();
        assert!(
            e.contains("stroke 0, point 0") && e.contains("not finite"),
            "{e}"
        );
    }

    #[test]
    fn unreadable_file() {
        let e = Strokes::load(Path::new("/nonexistent/strokes.json"), None).unwrap_err();
        assert!(matches!(e, Error::Io { .. }));
        assert!(e.to_string().contains("/nonexistent/strokes.json"));
        let e = Landmarks::load(Path::new("/nonexistent/lm.json"), None).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/lm.json"));
    }

    #[test]
    fn malformed_json_has_position() {
        let m = strokes_err("{\"version\":1,\n \"strokes\": [}", None);
        assert!(m.contains("malformed JSON") && m.contains("line 2"), "{m}");
        let m = strokes_err("[1,2]", None);
        assert!(m.contains("top level"), "{m}");
        let m = strokes_err(r#"{"version":1,"strokes":[{"kind":"direction"}]}"#, None);
        assert!(m.contains("missing field `points`"), "{m}");
    }

    #[test]
    fn version_checks() {
        let m = strokes_err(r#"{"version":2,"strokes":[]}"#, None);
        assert!(
            m.contains("version 2 is not supported; this coif reads version 1"),
            "{m}"
        );
        let m = strokes_err(r#"{"strokes":[]}"#, None);
        assert!(m.contains("missing \"version\""), "{m}");
        let m = strokes_err(r#"{"version":"1","strokes":[]}"#, None);
        assert!(m.contains("must be the integer 1"), "{m}");
        let m = landmarks_err(r#"{"version":3,"landmarks":{}}"#, None);
        assert!(m.contains("version 3 is not supported"), "{m}");
    }

    #[test]
    fn unknown_kind_and_short_stroke() {
        let m = strokes_err(
            r#"{"version":1,"strokes":[{"kind":"direction","points":[[0,0],[1,1]]},
               {"kind":"hair","points":[[0,0],[1,1]]}]}"#,
            None,
        );
        assert!(m.contains("stroke 1: unknown kind \"hair\""), "{m}");
        assert!(m.contains("direction, background, comb, cut"), "{m}");
        let m = strokes_err(
            r#"{"version":1,"strokes":[{"kind":"direction","points":[[0,0]]}]}"#,
            None,
        );
        assert!(m.contains("stroke 0 (direction) has 1 point(s)"), "{m}");
    }

    #[test]
    fn non_finite_coordinates() {
        for lit in ["NaN", "Infinity", "-inf", "nan"] {
            let m = strokes_err(
                &format!(
                    r#"{{"version":1,"strokes":[{{"kind":"direction","points":[[0,{lit}],[1,1]]}}]}}"#
                ),
                None,
            );
            assert!(m.contains("JSON has no NaN or Infinity"), "{lit}: {m}");
            assert!(m.contains("line 1"), "{m}");
        }
        let m = strokes_err(
            r#"{"version":1,"strokes":[{"kind":"direction","points":[[0,1e999],[1,1]]}]}"#,
            None,
        );
        assert!(m.contains("finite"), "{m}");
        // Fits in f64 but not in f32: becomes infinite, caught by validation.
        let m = strokes_err(
            r#"{"version":1,"strokes":[{"kind":"direction","points":[[0,0],[1e39,1]]}]}"#,
            None,
        );
        assert!(
            m.contains("stroke 0, point 1") && m.contains("not finite"),
            "{m}"
        );
    }

    #[test]
    fn out_of_image_points() {
        let m = strokes_err(GOOD_STROKES, Some((64, 47)));
        assert!(
            m.contains("stroke 1, point 1") && m.contains("outside the 64x47"),
            "{m}"
        );
        let m = strokes_err(
            r#"{"version":1,"strokes":[{"kind":"direction","points":[[0,0],[-0.5,3]]}]}"#,
            Some((10, 10)),
        );
        assert!(m.contains("stroke 0, point 1"), "{m}");
        let m = landmarks_err(GOOD_LANDMARKS, Some((64, 60)));
        assert!(
            m.contains("landmark \"chin\"") && m.contains("outside"),
            "{m}"
        );
    }

    #[test]
    fn missing_landmarks() {
        let m = landmarks_err(
            r#"{"version":1,"landmarks":{"left_eye":[1,2],"right_eye":[3,4],"chin":[5,6]}}"#,
            None,
        );
        assert!(
            m.contains("missing landmark(s): nose_tip, mouth_left, mouth_right"),
            "{m}"
        );
        let m = landmarks_err(r#"{"version":1}"#, None);
        assert!(m.contains("missing field `landmarks`"), "{m}");
    }

    fn schema(text: &str) -> serde_json::Value {
        let v: serde_json::Value = serde_json::from_str(text).expect("schema is JSON");
        assert_eq!(
            v["$schema"], "https://json-schema.org/draft/2020-12/schema",
            "draft 2020-12"
        );
        v
    }

    #[test]
    fn schema_examples_load() {
        let dir = tempfile::tempdir().unwrap();
        let s = schema(STROKES_SCHEMA);
        let examples = s["examples"].as_array().expect("examples array");
        assert!(!examples.is_empty());
        for (i, ex) in examples.iter().enumerate() {
            let p = dir.path().join(format!("strokes{i}.json"));
            std::fs::write(&p, serde_json::to_string_pretty(ex).unwrap()).unwrap();
            Strokes::load(&p, None).unwrap_or_else(|e| panic!("example {i}: {e}"));
        }
        // The schema's kind enum matches the Rust enum.
        let kinds: Vec<&str> = s["$defs"]["stroke"]["properties"]["kind"]["enum"]
            .as_array()
            .unwrap()
            .iter()
            .map(|k| k.as_str().unwrap())
            .collect();
        let ours: Vec<&str> = StrokeKind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(kinds, ours);
        // Its stroke fields are the ones serde writes, and the radius bound is ours.
        let props = &s["$defs"]["stroke"]["properties"];
        let mut keys: Vec<&str> = props
            .as_object()
            .unwrap()
            .keys()
            .map(|k| k.as_str())
            .collect();
        keys.sort_unstable();
        let mut full = Stroke::new(StrokeKind::Direction, vec![[0.0, 0.0], [1.0, 1.0]]);
        full.radius = Some(2.0);
        full.sure = true;
        let v = serde_json::to_value(&full).unwrap();
        let mut written: Vec<&str> = v.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        written.sort_unstable();
        assert_eq!(keys, written);
        assert_eq!(props["radius"]["maximum"], MAX_STROKE_RADIUS as f64);

        let l = schema(LANDMARKS_SCHEMA);
        let examples = l["examples"].as_array().expect("examples array");
        assert!(!examples.is_empty());
        for (i, ex) in examples.iter().enumerate() {
            let p = dir.path().join(format!("landmarks{i}.json"));
            std::fs::write(&p, serde_json::to_string_pretty(ex).unwrap()).unwrap();
            Landmarks::load(&p, None).unwrap_or_else(|e| panic!("example {i}: {e}"));
        }
        let req: Vec<&str> = l["properties"]["landmarks"]["required"]
            .as_array()
            .unwrap()
            .iter()
            .map(|k| k.as_str().unwrap())
            .collect();
        assert_eq!(req, REQUIRED_LANDMARKS.to_vec());
    }
}
