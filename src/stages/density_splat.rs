//! Vertex density splat with integer atomics (C13 §2.2, ρ of Eq. 5). Pairs with
//! `wgsl/density_splat.wgsl`; integer sums do not depend on order, so parity is exact.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};

pub const STAGE: StageDef = StageDef {
    name: "density_splat",
    wgsl: include_str!("../../wgsl/density_splat.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::ReadWrite],
    cpu: density_splat_cpu,
};

/// Workgroup width of the WGSL entry point.
pub const WORKGROUP: u32 = 256;
/// Largest workgroup count per dispatch dimension WebGPU guarantees.
const MAX_GROUPS: u32 = 65535;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub nx: u32,
    pub ny: u32,
    pub nz: u32,
    pub n_verts: u32,
    /// Invocations per dispatch row (workgroups in x · WORKGROUP); set by [`config`].
    pub row: u32,
}

/// A config for `n_verts` vertices and its 2D dispatch size.
pub fn config(dims: [u32; 3], n_verts: u32) -> (Config, [u32; 3]) {
    let total = crate::gpu::engine::groups(n_verts, WORKGROUP);
    let x = total.min(MAX_GROUPS);
    let y = total.div_ceil(x);
    let cfg = Config {
        nx: dims[0],
        ny: dims[1],
        nz: dims[2],
        n_verts,
        row: x * WORKGROUP,
    };
    (cfg, [x, y, 1])
}

fn density_splat_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let verts = b[1].get::<f32>();
    let mut density = b[2].get_mut::<u32>();
    let n = [cfg.nx as f32, cfg.ny as f32, cfg.nz as f32];
    // Serial: one add per vertex is memory bound, and order does not matter for integers.
    for q in verts[..3 * cfg.n_verts as usize].chunks_exact(3) {
        if !(q[0] >= 0.0 && q[1] >= 0.0 && q[2] >= 0.0 && q[0] < n[0] && q[1] < n[1] && q[2] < n[2])
        {
            continue;
        }
        let c = [
            q[0].floor() as usize,
            q[1].floor() as usize,
            q[2].floor() as usize,
        ];
        let idx = c[0] + cfg.nx as usize * (c[1] + cfg.ny as usize * c[2]);
        density[idx] = density[idx].wrapping_add(1);
    }
}
