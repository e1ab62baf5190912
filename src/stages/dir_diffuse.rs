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

fn dir_diffuse_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_theta, g_mask, g_known, g_known_w, g_src) = (
        b[1].get::<f32>(),
        b[2].get::<u32>(),
        b[3].get::<f32>(),
        b[4].get::<f32>(),
        b[5].get::<f32>(),
    );
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (theta, mask, known): (&[f32], &[u32], &[f32]) = (&g_theta, &g_mask, &g_known);
    let (known_w, src): (&[f32], &[f32]) = (&g_known_w, &g_src);
    let mut dst = b[6].get_mut::<f32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
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
                let (mut sx, mut sy, mut n) = (0.0f32, 0.0f32, 0.0f32);
                for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                        continue;
                    }
                    let j = yy as usize * w + xx as usize;
                    if mask[j] == 0 {
                        continue;
                    }
                    sx += src[2 * j];
                    sy += src[2 * j + 1];
                    n += 1.0;
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
                if cfg.use_orient == 1 && !theta[i].is_nan() {
                    let (tx, ty) = (theta[i].cos(), theta[i].sin());
                    let d = vx * tx + vy * ty;
                    vx = d * tx;
                    vy = d * ty;
                }
                row[2 * x] = vx;
                row[2 * x + 1] = vy;
            }
        });
}
