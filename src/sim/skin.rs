//! The full strands follow their simulated guides. Each strand is simulated as a chain of
//! `n` vertices at equal arc length ([`super::resample`]); every vertex of the full strand
//! hangs on the guide segment at its own arc length, at the same fraction along it, with
//! its offset from that point turned by the segment's frame: the head's rotation at the
//! root, transported segment by segment by the smallest turn that takes the carried rest
//! direction to the current one. Roots sit exactly on the guides' roots, the full strand's
//! detail (its curls between guide vertices) turns with the hair, and a strand too short to
//! simulate is carried rigidly by the head.

use crate::base::turn::turn;
use crate::hair::strands::StrandSet;
use crate::sim::track::{self, Rigid};
use glam::Vec3;

/// Where every vertex of the full strands hangs on the guides.
pub struct Skin {
    /// Per full vertex: the guide vertex starting its segment (global index into the guide
    /// positions), or `u32::MAX` for strands carried rigidly by the head.
    seg: Vec<u32>,
    t: Vec<f32>,
    offset: Vec<Vec3>,
    /// The full strands at rest (model space), attributes included.
    rest: StrandSet,
    /// Rest direction of every guide segment (unit; zero for the last vertex of a guide).
    rest_dir: Vec<Vec3>,
}

impl Skin {
    /// `full` are the strands as modelled, `guides` the resampled rest guides (after any
    /// rest-shape adjustment) with `n` vertices each, `dropped` the full strands that have
    /// no guide (in increasing order), as [`super::resample`] returns them.
    pub fn new(full: &StrandSet, guides: &StrandSet, n: usize, dropped: &[usize]) -> Skin {
        let gp = |g: usize| Vec3::from_array(guides.points[g]);
        let mut rest_dir = vec![Vec3::ZERO; guides.points.len()];
        for (g, d) in rest_dir.iter_mut().enumerate() {
            if g % n != n - 1 {
                *d = (gp(g + 1) - gp(g)).normalize_or_zero();
            }
        }
        let mut seg = Vec::with_capacity(full.points.len());
        let mut t = Vec::with_capacity(full.points.len());
        let mut offset = Vec::with_capacity(full.points.len());
        let mut next_dropped = dropped.iter().peekable();
        let mut guide = 0usize;
        for (i, st) in full.strands().enumerate() {
            if next_dropped.peek() == Some(&&i) {
                next_dropped.next();
                for _ in st {
                    seg.push(u32::MAX);
                    t.push(0.0);
                    offset.push(Vec3::ZERO);
                }
                continue;
            }
            // Arc length of every vertex, as resample measured it.
            let acc = crate::base::polyline::arc_lengths(st);
            let total = acc[acc.len() - 1];
            let base = guide * n;
            for (j, p) in st.iter().enumerate() {
                let u = (acc[j] / total * (n - 1) as f64).clamp(0.0, (n - 1) as f64);
                let k = (u.floor() as usize).min(n - 2);
                let f = (u - k as f64) as f32;
                let at = gp(base + k).lerp(gp(base + k + 1), f);
                seg.push((base + k) as u32);
                t.push(f);
                offset.push(Vec3::from_array(*p) - at);
            }
            guide += 1;
        }
        Skin {
            seg,
            t,
            offset,
            rest: full.clone(),
            rest_dir,
        }
    }

    /// The full strands for guide positions `x` (xyz per guide vertex) with the head at `m`.
    pub fn apply(&self, x: &[f32], m: &Rigid) -> StrandSet {
        let xp = |g: usize| Vec3::new(x[3 * g], x[3 * g + 1], x[3 * g + 2]);
        // A frame per guide segment, transported from the root: the head's rotation at the
        // root, then at each segment the smallest turn from where the frame carries the
        // rest direction to the segment's direction now. A rigid motion of the guides thus
        // moves the detail rigidly too (every turn is the identity).
        let nv = self.rest_dir.len();
        let mut frame = vec![m.0; nv];
        let mut q = m.0;
        for (g, (fr, &d0)) in frame.iter_mut().zip(&self.rest_dir).enumerate() {
            if d0 == Vec3::ZERO {
                // The guide's last vertex: the next guide starts at the head's frame again.
                q = m.0;
                continue;
            }
            let now = (xp(g + 1) - xp(g)).normalize_or_zero();
            q = turn((q * d0).normalize_or_zero(), now) * q;
            *fr = q;
        }
        let mut out = self.rest.clone();
        for (v, p) in out.points.iter_mut().enumerate() {
            let g = self.seg[v];
            if g == u32::MAX {
                *p = track::apply(m, self.rest.points[v]);
                continue;
            }
            let g = g as usize;
            let at = xp(g).lerp(xp(g + 1), self.t[v]);
            *p = (at + frame[g] * self.offset[v]).to_array();
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::resample;
    use glam::Mat3;

    /// At rest the skin gives back the modelled strands; a rigid motion of the guides moves
    /// the full strands by the same motion.
    #[test]
    fn rest_is_exact_and_rigid_motion_carries_the_detail() {
        let pts: Vec<[f32; 3]> = (0..17)
            .map(|i| {
                let s = i as f32 * 0.01;
                [s, 0.003 * (s * 900.0).sin(), 0.002 * (s * 700.0).cos()]
            })
            .collect();
        let mut full = StrandSet::new(pts.clone(), vec![17]);
        full.push(&[[0.5, 0.5, 0.5]]); // one vertex: dropped, carried rigidly
        let (guides, dropped) = resample(&full, 6);
        assert_eq!(dropped, vec![1]);
        let skin = Skin::new(&full, &guides, 6, &dropped);
        let x: Vec<f32> = guides.points.iter().flatten().copied().collect();
        let id = (Mat3::IDENTITY, Vec3::ZERO);
        let back = skin.apply(&x, &id);
        for (a, b) in back.points.iter().zip(&full.points) {
            assert!((Vec3::from_array(*a) - Vec3::from_array(*b)).length() < 1e-6);
        }
        let m = (Mat3::from_rotation_z(0.7), Vec3::new(0.1, 0.0, 0.0));
        let xm: Vec<f32> = guides
            .points
            .iter()
            .flat_map(|p| track::apply(&m, *p))
            .collect();
        let moved = skin.apply(&xm, &m);
        for (a, b) in moved.points.iter().zip(&full.points) {
            let want = Vec3::from_array(track::apply(&m, *b));
            assert!(
                (Vec3::from_array(*a) - want).length() < 1e-5,
                "{a:?} {want}"
            );
        }
    }
}
