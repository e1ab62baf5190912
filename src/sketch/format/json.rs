//! `sketch.json`: the sketch's codes as readable JSON, checked against its schema.

use super::*;

#[derive(Serialize, Deserialize)]
pub(super) struct JsonPrim {
    /// Degrees, a multiple of 15.
    pub(super) axis: u32,
    /// Degrees.
    pub(super) sides: [f64; 2],
    pub(super) rho: f32,
    /// Px to the left of the chain, a multiple of ¼ within ±2: an occluding line placed off
    /// its chain (version 4; absent: on it).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub(super) shift: f32,
}

fn is_zero(v: &f32) -> bool {
    *v == 0.0
}

#[derive(Serialize, Deserialize)]
pub(super) struct JsonCurve {
    pub(super) kind: String,
    pub(super) dirs: [i8; 2],
    pub(super) start: [u32; 2],
    pub(super) prims: Vec<JsonPrim>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct JsonBase {
    pub(super) x: f32,
    pub(super) y: f32,
    /// Degrees.
    pub(super) theta: f64,
    pub(super) sx: f32,
    pub(super) sy: f32,
    pub(super) amp: f32,
}

#[derive(Serialize, Deserialize)]
pub(super) struct JsonShading {
    pub(super) mean: f32,
    pub(super) bases: Vec<JsonBase>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct JsonSketch {
    pub(super) format: String,
    pub(super) version: u32,
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) seed: u64,
    pub(super) curves: Vec<JsonCurve>,
    pub(super) rho_off: RhoPrior,
    pub(super) shading: JsonShading,
    pub(super) colour: ColourMap,
    /// The hair region's polygons (absent: the whole image).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub(super) region: super::super::Region,
    /// The high band's along/across ratio (absent: none, no grain in synthesis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) along_across: Option<f32>,
}

pub(super) const FORMAT_NAME: &str = "coif-sketch";

pub(super) fn json_of(c: &Codes) -> JsonSketch {
    let s = decode(c);
    JsonSketch {
        format: FORMAT_NAME.into(),
        version: VERSION as u32,
        width: c.width,
        height: c.height,
        seed: c.seed,
        curves: c
            .curves
            .iter()
            .zip(&s.curves)
            .map(|(cc, cv)| {
                let mut idx = cc.axis as i64;
                JsonCurve {
                    kind: cc.kind.letter().to_string(),
                    dirs: cc.dirs,
                    start: cc.start,
                    prims: cc
                        .prims
                        .iter()
                        .zip(&cv.prims)
                        .enumerate()
                        .map(|(k, (pc, p))| {
                            if k > 0 {
                                idx += pc.turn as i64;
                            }
                            JsonPrim {
                                axis: idx.rem_euclid(AXIS_STEPS as i64) as u32 * 15,
                                sides: [0, 1].map(|s| {
                                    if cc.kind.hair_sides()[s] {
                                        side_deg(pc.side[s].0, pc.side[s].1)
                                    } else {
                                        0.0
                                    }
                                }),
                                rho: p.rho,
                                shift: p.shift,
                            }
                        })
                        .collect(),
                }
            })
            .collect(),
        rho_off: s.rho_off,
        shading: JsonShading {
            mean: s.shading.mean,
            bases: c
                .bases
                .iter()
                .zip(&s.shading.bases)
                .map(|(bc, b)| JsonBase {
                    x: b.x,
                    y: b.y,
                    theta: bc.theta as f64 * 180.0 / THETAS as f64,
                    sx: b.sx,
                    sy: b.sy,
                    amp: b.amp,
                })
                .collect(),
        },
        colour: s.colour,
        region: c.region.clone(),
        along_across: s.along_across,
    }
}

/// `sketch.json` of the quantised sketch (angles in degrees; see the schema).
pub fn to_json(s: &Sketch) -> String {
    serde_json::to_string_pretty(&json_of(&codes(s))).expect("a sketch serialises") + "\n"
}

/// Checks `v` against the schema; the message lists each failure with its JSON pointer.
pub fn validate_json(v: &serde_json::Value) -> std::result::Result<(), String> {
    let schema: serde_json::Value =
        serde_json::from_str(SCHEMA).map_err(|e| format!("the built-in schema: {e}"))?;
    let mut schemas = boon::Schemas::new();
    let mut compiler = boon::Compiler::new();
    compiler
        .add_resource(SCHEMA_URL, schema)
        .map_err(|e| format!("the built-in schema: {e}"))?;
    let idx = compiler
        .compile(SCHEMA_URL, &mut schemas)
        .map_err(|e| format!("the built-in schema: {e}"))?;
    schemas.validate(v, idx).map_err(|e| {
        // The leaves of boon's error tree are the concrete failures.
        fn leaves(e: &boon::ValidationError, out: &mut Vec<String>) {
            if e.causes.is_empty() {
                let at = e.instance_location.to_string();
                let at = if at.is_empty() { "/".to_string() } else { at };
                out.push(format!("at {at}: {}", e.kind));
            }
            for c in &e.causes {
                leaves(c, out);
            }
        }
        let mut out = Vec::new();
        leaves(&e, &mut out);
        out.truncate(8);
        out.join("; ")
    })
}

/// Reads `sketch.json` text; `path` names it in errors. The text must match the schema;
/// the numbers are then snapped to the `.czs` lattice and the sketch checked by [`validate`].
pub fn from_json(text: &str, path: &Path) -> Result<Sketch> {
    let bad = |m: String| Error::bad_file(path, m);
    let v: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        // A hand edit may write NaN or Infinity, which JSON cannot hold: say so.
        let at = (e.line() > 0)
            .then(|| text.lines().nth(e.line() - 1))
            .flatten();
        let token = at.and_then(|l| {
            let rest = l.get(e.column().saturating_sub(1)..).unwrap_or("");
            ["NaN", "nan", "Infinity", "-Infinity", "inf", "-inf"]
                .into_iter()
                .find(|t| rest.starts_with(t))
        });
        match token {
            Some(t) => bad(format!(
                "malformed JSON: {t} at line {} column {} is not a number (JSON has no NaN \
                 or infinity; every number of a sketch must be finite)",
                e.line(),
                e.column()
            )),
            None => bad(format!("malformed JSON: {e}")),
        }
    })?;
    validate_json(&v).map_err(|m| {
        bad(format!(
            "does not match the schema schemas/sketch.v1.schema.json: {m}"
        ))
    })?;
    let j: JsonSketch = serde_json::from_value(v)
        .map_err(|e| bad(format!("does not match the sketch format: {e}")))?;
    let (w, h) = (j.width, j.height);
    let mut curves = Vec::new();
    for (ci, c) in j.curves.iter().enumerate() {
        let kind = c
            .kind
            .chars()
            .next()
            .and_then(Kind::from_letter)
            .ok_or_else(|| bad(format!("curve {ci}: unknown kind \"{}\"", c.kind)))?;
        if c.start[0] > w || c.start[1] > h {
            return Err(bad(format!(
                "curve {ci} starts at ({}, {}), outside the {w}x{h} image",
                c.start[0], c.start[1]
            )));
        }
        let mut prims = Vec::new();
        let mut prev = 0u32;
        for (k, p) in c.prims.iter().enumerate() {
            let a = p.axis / 15;
            if k > 0 {
                let d = (a + AXIS_STEPS - prev) % AXIS_STEPS;
                if d != 0 && d != 1 && d != AXIS_STEPS - 1 {
                    return Err(bad(format!(
                        "curve {ci}, primitive {k}: the axis turns from {}° to {}°; a curve \
                         turns by −15°, 0 or +15° per primitive",
                        prev * 15,
                        p.axis
                    )));
                }
            }
            prev = a;
            if p.shift != 0.0 && kind != Kind::Occluding {
                return Err(bad(format!(
                    "curve {ci}, primitive {k}: a shift of {} px on a curve of kind {}; only \
                     occluding lines (c) lie off their chains",
                    p.shift, c.kind
                )));
            }
            let code = exact_shift_code(p.shift as f64).map_err(|e| {
                bad(format!(
                    "curve {ci}, primitive {k}: a shift of {} px; {e}",
                    p.shift
                ))
            })?;
            // Only the start's centre is read (the rest follow from the chain), where it is
            // painted: off the chain by its shift.
            let axis = axis_of(a as u8);
            let [x, y] = off_chain(c.start[0] as f32, c.start[1] as f32, axis, code);
            prims.push(Primitive {
                shift: shift_of(code),
                x: if k == 0 { x } else { 0.0 },
                y: if k == 0 { y } else { 0.0 },
                axis,
                rho: p.rho,
                side: p.sides.map(deg_to_rad),
            });
        }
        curves.push(Curve {
            kind,
            prims,
            dirs: c.dirs,
        });
    }
    for (pi, poly) in j.region.iter().enumerate() {
        if let Some(v) = poly.iter().find(|v| v[0] > w || v[1] > h) {
            return Err(bad(format!(
                "region polygon {pi} has the vertex ({}, {}), outside the {w}x{h} image",
                v[0], v[1]
            )));
        }
    }
    let sketch = Sketch {
        width: w,
        height: h,
        seed: j.seed,
        curves,
        rho_off: j.rho_off,
        shading: Shading {
            mean: j.shading.mean,
            bases: j
                .shading
                .bases
                .iter()
                .map(|b| Base {
                    x: b.x,
                    y: b.y,
                    theta: deg_to_rad(b.theta),
                    sx: b.sx,
                    sy: b.sy,
                    amp: b.amp,
                })
                .collect(),
        },
        colour: j.colour,
        region: j.region,
        along_across: j.along_across,
    };
    let q = quantise(&sketch);
    validate(&q, path)?;
    Ok(q)
}
