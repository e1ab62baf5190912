//! Editing a modelled scene with strokes (C13 appendix A): the comb turns strands toward a
//! stroke's direction, the cut shortens the strands that reach a stroke. Each is one pass
//! per strand ([`crate::stages::edit_comb`], [`crate::stages::edit_cut`], CPU mirrors
//! beside them); this host packs the strokes, uploads the strands tile by tile (packed with
//! an offsets buffer, each tile under the engine's binding limit) and measures the result.
//! Dropping the cut tips and compacting the strand arrays is plain Rust on the CPU.

pub mod hierarchy;

use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::hair::head::WeakPerspective;
use crate::hair::scene::Scene;
use crate::hair::strands::StrandSet;
use crate::io::annot::{StrokeKind, Strokes};
use crate::stages::edit_stroke::{nearest, pack_segments, project, SEG_FLOATS};
use crate::stages::{edit_comb, edit_cut};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// C13's radius of influence, image px.
pub const DEFAULT_RADIUS: f32 = 32.0;

/// What a comb did.
#[derive(Clone, Debug, Serialize)]
pub struct CombReport {
    pub strokes: usize,
    pub radius: f32,
    pub strands: usize,
    /// Strands with at least one vertex moved.
    pub strands_changed: usize,
    pub vertices_moved: usize,
    /// Largest relative change of a segment length (f64 check of the f32 result).
    pub length_error_max: f64,
    /// Largest change of a vertex's depth along the view axis, metres.
    pub depth_error_max: f64,
    /// Share of non-root vertices inside the head before and after (None without a head).
    pub inside_head_before: Option<f64>,
    pub inside_head_after: Option<f64>,
    pub seconds: f64,
    pub backend: String,
}

/// What a cut did.
#[derive(Clone, Debug, Serialize)]
pub struct CutReport {
    pub strokes: usize,
    pub radius: f32,
    pub seed: u64,
    pub strands: usize,
    /// Strands that lost vertices.
    pub strands_cut: usize,
    pub vertices_before: usize,
    pub vertices_after: usize,
    /// Strands whose kept tip was a drawn candidate (R > 0), and its mean r / R.
    pub drawn: usize,
    pub mean_r_over_radius: Option<f64>,
    pub seconds: f64,
    pub backend: String,
}

/// The scene's camera, or an error naming its `model.json`.
fn camera(scene: &Scene) -> Result<WeakPerspective> {
    scene.camera.ok_or_else(|| {
        Error::bad_file(
            scene.dir.join("model.json"),
            "the model has no camera (imported strands?): strokes are drawn on the photo, so \
             editing needs a model made by `coif model`",
        )
    })
}

/// Reads a strokes file for `kind` on `scene`: points must lie in the scene's image and at
/// least one stroke must be of that kind. Errors name the file.
pub fn load_strokes(scene: &Scene, path: &Path, kind: StrokeKind) -> Result<Strokes> {
    camera(scene)?;
    let size = (scene.width > 0 && scene.height > 0).then_some((scene.width, scene.height));
    let s = Strokes::load(path, size)?;
    if !s.strokes.iter().any(|st| st.kind == kind) {
        let mut found: Vec<&str> = s.strokes.iter().map(|st| st.kind.name()).collect();
        found.sort();
        found.dedup();
        return Err(Error::bad_file(
            path,
            format!(
                "no stroke of kind \"{kind}\" (found: {})",
                if found.is_empty() {
                    "none".to_string()
                } else {
                    found.join(", ")
                }
            ),
        ));
    }
    polylines(&s, kind).map_err(|e| Error::bad_file(path, e.to_string()))?;
    Ok(s)
}

/// A warning when a stroke of `kind` carries a segmentation brush (`radius`, `sure`): an
/// edit's reach is the job's radius for every stroke, so the field does nothing here.
pub fn unused_brush(
    strokes: &Strokes,
    kind: StrokeKind,
    path: &Path,
    radius: f32,
) -> Option<String> {
    let which: Vec<String> = strokes
        .strokes
        .iter()
        .enumerate()
        .filter(|(_, s)| s.kind == kind && (s.radius.is_some() || s.sure))
        .map(|(i, _)| i.to_string())
        .collect();
    (!which.is_empty()).then(|| {
        format!(
            "{}: stroke(s) {} carry \"radius\" or \"sure\", which are for segmentation; \
             the {kind} reaches {radius} px (--radius) from every stroke",
            path.display(),
            which.join(", ")
        )
    })
}

