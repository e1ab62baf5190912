//! One red-black SOR half-sweep of the robust flow energy of one warping step (see
//! `wgsl/flow_solve.wgsl`).

use super::flow_warp::DERIV_PER_PX;
use crate::gpu::engine::{groups, Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "flow_solve",
    wgsl: include_str!("../../wgsl/flow_solve.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::ReadWrite],
    cpu: flow_solve_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// Pixels with `(x + y) & 1 == colour` are relaxed.
    pub colour: u32,
    pub _pad0: u32,
    /// Smoothness weight α (in units of the squared feature gradient).
    pub alpha: f32,
    /// Charbonnier scale of the data residual; 0: quadratic.
    pub eps_data: f32,
    /// Charbonnier scale of the flow difference between neighbours, in pixels; 0: quadratic.
    pub eps_smooth: f32,
    /// Over-relaxation factor ω in (0, 2).
    pub omega: f32,
}

/// Threads cover half of each row (one colour), 8x8 groups.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [groups(cfg.width.div_ceil(2), 8), groups(cfg.height, 8), 1]
}

/// Robust weight 1/sqrt(1 + s2/eps²); 1 (quadratic) when eps is 0.
#[inline]
fn robust(s2: f32, eps: f32) -> f32 {
    if eps > 0.0 {
        1.0 / (1.0 + s2 / (eps * eps)).sqrt()
    } else {
        1.0
    }
}

#[inline]
fn dot(a: [f32; 2], b: [f32; 2]) -> f32 {
    a[0] * b[0] + a[1] * b[1]
}

fn flow_solve_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let g_deriv = b[1].get::<[f32; 2]>();
    let deriv: &[[f32; 2]] = &g_deriv;
    let mut flow = b[2].get_mut::<[f32; 2]>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    // Pixels of one colour read only the other colour: relax from a snapshot.
    let old = flow[..w * h].to_vec();
    flow[..w * h]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            let x0 = (y + cfg.colour as usize) & 1;
            for x in (x0..w).step_by(2) {
                let i = y * w + x;
                let u = old[i];
                let d = &deriv[DERIV_PER_PX * i..DERIV_PER_PX * (i + 1)];
                let (ix, iy, c0) = (d[0], d[1], d[2]);
                let r = [
                    c0[0] + ix[0] * u[0] + iy[0] * u[1],
                    c0[1] + ix[1] * u[0] + iy[1] * u[1],
                ];
                let wd = robust(dot(r, r), cfg.eps_data);
                let (mut sw, mut su) = (0.0f32, [0.0f32; 2]);
                let mut add_nb = |j: usize| {
                    let uj = old[j];
                    let dd = [u[0] - uj[0], u[1] - uj[1]];
                    let wj = robust(dot(dd, dd), cfg.eps_smooth);
                    sw += wj;
                    su[0] += wj * uj[0];
                    su[1] += wj * uj[1];
                };
                if x > 0 {
                    add_nb(i - 1);
                }
                if x + 1 < w {
                    add_nb(i + 1);
                }
                if y > 0 {
                    add_nb(i - w);
                }
                if y + 1 < h {
                    add_nb(i + w);
                }
                let s = cfg.alpha * sw;
                let a00 = wd * dot(ix, ix) + s;
                let a01 = wd * dot(ix, iy);
                let a11 = wd * dot(iy, iy) + s;
                let b0 = -wd * dot(c0, ix) + cfg.alpha * su[0];
                let b1 = -wd * dot(c0, iy) + cfg.alpha * su[1];
                let det = a00 * a11 - a01 * a01;
                if det > 0.0 {
                    let un = [(a11 * b0 - a01 * b1) / det, (a00 * b1 - a01 * b0) / det];
                    row[x] = [
                        u[0] + cfg.omega * (un[0] - u[0]),
                        u[1] + cfg.omega * (un[1] - u[1]),
                    ];
                }
            }
        });
}
