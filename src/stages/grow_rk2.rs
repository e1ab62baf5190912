//! RK2 strand growth in the 3D direction field, one invocation per strand (C13 §2.2).
//! Pairs with `wgsl/grow_rk2.wgsl`; the mirror below does the same f32 arithmetic in the
//! same order so that GPU and CPU strands agree to rounding.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "grow_rk2",
    wgsl: include_str!("../../wgsl/grow_rk2.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: grow_rk2_cpu,
};

/// Workgroup width of the WGSL entry point.
pub const WORKGROUP: u32 = 64;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub nx: u32,
    pub ny: u32,
    pub nz: u32,
    pub n_strands: u32,
    pub max_steps: u32,
    pub record_every: u32,
    /// Vertex slots per strand: 1 + ceil(max_steps / record_every).
    pub max_verts: u32,
    pub step: f32,
    pub min_speed: f32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.n_strands, WORKGROUP), 1, 1]
}

/// Vertex slots a strand needs for `max_steps` steps stored every `record_every`: the root,
/// one per full record interval and the tip of a partial one.
pub fn max_verts(max_steps: u32, record_every: u32) -> u32 {
    1 + max_steps.div_ceil(record_every)
}

type V3 = [f32; 3];

fn lerp3(a: V3, b: V3, t: f32) -> V3 {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

struct Field<'a> {
    cfg: Config,
    dir: &'a [f32],
    vol: &'a [u32],
}

impl Field<'_> {
    fn fetch(&self, i: i32, j: i32, k: i32) -> V3 {
        let c = 3
            * (i as usize
                + self.cfg.nx as usize * (j as usize + self.cfg.ny as usize * k as usize));
        [self.dir[c], self.dir[c + 1], self.dir[c + 2]]
    }

    fn sample(&self, g: V3) -> V3 {
        let x = [g[0] - 0.5, g[1] - 0.5, g[2] - 0.5];
        let b = [x[0].floor(), x[1].floor(), x[2].floor()];
        let f = [x[0] - b[0], x[1] - b[1], x[2] - b[2]];
        let hi = [
            self.cfg.nx as i32 - 1,
            self.cfg.ny as i32 - 1,
            self.cfg.nz as i32 - 1,
        ];
        // `as i32` saturates like WGSL's f32 -> i32 conversion for in-range values.
        let i0: [i32; 3] = std::array::from_fn(|a| (b[a] as i32).clamp(0, hi[a]));
        let i1: [i32; 3] = std::array::from_fn(|a| (b[a] as i32 + 1).clamp(0, hi[a]));
        let c00 = lerp3(
            self.fetch(i0[0], i0[1], i0[2]),
            self.fetch(i1[0], i0[1], i0[2]),
            f[0],
        );
        let c10 = lerp3(
            self.fetch(i0[0], i1[1], i0[2]),
            self.fetch(i1[0], i1[1], i0[2]),
            f[0],
        );
        let c01 = lerp3(
            self.fetch(i0[0], i0[1], i1[2]),
            self.fetch(i1[0], i0[1], i1[2]),
            f[0],
        );
        let c11 = lerp3(
            self.fetch(i0[0], i1[1], i1[2]),
            self.fetch(i1[0], i1[1], i1[2]),
            f[0],
        );
        let c0 = lerp3(c00, c10, f[1]);
        let c1 = lerp3(c01, c11, f[1]);
        lerp3(c0, c1, f[2])
    }

    fn in_volume(&self, q: V3) -> bool {
        let n = [self.cfg.nx as f32, self.cfg.ny as f32, self.cfg.nz as f32];
        if !(q[0] >= 0.0 && q[1] >= 0.0 && q[2] >= 0.0 && q[0] < n[0] && q[1] < n[1] && q[2] < n[2])
        {
            return false;
        }
        let c = [
            q[0].floor() as usize,
            q[1].floor() as usize,
            q[2].floor() as usize,
        ];
        self.vol[c[0] + self.cfg.nx as usize * (c[1] + self.cfg.ny as usize * c[2])] != 0
    }
}

fn norm(v: V3) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Grows one strand into `out` (its `max_verts` slots); returns the vertex count.
fn grow_one(field: &Field, seed: V3, sign: f32, out: &mut [f32]) -> u32 {
    let cfg = &field.cfg;
    let store = |out: &mut [f32], k: u32, p: V3| {
        let o = 3 * k as usize;
        out[o..o + 3].copy_from_slice(&p);
    };
    let mut p = seed;
    let h = cfg.step * sign;
    let hh = 0.5 * h;
    store(out, 0, p);
    let mut count = 1u32;
    let mut pending = 0u32;
    for _ in 0..cfg.max_steps {
        let v1 = field.sample(p);
        let l1 = norm(v1);
        // NaN stops too, as `!(l1 > min_speed)` does in the shader.
        if l1.is_nan() || l1 <= cfg.min_speed {
            break;
        }
        let m: V3 = std::array::from_fn(|a| p[a] + (v1[a] / l1) * hh);
        let v2 = field.sample(m);
        let l2 = norm(v2);
        if l2.is_nan() || l2 <= cfg.min_speed {
            break;
        }
        let q: V3 = std::array::from_fn(|a| p[a] + (v2[a] / l2) * h);
        if !field.in_volume(q) {
            break;
        }
        p = q;
        pending += 1;
        if pending == cfg.record_every {
            store(out, count, p);
            count += 1;
            pending = 0;
        }
    }
    if pending > 0 {
        store(out, count, p);
        count += 1;
    }
    count
}

fn grow_rk2_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_dir, g_vol, g_seeds, g_signs) = (
        b[1].get::<f32>(),
        b[2].get::<u32>(),
        b[3].get::<f32>(),
        b[4].get::<f32>(),
    );
    // Plain slices: the RefCell guards are not Sync, the data is.
    let field = Field {
        cfg,
        dir: &g_dir,
        vol: &g_vol,
    };
    let (seeds, signs): (&[f32], &[f32]) = (&g_seeds, &g_signs);
    let mut verts = b[5].get_mut::<f32>();
    let mut counts = b[6].get_mut::<u32>();
    let n = cfg.n_strands as usize;
    let stride = 3 * cfg.max_verts as usize;
    verts[..n * stride]
        .par_chunks_mut(stride)
        .zip(counts[..n].par_iter_mut())
        .enumerate()
        .for_each(|(s, (out, count))| {
            let seed = [seeds[3 * s], seeds[3 * s + 1], seeds[3 * s + 2]];
            *count = grow_one(&field, seed, signs[s], out);
        });
}