/// The polylines of `kind`, or an error when there are none.
fn polylines(strokes: &Strokes, kind: StrokeKind) -> Result<Vec<Vec<[f32; 2]>>> {
    let v: Vec<Vec<[f32; 2]>> = strokes
        .strokes
        .iter()
        .filter(|s| s.kind == kind)
        .map(|s| s.points.clone())
        .collect();
    if v.is_empty() {
        return Err(Error::Invalid(format!("no stroke of kind \"{kind}\"")));
    }
    if let Some(p) = v
        .iter()
        .flatten()
        .find(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(Error::Invalid(format!("stroke point {p:?} is not finite")));
    }
    // A stroke that stays on one point has no direction and crosses nothing.
    if let Some(i) = v.iter().position(|s| s.iter().all(|p| *p == s[0])) {
        return Err(Error::Invalid(format!(
            "{kind} stroke {i} has no two distinct points"
        )));
    }
    Ok(v)
}

fn check_radius(radius: f32, min_exclusive: bool) -> Result<()> {
    let ok = radius.is_finite()
        && if min_exclusive {
            radius > 0.0
        } else {
            radius >= 0.0
        };
    if !ok {
        return Err(Error::Invalid(format!(
            "--radius must be finite and {}, got {radius}",
            if min_exclusive {
                "positive"
            } else {
                "at least 0"
            }
        )));
    }
    Ok(())
}

/// Strand ranges [a, b) whose vertices (12 bytes each) and offsets fit one binding and whose
/// invocations fit one dispatch.
fn tiles(counts: &[u32], max_bytes: u64, wg: u32) -> Result<Vec<(usize, usize)>> {
    let max_verts = (max_bytes / 12) as usize;
    let max_strands = ((max_bytes / 4) as usize)
        .saturating_sub(1)
        .min(65535 * wg as usize);
    let mut out = Vec::new();
    let (mut a, mut verts) = (0usize, 0usize);
    for (i, &c) in counts.iter().enumerate() {
        let c = c as usize;
        if c > max_verts {
            return Err(Error::Invalid(format!(
                "strand {i} has {c} vertices, more than one GPU binding holds ({max_verts})"
            )));
        }
        if verts + c > max_verts || i - a >= max_strands {
            out.push((a, i));
            (a, verts) = (i, 0);
        }
        verts += c;
    }
    if a < counts.len() {
        out.push((a, counts.len()));
    }
    Ok(out)
}

/// Offsets of strands [a, b) relative to the first, plus the end.
fn tile_offsets(counts: &[u32]) -> Vec<u32> {
    let mut o = Vec::with_capacity(counts.len() + 1);
    o.push(0u32);
    for &c in counts {
        o.push(o[o.len() - 1] + c);
    }
    o
}

fn flat(points: &[[f32; 3]]) -> Vec<f32> {
    points.iter().flatten().copied().collect()
}

