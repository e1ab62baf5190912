//! A multi-scale strand hierarchy (C13 §4 after Wang et al. 2009), so that comb and cut act
//! at any level and the detail below it comes back.
//!
//! Level 0 is the strands. Level L + 1 clusters the members of level L (strands, or the
//! centres of level L) by k-means on a feature vector: `samples` points at equal arc-length
//! fractions (model space), with about `branching` members per cluster, until at most `top`
//! clusters are left. A cluster's centre is a strand of `samples` vertices: the mean of its
//! members' features. Every member is stored as its centre plus a residual: each member
//! vertex at arc fraction u hangs at the centre's point at u, offset by a vector carried by
//! the centre's frames (transported from the root by the smallest turns, the identity at
//! rest). Editing the centres of a level and rebuilding level by level gives back every
//! member's own detail, unchanged, around the edited shape. Clustering is light, branchy
//! work and stays on the CPU (rayon).

use crate::base::rng::Rng;
use crate::base::turn::turn;
use crate::error::{Error, Result};
use crate::hair::strands::StrandSet;
use glam::{Mat3, Vec3};
use rayon::prelude::*;

#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct HierarchyParams {
    /// Members per cluster, about.
    pub branching: usize,
    /// The top level has at most this many clusters.
    pub top: usize,
    /// Points per feature vector and vertices per centre strand.
    pub samples: usize,
    /// Lloyd iterations per level.
    pub iterations: u32,
    pub seed: u64,
}

impl Default for HierarchyParams {
    fn default() -> Self {
        HierarchyParams {
            branching: 16,
            top: 50,
            samples: 16,
            iterations: 6,
            seed: 1,
        }
    }
}

/// One member's residual: per member vertex, its arc fraction along the member and its
/// offset from the centre's point at that fraction, in the centre's rest frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Residual {
    pub u: Vec<f32>,
    pub offset: Vec<[f32; 3]>,
    /// The member's root, kept exactly: roots never move.
    pub root: [f32; 3],
}

/// Clusters of one level.
#[derive(Clone, Debug)]
pub struct Level {
    /// Centre strands, `samples` vertices each.
    pub centres: StrandSet,
    /// For every member (of the level below), its cluster.
    pub parent: Vec<u32>,
    /// For every member, its residual to its cluster's centre.
    pub residuals: Vec<Residual>,
}

#[derive(Clone, Debug)]
pub struct Hierarchy {
    pub params: HierarchyParams,
    /// Level 1, 2, ...: `levels[L - 1]` clusters the members of level L - 1.
    pub levels: Vec<Level>,
}

/// Arc fractions of a polyline's vertices (0 at the root, 1 at the tip; 0 for a point).
fn fractions(p: &[[f32; 3]]) -> Vec<f32> {
    let acc = crate::base::polyline::arc_lengths(p);
    let total = acc[acc.len() - 1];
    acc.iter()
        .map(|&a| if total > 0.0 { (a / total) as f32 } else { 0.0 })
        .collect()
}

/// `m` points at equal arc fractions of a polyline (its root and tip included).
pub fn feature(p: &[[f32; 3]], m: usize) -> Vec<[f32; 3]> {
    let u = fractions(p);
    (0..m)
        .map(|k| {
            let t = k as f32 / (m - 1) as f32;
            at(p, &u, t)
        })
        .collect()
}

