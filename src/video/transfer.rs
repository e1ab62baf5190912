//! Hair replacement through a video (C13 §4): every strand ξ′ of a new model S′ takes the
//! motion, relative to the head, of its nearest strand ξ of the tracked model S (nearest by
//! a feature vector of root and two points along the strand), plus the head's motion M_i.
//! Light, branchy work (a nearest-neighbour search, per-strand resampling): CPU, in
//! parallel over strands.
//!
//! Both models live in the same parametric head's model space (`coif model` fits the same
//! head to any photo), so S′ needs no alignment beyond that; a head with other parameters is
//! refused, since its scalp would not match.

use crate::base::polyline::arc_lengths;
use crate::error::{Error, Result};
use crate::hair::scene::{Animation, Scene};
use crate::hair::strands::StrandSet;
use crate::sim::track::{apply, apply_inv, pose_transform};
use glam::Vec3;
use rayon::prelude::*;

/// Arc lengths (m) of the two points after the root in a strand's feature vector.
pub const FEATURE_ARCS_M: [f32; 2] = [0.03, 0.08];

/// A strand's feature vector: its root and its points at [`FEATURE_ARCS_M`] (the tip when
/// shorter).
pub fn feature(strand: &[[f32; 3]]) -> [f32; 9] {
    let arcs = arc_lengths(strand);
    let at = |a: f32| -> [f32; 3] { point_at(strand, &arcs, a as f64) };
    let (r, p, q) = (strand[0], at(FEATURE_ARCS_M[0]), at(FEATURE_ARCS_M[1]));
    [r[0], r[1], r[2], p[0], p[1], p[2], q[0], q[1], q[2]]
}

fn point_at(strand: &[[f32; 3]], arcs: &[f64], a: f64) -> [f32; 3] {
    if strand.len() == 1 || a <= 0.0 {
        return strand[0];
    }
    let k = arcs.partition_point(|&x| x < a);
    if k >= strand.len() {
        return strand[strand.len() - 1];
    }
    let (a0, a1) = (arcs[k - 1], arcs[k]);
    let t = if a1 > a0 {
        ((a - a0) / (a1 - a0)) as f32
    } else {
        0.0
    };
    let (p, q) = (Vec3::from_array(strand[k - 1]), Vec3::from_array(strand[k]));
    p.lerp(q, t).to_array()
}

fn dist2(a: &[f32; 9], b: &[f32; 9]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Nearest tracked strand of every new strand by [`feature`]. A uniform grid on the roots
/// bounds the search: the root is part of the feature, so no strand whose root is farther
/// than the best distance so far can be nearer.
pub fn nearest(tracked: &StrandSet, new: &StrandSet) -> Vec<usize> {
    let ft: Vec<[f32; 9]> = tracked.strands().map(feature).collect();
    let cell = 0.01f32;
    let key = |p: &[f32]| -> [i32; 3] {
        [
            (p[0] / cell).floor() as i32,
            (p[1] / cell).floor() as i32,
            (p[2] / cell).floor() as i32,
        ]
    };
    let mut grid: std::collections::HashMap<[i32; 3], Vec<usize>> = Default::default();
    for (i, f) in ft.iter().enumerate() {
        grid.entry(key(&f[..3])).or_default().push(i);
    }
    let reach = grid
        .keys()
        .flat_map(|k| k.iter().map(|v| v.unsigned_abs()))
        .max()
        .unwrap_or(0) as i32
        + 2;
    new.strands()
        .collect::<Vec<_>>()
        .par_iter()
        .map(|s| {
            let f = feature(s);
            let c = key(&f[..3]);
            let mut best = (f32::INFINITY, 0usize);
            for ring in 0..=(2 * reach) {
                // Every cell of this ring is at least (ring − 1) cells from the root.
                let lower = (ring as f32 - 1.0).max(0.0) * cell;
                if lower * lower > best.0 {
                    break;
                }
                for dx in -ring..=ring {
                    for dy in -ring..=ring {
                        for dz in -ring..=ring {
                            if dx.abs().max(dy.abs()).max(dz.abs()) != ring {
                                continue;
                            }
                            if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                                for &i in list {
                                    let d = dist2(&f, &ft[i]);
                                    if d < best.0 {
                                        best = (d, i);
                                    }
                                }
                            }
                        }
                    }
                }
            }
            best.1
        })
        .collect()
}