/// Combs the scene's strands toward every comb stroke (C13 A.1) with radius `radius` px.
pub fn comb(
    engine: &Engine,
    scene: &Scene,
    strokes: &Strokes,
    radius: f32,
) -> Result<(StrandSet, CombReport)> {
    let t0 = Instant::now();
    let cam = camera(scene)?;
    check_radius(radius, true)?;
    let lines = polylines(strokes, StrokeKind::Comb)?;
    let segs = pack_segments(&lines);
    let s = &scene.strands;
    s.validate()?;
    let r = [cam.r.row(0), cam.r.row(1), cam.r.row(2)].map(|v| v.to_array());
    let base = edit_comb::Config {
        n_strands: 0,
        n_segs: (segs.len() / SEG_FLOATS) as u32,
        radius,
        s: cam.s,
        r00: r[0][0],
        r01: r[0][1],
        r02: r[0][2],
        r10: r[1][0],
        r11: r[1][1],
        r12: r[1][2],
        r20: r[2][0],
        r21: r[2][1],
        r22: r[2][2],
        tx: cam.t.x,
        ty: cam.t.y,
        _pad0: 0,
    };
    let off = s.offsets();
    let mut out = s.clone();
    for (a, b) in tiles(&s.counts, engine.max_binding_bytes(), edit_comb::WORKGROUP)? {
        let cfg = edit_comb::Config {
            n_strands: (b - a) as u32,
            ..base
        };
        let mut rec = Recording::default();
        let u = rec.uniform("coif.edit.comb.cfg", &cfg);
        let sg = rec.upload("coif.edit.segs", &segs);
        let of = rec.upload("coif.edit.offsets", &tile_offsets(&s.counts[a..b]));
        let xs = rec.upload("coif.edit.x", &flat(&s.points[off[a]..off[b]]));
        rec.dispatch(
            &edit_comb::STAGE,
            edit_comb::workgroups(&cfg),
            &[u, sg, of, xs],
            &[],
        );
        rec.download(xs);
        let dl = engine.run(rec)?;
        let x = dl.get::<f32>(xs);
        for (dst, src) in out.points[off[a]..off[b]].iter_mut().zip(x.chunks(3)) {
            *dst = [src[0], src[1], src[2]];
        }
    }
    // Figures: what moved, and how well lengths and depths were kept (f64).
    let depth = |p: &[f32; 3]| (0..3).map(|c| r[2][c] as f64 * p[c] as f64).sum::<f64>();
    let len = |a: &[f32; 3], b: &[f32; 3]| {
        (0..3)
            .map(|c| (b[c] as f64 - a[c] as f64).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let (mut changed, mut moved, mut len_err, mut depth_err) = (0, 0, 0.0f64, 0.0f64);
    for i in 0..s.len() {
        let (p, q) = (
            &s.points[off[i]..off[i + 1]],
            &out.points[off[i]..off[i + 1]],
        );
        let m = p.iter().zip(q).filter(|(a, b)| a != b).count();
        if m == 0 {
            continue;
        }
        changed += 1;
        moved += m;
        for k in 0..p.len() {
            depth_err = depth_err.max((depth(&q[k]) - depth(&p[k])).abs());
            if k + 1 < p.len() {
                let l0 = len(&p[k], &p[k + 1]);
                if l0 > 0.0 {
                    len_err = len_err.max((len(&q[k], &q[k + 1]) - l0).abs() / l0);
                }
            }
        }
    }
    let inside = |set: &StrandSet| {
        scene.head.as_ref().map(|h| {
            let (mut n, mut inn) = (0usize, 0usize);
            for st in set.strands() {
                for p in &st[1..] {
                    n += 1;
                    if h.sdf(glam::Vec3::from_array(*p)) < 0.0 {
                        inn += 1;
                    }
                }
            }
            inn as f64 / n.max(1) as f64
        })
    };
    let report = CombReport {
        strokes: lines.len(),
        radius,
        strands: s.len(),
        strands_changed: changed,
        vertices_moved: moved,
        length_error_max: len_err,
        depth_error_max: depth_err,
        inside_head_before: inside(s),
        inside_head_after: inside(&out),
        seconds: t0.elapsed().as_secs_f64(),
        backend: engine.describe(),
    };
    Ok((out, report))
}

/// The new vertex count of every strand under the cut strokes (the pass alone; see
/// [`cut`]).
pub fn cut_counts(
    engine: &Engine,
    scene: &Scene,
    strokes: &Strokes,
    radius: f32,
    seed: u64,
) -> Result<Vec<u32>> {
    let cam = camera(scene)?;
    check_radius(radius, false)?;
    let lines = polylines(strokes, StrokeKind::Cut)?;
    let segs = pack_segments(&lines);
    let s = &scene.strands;
    s.validate()?;
    let (r0, r1) = (cam.r.row(0).to_array(), cam.r.row(1).to_array());
    let off = s.offsets();
    let mut counts = Vec::with_capacity(s.len());
    for (a, b) in tiles(&s.counts, engine.max_binding_bytes(), edit_cut::WORKGROUP)? {
        let cfg = edit_cut::Config {
            n_strands: (b - a) as u32,
            n_segs: (segs.len() / SEG_FLOATS) as u32,
            radius,
            s: cam.s,
            r00: r0[0],
            r01: r0[1],
            r02: r0[2],
            r10: r1[0],
            r11: r1[1],
            r12: r1[2],
            tx: cam.t.x,
            ty: cam.t.y,
            seed_lo: seed as u32,
            seed_hi: (seed >> 32) as u32,
            first_strand: a as u32,
            _pad0: 0,
        };
        let mut rec = Recording::default();
        let u = rec.uniform("coif.edit.cut.cfg", &cfg);
        let sg = rec.upload("coif.edit.segs", &segs);
        let of = rec.upload("coif.edit.offsets", &tile_offsets(&s.counts[a..b]));
        let xs = rec.upload("coif.edit.x", &flat(&s.points[off[a]..off[b]]));
        // Pre-filled with a value no count can take, so a strand the pass missed shows.
        let out = rec.alloc("coif.edit.counts", 4 * (b - a) as u64, u32::MAX);
        rec.dispatch(
            &edit_cut::STAGE,
            edit_cut::workgroups(&cfg),
            &[u, sg, of, xs, out],
            &[],
        );
        rec.download(out);
        let dl = engine.run(rec)?;
        counts.extend_from_slice(&dl.get::<u32>(out)[..b - a]);
    }
    if let Some(i) = counts
        .iter()
        .zip(&s.counts)
        .position(|(&k, &n)| k == 0 || k > n)
    {
        return Err(Error::Gpu(format!(
            "the cut pass wrote {} vertices for strand {i} of {}",
            counts[i], s.counts[i]
        )));
    }
    Ok(counts)
}

/// Cuts the scene's strands with every cut stroke (C13 A.2): radius `radius` px (0: a clean
/// cut at the first crossing), candidates drawn with `seed`.
pub fn cut(
    engine: &Engine,
    scene: &Scene,
    strokes: &Strokes,
    radius: f32,
    seed: u64,
) -> Result<(StrandSet, CutReport)> {
    let t0 = Instant::now();
    let counts = cut_counts(engine, scene, strokes, radius, seed)?;
    let s = &scene.strands;
    let off = s.offsets();
    // Compaction on the CPU: each strand keeps its first `counts[i]` vertices and their
    // attributes.
    let keep = |i: usize| off[i]..off[i] + counts[i] as usize;
    let pick = |v: &Vec<f32>| (0..s.len()).flat_map(|i| v[keep(i)].to_vec()).collect();
    let out = StrandSet {
        points: (0..s.len())
            .flat_map(|i| s.points[keep(i)].to_vec())
            .collect(),
        counts: counts.clone(),
        thickness: s.thickness.as_ref().map(pick),
        transparency: s.transparency.as_ref().map(pick),
        colors: s
            .colors
            .as_ref()
            .map(|c| (0..s.len()).flat_map(|i| c[keep(i)].to_vec()).collect()),
    };
    let lines = polylines(strokes, StrokeKind::Cut)?;
    let mut drawn = 0usize;
    let mut sum = 0.0f64;
    if radius > 0.0 {
        let cam = camera(scene)?;
        let segs = pack_segments(&lines);
        let (r0, r1) = (cam.r.row(0).to_array(), cam.r.row(1).to_array());
        let n_segs = (segs.len() / SEG_FLOATS) as u32;
        for i in 0..s.len() {
            let tip = s.points[off[i] + counts[i] as usize - 1];
            let r = nearest(&segs, n_segs, project(r0, r1, cam.s, cam.t.to_array(), tip)).0;
            if r < radius {
                drawn += 1;
                sum += (r / radius) as f64;
            }
        }
    }
    let report = CutReport {
        strokes: lines.len(),
        radius,
        seed,
        strands: s.len(),
        strands_cut: counts.iter().zip(&s.counts).filter(|(a, b)| a < b).count(),
        vertices_before: s.points.len(),
        vertices_after: out.points.len(),
        drawn,
        mean_r_over_radius: (drawn > 0).then(|| sum / drawn as f64),
        seconds: t0.elapsed().as_secs_f64(),
        backend: engine.describe(),
    };
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::annot::Stroke;

    #[test]
    fn a_segmentation_brush_on_an_edit_stroke_is_named() {
        let line = |k| Stroke::new(k, vec![[1.0, 1.0], [9.0, 9.0]]);
        let mut thin = line(StrokeKind::Comb);
        thin.radius = Some(2.0);
        let mut sure = line(StrokeKind::Direction);
        sure.sure = true;
        let s = Strokes::new(vec![line(StrokeKind::Comb), thin, sure]);
        let p = Path::new("comb.json");
        let w = unused_brush(&s, StrokeKind::Comb, p, 32.0).unwrap();
        assert!(w.starts_with("comb.json: stroke(s) 1 carry"), "{w}");
        assert!(w.contains("reaches 32 px"), "{w}");
        // The direction stroke's mark is not the comb's business, nor a cut's.
        assert_eq!(unused_brush(&s, StrokeKind::Cut, p, 32.0), None);
        let plain = Strokes::new(vec![line(StrokeKind::Comb)]);
        assert_eq!(unused_brush(&plain, StrokeKind::Comb, p, 32.0), None);
    }
}