/// The point at arc fraction `t` of a polyline whose vertex fractions are `u`.
fn at(p: &[[f32; 3]], u: &[f32], t: f32) -> [f32; 3] {
    if p.len() == 1 {
        return p[0];
    }
    let j = u.partition_point(|&x| x <= t).clamp(1, p.len() - 1);
    let (a, b) = (u[j - 1], u[j]);
    let f = if b > a {
        ((t - a) / (b - a)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    std::array::from_fn(|c| p[j - 1][c] + (p[j][c] - p[j - 1][c]) * f)
}

/// The segment of an `m`-point centre holding arc fraction `t`, and the fraction along it.
fn centre_segment(m: usize, t: f32) -> (usize, f32) {
    let x = (t * (m - 1) as f32).clamp(0.0, (m - 1) as f32);
    let k = (x.floor() as usize).min(m - 2);
    (k, x - k as f32)
}

/// Frames of an edited centre relative to its rest shape: the identity at the root, then
/// per segment the smallest turn from where the frame carries the rest direction to the
/// edited one. At rest every frame is the identity.
fn frames(rest: &[[f32; 3]], now: &[[f32; 3]]) -> Vec<Mat3> {
    let mut q = Mat3::IDENTITY;
    let mut out = Vec::with_capacity(rest.len().saturating_sub(1));
    for k in 0..rest.len().saturating_sub(1) {
        let d0 = (Vec3::from_array(rest[k + 1]) - Vec3::from_array(rest[k])).normalize_or_zero();
        let d1 = (Vec3::from_array(now[k + 1]) - Vec3::from_array(now[k])).normalize_or_zero();
        if d0 != Vec3::ZERO && d1 != Vec3::ZERO {
            q = turn((q * d0).normalize_or_zero(), d1) * q;
        }
        out.push(q);
    }
    out
}

/// A member's residual to a centre (both at rest).
pub fn residual(member: &[[f32; 3]], centre: &[[f32; 3]]) -> Residual {
    let u = fractions(member);
    let m = centre.len();
    let offset = member
        .iter()
        .zip(&u)
        .map(|(p, &t)| {
            let (k, f) = centre_segment(m, t);
            let c = Vec3::from_array(centre[k]).lerp(Vec3::from_array(centre[k + 1]), f);
            (Vec3::from_array(*p) - c).to_array()
        })
        .collect();
    Residual {
        u,
        offset,
        root: member[0],
    }
}

/// A member placed on an edited centre: vertices up to arc fraction `keep` (1: all).
fn place(r: &Residual, centre: &[[f32; 3]], fr: &[Mat3], keep: f32) -> Vec<[f32; 3]> {
    let m = centre.len();
    r.u.iter()
        .zip(&r.offset)
        .take_while(|(&t, _)| t <= keep + 1e-6)
        .enumerate()
        .map(|(j, (&t, o))| {
            if j == 0 {
                return r.root;
            }
            let (k, f) = centre_segment(m, t);
            let c = Vec3::from_array(centre[k]).lerp(Vec3::from_array(centre[k + 1]), f);
            (c + fr[k] * Vec3::from_array(*o)).to_array()
        })
        .collect()
}

fn dist2(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f32>())
        .sum()
}

/// k-means (Lloyd) of equal-length features; returns the centres and each point's cluster.
fn kmeans(
    feats: &[Vec<[f32; 3]>],
    k: usize,
    iterations: u32,
    rng: &mut Rng,
) -> (Vec<Vec<[f32; 3]>>, Vec<u32>) {
    let n = feats.len();
    // Seeds: a random permutation's first k, so a re-run with the same seed is identical.
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        order.swap(i, rng.below(i as u32 + 1) as usize);
    }
    let mut centres: Vec<Vec<[f32; 3]>> = order[..k].iter().map(|&i| feats[i].clone()).collect();
    let mut assign = vec![0u32; n];
    for _ in 0..iterations.max(1) {
        assign = feats
            .par_iter()
            .map(|f| {
                let mut best = (f32::INFINITY, 0u32);
                for (c, ctr) in centres.iter().enumerate() {
                    let d = dist2(f, ctr);
                    if d < best.0 {
                        best = (d, c as u32);
                    }
                }
                best.1
            })
            .collect();
        let m = feats[0].len();
        let mut sum = vec![vec![[0.0f64; 3]; m]; k];
        let mut count = vec![0usize; k];
        for (f, &a) in feats.iter().zip(&assign) {
            count[a as usize] += 1;
            for (s, p) in sum[a as usize].iter_mut().zip(f) {
                for c in 0..3 {
                    s[c] += p[c] as f64;
                }
            }
        }
        for (c, ctr) in centres.iter_mut().enumerate() {
            // An empty cluster keeps its centre.
            if count[c] > 0 {
                for (q, s) in ctr.iter_mut().zip(&sum[c]) {
                    *q = s.map(|v| (v / count[c] as f64) as f32);
                }
            }
        }
    }
    (centres, assign)
}

impl Hierarchy {
    /// Builds the levels above `strands` (model space).
    pub fn build(strands: &StrandSet, p: &HierarchyParams) -> Result<Hierarchy> {
        strands.validate()?;
        if p.samples < 2 || p.branching < 2 || p.top < 1 {
            return Err(Error::Invalid(format!(
                "hierarchy: samples {} and branching {} must be at least 2, top {} at least 1",
                p.samples, p.branching, p.top
            )));
        }
        let mut rng = Rng::new(p.seed);
        let mut members: Vec<Vec<[f32; 3]>> = strands.strands().map(|s| s.to_vec()).collect();
        let mut levels = Vec::new();
        while members.len() > p.top {
            let k = members
                .len()
                .div_ceil(p.branching)
                .max(p.top.min(members.len()));
            let feats: Vec<Vec<[f32; 3]>> =
                members.par_iter().map(|s| feature(s, p.samples)).collect();
            let (centres, parent) =
                kmeans(&feats, k, p.iterations, &mut rng.fork(levels.len() as u64));
            let residuals = members
                .par_iter()
                .zip(&parent)
                .map(|(s, &c)| residual(s, &centres[c as usize]))
                .collect();
            let mut set = StrandSet::default();
            for c in &centres {
                set.push(c);
            }
            levels.push(Level {
                centres: set,
                parent,
                residuals,
            });
            members = centres;
            if k <= p.top {
                break;
            }
        }
        Ok(Hierarchy { params: *p, levels })
    }

