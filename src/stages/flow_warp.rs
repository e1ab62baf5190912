//! One warping step of the coarse-to-fine flow: warp frame b by the current flow and
//! linearise the 2-channel data term (see `wgsl/flow_warp.wgsl`).

use super::flow_up::mix2;
use crate::gpu::engine::{groups, Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "flow_warp",
    wgsl: include_str!("../../wgsl/flow_warp.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: flow_warp_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// A WGSL `vec2<f32>` element.
type Vec2 = [f32; 2];

/// vec2 slots per pixel in the `deriv` buffer: Ix, Iy, c0.
pub const DERIV_PER_PX: usize = 3;

/// One invocation per pixel, 8x8 groups.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [groups(cfg.width, 8), groups(cfg.height, 8), 1]
}

#[inline]
fn sub(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// WGSL `transport`: the double-angle feature `f` = w (cos 2θ, sin 2θ) of a tangent mapped by
/// the matrix with columns `c0`, `c1`, same weight w.
#[inline]
fn transport(f: [f32; 2], c0: [f32; 2], c1: [f32; 2]) -> [f32; 2] {
    let w = f[0].hypot(f[1]);
    if w <= 0.0 {
        return [0.0; 2];
    }
    let th = 0.5 * f[1].atan2(f[0]);
    let (s, c) = th.sin_cos();
    let t = [c * c0[0] + s * c1[0], c * c0[1] + s * c1[1]];
    let n2 = t[0] * t[0] + t[1] * t[1];
    if n2 <= 0.0 {
        return f;
    }
    let k = w / n2;
    [k * (t[0] * t[0] - t[1] * t[1]), k * (2.0 * t[0] * t[1])]
}

fn flow_warp_cpu(_wg: [u32; 3], bind: &[CpuBinding]) {
    let cfg: Config = bind[0].uniform();
    let (g_a, g_b, g_flow) = (
        bind[1].get::<[f32; 2]>(),
        bind[2].get::<[f32; 2]>(),
        bind[3].get::<[f32; 2]>(),
    );
    let (a, b, flow): (&[Vec2], &[Vec2], &[Vec2]) = (&g_a, &g_b, &g_flow);
    let mut deriv = bind[4].get_mut::<[f32; 2]>();
    let (w, h) = (cfg.width as i32, cfg.height as i32);
    let clamped = |x: i32, y: i32| (y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize;
    let a_at = |x: i32, y: i32| a[clamped(x, y)];
    let flow_at = |x: i32, y: i32| flow[clamped(x, y)];
    let hi = [(w - 1) as f32, (h - 1) as f32];
    const OFFS: [(usize, usize); 5] = [(1, 1), (2, 1), (0, 1), (1, 2), (1, 0)];
    deriv[..DERIV_PER_PX * (w * h) as usize]
        .par_chunks_mut(DERIV_PER_PX * w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as i32;
            for x in 0..w {
                let i = (y * w + x) as usize;
                let out = &mut row[DERIV_PER_PX * x as usize..DERIV_PER_PX * (x as usize + 1)];
                let u = flow[i];
                let p = [x as f32 + u[0], y as f32 + u[1]];
                if !(p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= hi[0] && p[1] <= hi[1]) {
                    out.fill([0.0; 2]);
                    continue;
                }
                let (x0, y0) = (p[0].floor() as i32, p[1].floor() as i32);
                let f = [p[0] - x0 as f32, p[1] - y0 as f32];
                let mut t = [[0.0f32; 2]; 16];
                for j in 0..4 {
                    let yy = (y0 - 1 + j).clamp(0, h - 1);
                    for k in 0..4 {
                        let xx = (x0 - 1 + k).clamp(0, w - 1);
                        t[(4 * j + k) as usize] = b[(yy * w + xx) as usize];
                    }
                }
                let mut s = [[0.0f32; 2]; 5];
                for (n, &(ox, oy)) in OFFS.iter().enumerate() {
                    let o = 4 * oy + ox;
                    let top = mix2(t[o], t[o + 1], f[0]);
                    let bot = mix2(t[o + 4], t[o + 5], f[0]);
                    s[n] = mix2(top, bot, f[1]);
                }
                let ax = sub(a_at(x + 1, y), a_at(x - 1, y));
                let ay = sub(a_at(x, y + 1), a_at(x, y - 1));
                let (dbx, dby) = (sub(s[1], s[2]), sub(s[3], s[4]));
                // Columns of J = I + ∇u.
                let du_dx = sub(flow_at(x + 1, y), flow_at(x - 1, y));
                let du_dy = sub(flow_at(x, y + 1), flow_at(x, y - 1));
                let at = transport(
                    a[i],
                    [1.0 + 0.5 * du_dx[0], 0.5 * du_dx[1]],
                    [0.5 * du_dy[0], 1.0 + 0.5 * du_dy[1]],
                );
                let it = sub(s[0], at);
                let mut ix = [0.0f32; 2];
                let mut iy = [0.0f32; 2];
                let mut c0 = [0.0f32; 2];
                for c in 0..2 {
                    ix[c] = 0.5 * (0.5 * dbx[c] + 0.5 * ax[c]);
                    iy[c] = 0.5 * (0.5 * dby[c] + 0.5 * ay[c]);
                    c0[c] = it[c] - ix[c] * u[0] - iy[c] * u[1];
                }
                out[0] = ix;
                out[1] = iy;
                out[2] = c0;
            }
        });
}