/// The new model carried through the video's frames: a scene with the new strands, the
/// video's footage and head poses, and frame files of the new strands (written to `out`).
pub fn transfer(video: &Scene, new: &Scene, out: &std::path::Path) -> Result<Scene> {
    let meta = video.dir.join("model.json");
    let a = video
        .animation
        .as_ref()
        .filter(|a| a.footage.is_some())
        .ok_or_else(|| {
            Error::bad_file(
                &meta,
                "not a tracked video (no animation with footage): make one with `coif video`",
            )
        })?;
    let footage = a.footage.as_ref().expect("filtered");
    match (&video.head, &new.head) {
        (Some(h0), Some(h1)) if h0.params() == h1.params() => {}
        (Some(_), Some(_)) => {
            return Err(Error::bad_file(
                new.dir.join("model.json"),
                "its head has other parameters than the video's: the scalps would not match",
            ))
        }
        _ => {
            return Err(Error::bad_file(
                new.dir.join("model.json"),
                "the model has no head (an imported strand file?): hair replacement needs one",
            ))
        }
    }
    let near = nearest(&video.strands, &new.strands);
    let tracked_off = video.strands.offsets();
    let tracked_arcs: Vec<Vec<f64>> = video.strands.strands().map(arc_lengths).collect();
    let new_strands: Vec<&[[f32; 3]]> = new.strands.strands().collect();
    crate::io::ensure_dir(&out.join("frames"))?;
    let mut names = Vec::with_capacity(a.frames.len());
    for (k, pose) in a.head.iter().enumerate() {
        let m = pose_transform(pose);
        let world = video.frame(k)?;
        if world.counts != video.strands.counts {
            return Err(Error::bad_file(
                video.dir.join(&a.frames[k]),
                "its strands do not match the model's (counts differ)",
            ));
        }
        // The tracked strands' motion relative to the head, per vertex.
        let rel: Vec<[f32; 3]> = world
            .points
            .iter()
            .zip(&video.strands.points)
            .map(|(w, r)| {
                let h = apply_inv(&m, *w);
                [h[0] - r[0], h[1] - r[1], h[2] - r[2]]
            })
            .collect();
        let pts: Vec<[f32; 3]> = new_strands
            .par_iter()
            .zip(&near)
            .flat_map_iter(|(s, &j)| {
                let (o, arcs) = (tracked_off[j], &tracked_arcs[j]);
                let d = &rel[o..o + arcs.len()];
                let own = arc_lengths(s);
                s.iter()
                    .zip(own)
                    .map(|(p, a)| {
                        let dv = point_at(d, arcs, a);
                        apply(&m, [p[0] + dv[0], p[1] + dv[1], p[2] + dv[2]])
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let name = format!("frames/{k:04}.hair");
        crate::io::strands::write(
            &out.join(&name),
            &StrandSet::new(pts, new.strands.counts.clone()),
        )?;
        names.push(name);
    }
    // Footage files stay where the video model keeps them: paths relative to `out`.
    let rel = |p: &String| -> String { pathdiff(&video.dir.join(p), out) };
    let mut s = new.clone();
    s.dir = out.to_path_buf();
    s.camera = video.camera;
    s.photo = video.photo.clone();
    s.mask = video.mask.clone();
    s.width = video.width;
    s.height = video.height;
    s.animation = Some(Animation {
        fps: a.fps,
        frames: names,
        head: a.head.clone(),
        footage: Some(crate::hair::scene::Footage {
            photos: footage.photos.iter().map(rel).collect(),
            masks: footage.masks.iter().map(rel).collect(),
            cameras: footage.cameras.clone(),
        }),
    });
    Ok(s)
}

/// `path` as seen from `base`: relative when both are, else absolute.
fn pathdiff(path: &std::path::Path, base: &std::path::Path) -> String {
    let abs = |p: &std::path::Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let (p, b) = (abs(path), abs(base));
    let (pc, bc): (Vec<_>, Vec<_>) = (p.components().collect(), b.components().collect());
    let common = pc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return p.display().to_string();
    }
    let mut r = std::path::PathBuf::new();
    for _ in common..bc.len() {
        r.push("..");
    }
    for c in &pc[common..] {
        r.push(c.as_os_str());
    }
    r.display().to_string()
}