    /// The strands of `level` (0: the strands themselves, which the caller holds).
    pub fn centres(&self, level: usize) -> Result<&StrandSet> {
        match level {
            0 => Err(Error::Invalid("level 0 is the strands themselves".into())),
            l if l <= self.levels.len() => Ok(&self.levels[l - 1].centres),
            l => Err(Error::Invalid(format!(
                "--level {l}: the hierarchy has levels 0 to {}",
                self.levels.len()
            ))),
        }
    }

    /// Rebuilds every level below `level` from its edited centres, down to the strands.
    /// `edited` has the level's centres, possibly cut shorter (fewer vertices: members keep
    /// the same share of their arc length); `strands` gives the members' attributes.
    pub fn rebuild(
        &self,
        level: usize,
        edited: &StrandSet,
        strands: &StrandSet,
    ) -> Result<StrandSet> {
        self.rebuild_levels(level, edited, strands).map(|(s, _)| s)
    }

    /// [`Hierarchy::rebuild`], also returning the rebuilt members of every level below
    /// `level`, top first (the last entry is the strands' points).
    #[allow(clippy::type_complexity)] // one list of polylines per level
    pub fn rebuild_levels(
        &self,
        level: usize,
        edited: &StrandSet,
        strands: &StrandSet,
    ) -> Result<(StrandSet, Vec<Vec<Vec<[f32; 3]>>>)> {
        let rest = self.centres(level)?;
        if edited.len() != rest.len() {
            return Err(Error::Invalid(format!(
                "{} edited centres for {} at level {level}",
                edited.len(),
                rest.len()
            )));
        }
        let mut now: Vec<Vec<[f32; 3]>> = edited.strands().map(|s| s.to_vec()).collect();
        let mut keep: Vec<f32> = edited
            .counts
            .iter()
            .zip(&rest.counts)
            .map(|(&a, &b)| {
                if a >= b {
                    1.0
                } else {
                    (a.max(1) - 1) as f32 / (b - 1) as f32
                }
            })
            .collect();
        let mut history = Vec::with_capacity(level);
        for l in (0..level).rev() {
            let lv = &self.levels[l];
            let rest_c: Vec<&[[f32; 3]]> = lv.centres.strands().collect();
            // A cut centre keeps its rest shape past the cut, for its frames.
            let full_now: Vec<Vec<[f32; 3]>> = rest_c
                .iter()
                .zip(&now)
                .map(|(r, n)| {
                    let mut n = n.clone();
                    n.extend_from_slice(&r[n.len()..]);
                    n
                })
                .collect();
            let fr: Vec<Vec<Mat3>> = rest_c
                .iter()
                .zip(&full_now)
                .map(|(r, n)| frames(r, n))
                .collect();
            let (members, kept): (Vec<Vec<[f32; 3]>>, Vec<f32>) = lv
                .residuals
                .par_iter()
                .zip(&lv.parent)
                .map(|(r, &c)| {
                    let c = c as usize;
                    let pts = place(r, &full_now[c], &fr[c], keep[c]);
                    (pts, keep[c])
                })
                .unzip();
            history.push(members.clone());
            now = members;
            keep = kept;
        }
        // The strands: attributes follow the vertices kept.
        let mut out = StrandSet::default();
        let off = strands.offsets();
        let mut colors = strands.colors.as_ref().map(|_| Vec::new());
        let mut transparency = strands.transparency.as_ref().map(|_| Vec::new());
        let mut thickness = strands.thickness.as_ref().map(|_| Vec::new());
        for (i, pts) in now.iter().enumerate() {
            // The root always stays.
            let pts: &[[f32; 3]] = if pts.is_empty() {
                &strands.points[off[i]..off[i] + 1]
            } else {
                pts
            };
            out.push(pts);
            let r = off[i]..off[i] + pts.len();
            if let (Some(d), Some(s)) = (&mut colors, &strands.colors) {
                d.extend_from_slice(&s[r.clone()]);
            }
            if let (Some(d), Some(s)) = (&mut transparency, &strands.transparency) {
                d.extend_from_slice(&s[r.clone()]);
            }
            if let (Some(d), Some(s)) = (&mut thickness, &strands.thickness) {
                d.extend_from_slice(&s[r]);
            }
        }
        out.colors = colors;
        out.transparency = transparency;
        out.thickness = thickness;
        Ok((out, history))
    }

    /// The residual of a placed member re-derived against an edited centre (the inverse of
    /// placing it): what a test compares with the stored residual.
    pub fn offsets_on(
        r: &Residual,
        rest: &[[f32; 3]],
        now: &[[f32; 3]],
        member: &[[f32; 3]],
    ) -> Vec<[f32; 3]> {
        let fr = frames(rest, now);
        let m = now.len();
        member
            .iter()
            .zip(&r.u)
            .map(|(p, &t)| {
                let (k, f) = centre_segment(m, t);
                let c = Vec3::from_array(now[k]).lerp(Vec3::from_array(now[k + 1]), f);
                (fr[k].transpose() * (Vec3::from_array(*p) - c)).to_array()
            })
            .collect()
    }
}
