//! Comparison of a reconstructed strand model with the 3D ground truth (the strands
//! `crate::synth::synth3d` grows and draws).

use crate::base::stats::{quantile, Rank};
use crate::hair::head::Head;
use crate::hair::strands::StrandSet;
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// How close a reconstructed strand model is to the ground truth, in 3D (model space).
#[derive(Clone, Debug, serde::Serialize)]
pub struct GtFigures {
    pub model_vertices: usize,
    pub gt_vertices: usize,
    /// Angle between each model vertex's tangent and the tangent of the nearest GT vertex,
    /// sign-aware (root → tip both), degrees: median, and the share within 30°. Model
    /// vertices with no GT vertex within [`GT_SEARCH_M`] count as 180°; vertices of
    /// one-vertex strands (no tangent) are left out.
    pub tangent_median_deg: f32,
    pub tangent_within_30: f32,
    /// Distance of each model vertex to the nearest GT vertex, mm (capped at
    /// [`GT_SEARCH_M`]): median and 90th percentile.
    pub dist_median_mm: f32,
    pub dist_p90_mm: f32,
    /// Share of GT vertices with a model vertex within 1 cm.
    pub gt_covered_1cm: f32,
    /// Share of model vertices more than 1 mm inside the head.
    pub model_inside_head: f32,
}

/// Nearest-neighbour searches give up beyond this distance, metres.
pub const GT_SEARCH_M: f32 = 0.05;

/// Uniform-grid spatial hash over points.
pub(super) struct PointHash {
    pub(super) cell: f32,
    pub(super) map: HashMap<[i32; 3], (u32, u32)>,
    pub(super) order: Vec<u32>,
    pub(super) pts: Vec<Vec3>,
}

impl PointHash {
    pub(super) fn new(pts: Vec<Vec3>, cell: f32) -> Self {
        let key = |p: Vec3| (p / cell).floor().as_ivec3().to_array();
        let mut order: Vec<u32> = (0..pts.len() as u32).collect();
        order.sort_by_key(|&i| key(pts[i as usize]));
        let mut map = HashMap::new();
        let mut i = 0;
        while i < order.len() {
            let k = key(pts[order[i] as usize]);
            let mut j = i + 1;
            while j < order.len() && key(pts[order[j] as usize]) == k {
                j += 1;
            }
            map.insert(k, (i as u32, j as u32));
            i = j;
        }
        PointHash {
            cell,
            map,
            order,
            pts,
        }
    }

    /// Whether any point lies within `r`.
    pub(super) fn any_within(&self, p: Vec3, r: f32) -> bool {
        let lo = ((p - r) / self.cell).floor().as_ivec3();
        let hi = ((p + r) / self.cell).floor().as_ivec3();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    if let Some(&(a, b)) = self.map.get(&[x, y, z]) {
                        if self.order[a as usize..b as usize]
                            .iter()
                            .any(|&i| self.pts[i as usize].distance(p) <= r)
                        {
                            return true;
                        }
                    }
                }
            }
        }
        false
    }

    /// Nearest point within `max` (index, distance).
    pub(super) fn nearest(&self, p: Vec3, max: f32) -> Option<(usize, f32)> {
        let c = (p / self.cell).floor().as_ivec3();
        let rings = (max / self.cell).ceil() as i32 + 1;
        let mut best: Option<(usize, f32)> = None;
        for r in 0..=rings {
            // Every point in ring r+1 or beyond is at least r cells away.
            if let Some((_, d)) = best {
                if d <= (r - 1).max(0) as f32 * self.cell {
                    break;
                }
            }
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                            continue;
                        }
                        let k = [c.x + dx, c.y + dy, c.z + dz];
                        let Some(&(a, b)) = self.map.get(&k) else {
                            continue;
                        };
                        for &i in &self.order[a as usize..b as usize] {
                            let d = self.pts[i as usize].distance(p);
                            if d <= max && best.is_none_or(|(_, bd)| d < bd) {
                                best = Some((i as usize, d));
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

/// Unit tangents (root → tip) of every vertex, central differences.
pub(super) fn tangents(s: &StrandSet) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(s.points.len());
    for st in s.strands() {
        for i in 0..st.len() {
            let a = Vec3::from_array(st[i.saturating_sub(1)]);
            let b = Vec3::from_array(st[(i + 1).min(st.len() - 1)]);
            out.push((b - a).normalize_or_zero());
        }
    }
    out
}

/// Compares a reconstructed model (model space, metres) with the ground truth.
pub fn compare_to_gt(model: &StrandSet, gt: &StrandSet, head: &Head) -> GtFigures {
    let gt_pts: Vec<Vec3> = gt.points.iter().map(|&p| Vec3::from_array(p)).collect();
    let m_pts: Vec<Vec3> = model.points.iter().map(|&p| Vec3::from_array(p)).collect();
    let gt_tan = tangents(gt);
    let m_tan = tangents(model);
    let gh = PointHash::new(gt_pts.clone(), 0.01);
    // (angle, or NaN for a vertex without a tangent; distance mm).
    let per: Vec<(f32, f32)> = m_pts
        .par_iter()
        .zip(m_tan.par_iter())
        .map(|(&p, &t)| {
            let tangent = t != Vec3::ZERO;
            match gh.nearest(p, GT_SEARCH_M) {
                Some((i, d)) => {
                    let g = gt_tan[i];
                    let ang = if !tangent {
                        f32::NAN
                    } else if g == Vec3::ZERO {
                        // A GT strand of one vertex has no direction to agree with.
                        180.0
                    } else {
                        t.dot(g).clamp(-1.0, 1.0).acos().to_degrees()
                    };
                    (ang, d * 1000.0)
                }
                None => (if tangent { 180.0 } else { f32::NAN }, GT_SEARCH_M * 1000.0),
            }
        })
        .collect();
    let mut angs: Vec<f32> = per.iter().map(|x| x.0).filter(|a| !a.is_nan()).collect();
    let mut dists: Vec<f32> = per.iter().map(|x| x.1).collect();
    let within = angs.iter().filter(|&&a| a <= 30.0).count();
    let n_ang = angs.len().max(1) as f32;
    let mh = PointHash::new(m_pts.clone(), 0.01);
    let covered = gt_pts
        .par_iter()
        .filter(|&&p| mh.any_within(p, 0.01))
        .count();
    let inside = m_pts.par_iter().filter(|&&p| head.sdf(p) < -0.001).count();
    let n = m_pts.len().max(1) as f32;
    GtFigures {
        model_vertices: m_pts.len(),
        gt_vertices: gt_pts.len(),
        tangent_median_deg: quantile(&mut angs, 0.5, Rank::Floor).unwrap_or(f32::NAN),
        tangent_within_30: within as f32 / n_ang,
        dist_median_mm: quantile(&mut dists, 0.5, Rank::Floor).unwrap_or(f32::NAN),
        dist_p90_mm: quantile(&mut dists, 0.9, Rank::Floor).unwrap_or(f32::NAN),
        gt_covered_1cm: covered as f32 / gt_pts.len().max(1) as f32,
        model_inside_head: inside as f32 / n,
    }
}
