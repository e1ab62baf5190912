//! OBJ polylines (`l` elements).

use super::*;
use std::fmt::Write as _;

pub(super) fn decode_obj(b: &[u8]) -> Msg<StrandSet> {
    let text = std::str::from_utf8(b).map_err(|_| "not a text OBJ file (invalid UTF-8)")?;
    let mut verts: Vec<[f32; 3]> = Vec::new();
    let mut vcols: Vec<[f32; 3]> = Vec::new();
    let mut all_colored = true;
    let mut lines: Vec<Vec<usize>> = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let mut toks = line.split_ascii_whitespace();
        let bad = |what: &str| format!("line {}: {what}: {line:?}", ln + 1);
        match toks.next() {
            Some("v") => {
                let vals = toks
                    .map(|t| t.parse::<f32>())
                    .collect::<std::result::Result<Vec<f32>, _>>()
                    .map_err(|_| bad("bad vertex"))?;
                match vals.len() {
                    3 | 4 => all_colored = false,
                    // "v x y z r g b" is the common vertex-colour extension (MeshLab, Blender).
                    6 => vcols.push([vals[3], vals[4], vals[5]]),
                    _ => return Err(bad("a vertex needs 3, 4 or 6 numbers")),
                }
                verts.push([vals[0], vals[1], vals[2]]);
            }
            Some("l") => {
                let mut idx = Vec::new();
                for t in toks {
                    // "l v/vt" also occurs; only the vertex index matters here.
                    let v: i64 = t
                        .split('/')
                        .next()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| bad("bad index"))?;
                    // Negative indices count back from the vertices seen so far.
                    let abs = if v < 0 { verts.len() as i64 + v } else { v - 1 };
                    if abs < 0 {
                        return Err(bad("index out of range"));
                    }
                    idx.push(abs as usize);
                }
                if idx.is_empty() {
                    return Err(bad("polyline without vertices"));
                }
                lines.push(idx);
            }
            _ => {}
        }
    }
    if lines.is_empty() {
        return Err("no polylines (\"l\" lines) in OBJ".into());
    }
    let n = verts.len();
    let mut points = Vec::new();
    let mut colors = Vec::new();
    let mut counts = Vec::with_capacity(lines.len());
    let colored = all_colored && !vcols.is_empty();
    for l in &lines {
        for &i in l {
            let p = verts
                .get(i)
                .ok_or_else(|| format!("polyline index {} outside 1..={n}", i + 1))?;
            points.push(*p);
            if colored {
                colors.push(vcols[i]);
            }
        }
        counts.push(l.len() as u32);
    }
    let mut s = StrandSet::new(points, counts);
    s.colors = colored.then_some(colors);
    Ok(s)
}

pub(super) fn encode_obj(s: &StrandSet) -> Vec<u8> {
    let mut t = format!(
        "# written by coif: {} strands, {} points\n",
        s.counts.len(),
        s.points.len()
    );
    for (i, [x, y, z]) in s.points.iter().enumerate() {
        let _ = write!(t, "v {x} {y} {z}");
        if let Some(c) = &s.colors {
            let [r, g, b] = c[i];
            let _ = write!(t, " {r} {g} {b}");
        }
        t.push('\n');
    }
    // A 1-vertex strand is written as "l i": kept so the strand count survives.
    let mut next = 1usize;
    for &c in &s.counts {
        t.push('l');
        for v in next..next + c as usize {
            let _ = write!(t, " {v}");
        }
        t.push('\n');
        next += c as usize;
    }
    t.into_bytes()
}
