//! One Jacobi sweep of constrained linear vector-field diffusion (C13 §2.1 dense direction).
//! CZ06's fill-in (Eq. 16-17: nonlinear in the angle, with a growing weight schedule) is a
//! different pass, `cz_fill`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "dir_diffuse",
    wgsl: include_str!("../../wgsl/dir_diffuse.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: dir_diffuse_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub lambda: f32,
    pub use_orient: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width, 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

/// The per-pixel tangents (cos θ, sin θ) interleaved, NaN where θ is NaN: the `tangent`
/// binding, computed once for all the sweeps.
pub fn tangents(theta: &[f32]) -> Vec<f32> {
    let mut t = vec![0.0f32; 2 * theta.len()];
    t.par_chunks_mut(2)
        .zip(theta.par_iter())
        .for_each(|(t, &th)| {
            let (s, c) = if th.is_nan() {
                (f32::NAN, f32::NAN)
            } else {
                th.sin_cos()
            };
            t[0] = c;
            t[1] = s;
        });
    t
}

fn dir_diffuse_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_tangent, g_mask, g_known, g_known_w, g_src) = (
        b[1].get::<f32>(),
        b[2].get::<u32>(),
        b[3].get::<f32>(),
        b[4].get::<f32>(),
        b[5].get::<f32>(),
    );
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (tangent, mask, known): (&[f32], &[u32], &[f32]) = (&g_tangent, &g_mask, &g_known);
    let (known_w, src): (&[f32], &[f32]) = (&g_known_w, &g_src);
    let mut dst = b[6].get_mut::<f32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let orient = cfg.use_orient == 1;
    dst[..2 * w * h]
        .par_chunks_mut(2 * w)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let i = y * w + x;
                if mask[i] == 0 {
                    row[2 * x] = 0.0;
                    row[2 * x + 1] = 0.0;
                    continue;
                }
                // The four neighbours in the shader's order (left, right, up, down), so the
                // sums round the same way.
                let (mut sx, mut sy, mut n) = (0.0f32, 0.0f32, 0.0f32);
                let mut add = |j: usize| {
                    if mask[j] != 0 {
                        sx += src[2 * j];
                        sy += src[2 * j + 1];
                        n += 1.0;
                    }
                };
                if x > 0 {
                    add(i - 1);
                }
                if x + 1 < w {
                    add(i + 1);
                }
                if y > 0 {
                    add(i - w);
                }
                if y + 1 < h {
                    add(i + w);
                }
                let c = cfg.lambda * known_w[i];
                let den = n + c;
                let (mut vx, mut vy) = if den > 0.0 {
                    (
                        (sx + c * known[2 * i]) / den,
                        (sy + c * known[2 * i + 1]) / den,
                    )
                } else {
                    (0.0, 0.0)
                };
                if orient && !tangent[2 * i].is_nan() {
                    let (tx, ty) = (tangent[2 * i], tangent[2 * i + 1]);
                    let d = vx * tx + vy * ty;
                    vx = d * tx;
                    vy = d * ty;
                }
                row[2 * x] = vx;
                row[2 * x + 1] = vy;
            }
        });
}
