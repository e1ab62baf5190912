//! Comb (C13 appendix A.1), one invocation per strand. Pairs with `wgsl/edit_comb.wgsl`;
//! the mirror below does the same f32 arithmetic in the same order.
//!
//! A comb stroke γ (image px) defines f(p) = t(p′)·h(‖p−p′‖), p′ the nearest stroke point,
//! t the stroke direction there and h a tent, 1 at 0 and 0 at R and beyond. (The paper
//! prints "h = 0 when ‖p−p′‖² ≥ R", which would make R = 32 a 5.7 px radius: a typo for
//! ‖p−p′‖ ≥ R.) Root to tip, each vertex k whose projection is within R of γ turns the rest
//! of its strand (k+1 onward) about the view axis through vertex k by h × the signed image
//! angle from the projected segment k→k+1 to t. The paper gives no angle; this one makes a
//! vertex on the stroke align its segment with it exactly.
//!
//! Turns about parallel axes only rotate the later segments, so the strand is rebuilt from
//! its segments in camera space, each turned by the angle accumulated so far: x and y of a
//! segment rotate, its view z (depth) is untouched, and its length is kept to rounding.
//! Image y points down while view y points up, so a turn by δ in the image is −δ in view.
//! Vertices before the first turn, and strands that never come within R, are not written.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use crate::stages::edit_stroke::{nearest, project};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "edit_comb",
    wgsl: include_str!("../../wgsl/edit_comb.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::Read, Bind::ReadWrite],
    cpu: edit_comb_cpu,
};

/// Workgroup width of the WGSL entry point.
pub const WORKGROUP: u32 = 64;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub n_strands: u32,
    pub n_segs: u32,
    /// R, image px.
    pub radius: f32,
    /// Camera scale, px per metre.
    pub s: f32,
    /// Camera rotation model → view, row-major.
    pub r00: f32,
    pub r01: f32,
    pub r02: f32,
    pub r10: f32,
    pub r11: f32,
    pub r12: f32,
    pub r20: f32,
    pub r21: f32,
    pub r22: f32,
    /// Image position of the model origin, px.
    pub tx: f32,
    pub ty: f32,
    pub _pad0: u32,
}

impl Config {
    pub fn rows(&self) -> [[f32; 3]; 3] {
        [
            [self.r00, self.r01, self.r02],
            [self.r10, self.r11, self.r12],
            [self.r20, self.r21, self.r22],
        ]
    }
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.n_strands, WORKGROUP), 1, 1]
}

type V3 = [f32; 3];

fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn turn(v: V3, a: f32) -> V3 {
    let (s, c) = (a.sin(), a.cos());
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

/// Combs one strand in place (`x`: its vertices, xyz); returns whether any vertex moved.
pub fn comb_strand(cfg: &Config, segs: &[f32], x: &mut [f32]) -> bool {
    let n = x.len() / 3;
    let [r0, r1, r2] = cfg.rows();
    let get = |x: &[f32], i: usize| -> V3 { [x[3 * i], x[3 * i + 1], x[3 * i + 2]] };
    let mut phi = 0.0f32;
    let mut touched = false;
    let mut prev_orig = get(x, 0);
    let mut prev_new = prev_orig;
    for k in 0..n.saturating_sub(1) {
        let next_orig = get(x, k + 1);
        let e = [
            next_orig[0] - prev_orig[0],
            next_orig[1] - prev_orig[1],
            next_orig[2] - prev_orig[2],
        ];
        let e0 = [dot(r0, e), dot(r1, e), dot(r2, e)];
        let mut ev = turn(e0, phi);
        let pk = project(r0, r1, cfg.s, [cfg.tx, cfg.ty], prev_new);
        let (dist, t) = nearest(segs, cfg.n_segs, pk);
        if dist < cfg.radius {
            let h = 1.0 - dist / cfg.radius;
            // The segment's image direction (y down).
            let (sx, sy) = (ev[0], -ev[1]);
            if sx != 0.0 || sy != 0.0 {
                let delta = (sx * t[1] - sy * t[0]).atan2(sx * t[0] + sy * t[1]);
                phi -= h * delta;
                ev = turn(e0, phi);
            }
            touched = true;
        }
        let mut next_new = next_orig;
        if touched {
            // Back to model space with the transposed rotation.
            next_new = [
                prev_new[0] + r0[0] * ev[0] + r1[0] * ev[1] + r2[0] * ev[2],
                prev_new[1] + r0[1] * ev[0] + r1[1] * ev[1] + r2[1] * ev[2],
                prev_new[2] + r0[2] * ev[0] + r1[2] * ev[1] + r2[2] * ev[2],
            ];
            x[3 * (k + 1)..3 * (k + 2)].copy_from_slice(&next_new);
        }
        prev_orig = next_orig;
        prev_new = next_new;
    }
    touched
}

/// Splits packed vertices (xyz) into one mutable slice per strand by `offsets`.
pub fn split_strands<'a>(mut x: &'a mut [f32], offsets: &[u32]) -> Vec<&'a mut [f32]> {
    let mut out = Vec::with_capacity(offsets.len().saturating_sub(1));
    for w in offsets.windows(2) {
        let (a, b) = std::mem::take(&mut x).split_at_mut(3 * (w[1] - w[0]) as usize);
        out.push(a);
        x = b;
    }
    out
}

/// Bindings: cfg, segs (8 f32 per stroke segment), offsets (n_strands + 1, vertices, the
/// first 0), xs (xyz per vertex, model space, in place).
pub fn edit_comb_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let segs = b[1].get::<f32>();
    let offsets = b[2].get::<u32>();
    let mut xs = b[3].get_mut::<f32>();
    let segs = &*segs;
    let ns = cfg.n_strands as usize;
    let start = 3 * offsets[0] as usize;
    split_strands(&mut xs[start..], &offsets[..ns + 1])
        .into_par_iter()
        .for_each(|x| {
            comb_strand(&cfg, segs, x);
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stages::edit_stroke::pack_segments;

    /// A strand hanging straight down the image, combed by a stroke drawn left to right
    /// across it: the part past the stroke turns to point right (+x image), keeps its
    /// segment lengths and depths, and the root stays put.
    #[test]
    fn a_hanging_strand_turns_to_the_stroke_direction() {
        let cfg = Config {
            n_strands: 1,
            n_segs: 1,
            radius: 8.0,
            s: 100.0,
            r00: 1.0,
            r11: 1.0,
            r22: 1.0,
            tx: 50.0,
            ty: 50.0,
            ..Default::default()
        };
        let segs = pack_segments(&[vec![[0.0, 60.0], [200.0, 60.0]]]);
        // Image y = 50 − 100·y: y from 0 down to −0.3 crosses the stroke at image y 60.
        let n = 31;
        let mut x: Vec<f32> = (0..n)
            .flat_map(|i| [0.0, -0.01 * i as f32, 0.002 * i as f32])
            .collect();
        let x0 = x.clone();
        assert!(comb_strand(&cfg, &segs, &mut x));
        assert_eq!(x[..3], x0[..3]);
        for i in 0..n - 1 {
            let e: Vec<f32> = (0..3).map(|c| x[3 * i + 3 + c] - x[3 * i + c]).collect();
            let l = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
            assert!((l - (0.0001f32 + 0.000004).sqrt()).abs() < 1e-6, "{l}");
            assert!((e[2] - 0.002).abs() < 1e-7);
        }
        // The last segment is inside the band and points right in the image.
        let k = 3 * (n - 2);
        let (ex, ey) = (x[k + 3] - x[k], x[k + 4] - x[k + 1]);
        assert!(ex > 0.0 && ey.abs() < 0.05 * ex, "{ex} {ey}");
    }
}
