//! One half-sweep of red-black Gauss-Seidel for CZ06 Step 1's orientation field (Eq. 25,
//! signs corrected); see `wgsl/cz_theta_gs.wgsl` for the update and why it lowers the energy.
//! The host is `crate::sketch::theta`.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "cz_theta_gs",
    wgsl: include_str!("../../wgsl/cz_theta_gs.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: cz_theta_gs_cpu,
};

/// Pixel flags: off the hair (neither updated nor a neighbour).
pub const OFF: u32 = 0;
/// A pixel the sweep updates.
pub const FREE: u32 = 1;
/// A pixel held by the sketch (a neighbour, never updated).
pub const FIXED: u32 = 2;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// The colour updated: pixels with (x + y) mod 2 == parity.
    pub parity: u32,
    /// 1/2λθ², the weight of a neighbour.
    pub half_smooth: f32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width, 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

fn cz_theta_gs_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_data, g_flags, g_src) = (
        b[1].get::<[f32; 2]>(),
        b[2].get::<u32>(),
        b[3].get::<[f32; 2]>(),
    );
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (data, flags, src): (&[[f32; 2]], &[u32], &[[f32; 2]]) = (&g_data, &g_flags, &g_src);
    let mut dst = b[4].get_mut::<[f32; 2]>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let neighbour = |x: i64, y: i64| -> [f32; 2] {
        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
            return [0.0; 2];
        }
        let j = y as usize * w + x as usize;
        if flags[j] == OFF {
            return [0.0; 2];
        }
        src[j]
    };
    dst[..w * h]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let i = y * w + x;
                let z = src[i];
                if flags[i] != FREE || ((x + y) & 1) as u32 != cfg.parity {
                    *out = z;
                    continue;
                }
                let (xi, yi) = (x as i64, y as i64);
                let (l, r, u, d) = (
                    neighbour(xi - 1, yi),
                    neighbour(xi + 1, yi),
                    neighbour(xi, yi - 1),
                    neighbour(xi, yi + 1),
                );
                let nb = [l[0] + r[0] + u[0] + d[0], l[1] + r[1] + u[1] + d[1]];
                let sum = [
                    data[i][0] + cfg.half_smooth * nb[0],
                    data[i][1] + cfg.half_smooth * nb[1],
                ];
                let n2 = sum[0] * sum[0] + sum[1] * sum[1];
                *out = if n2 > 1e-24 {
                    let n = n2.sqrt();
                    [sum[0] / n, sum[1] / n]
                } else {
                    z
                };
            }
        });
}
