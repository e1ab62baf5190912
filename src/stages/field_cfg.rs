//! The uniform shared by every `field_*` stage (WGSL: `wgsl/shared/field_cfg.wgsl`), and the
//! neighbour walk the CPU mirrors use.
//!
//! Data layout (one multigrid level of `nx·ny·nz` cells, index `x + nx·(y + ny·z)`):
//! * `cellw`: one f32 per cell, `-1` outside the (level's) hair volume H, else the penalty
//!   weight `p ≥ 0` of C13 Eq. (3) (`w_c` on constrained fine cells, averaged on coarse ones).
//!   Folding the mask into the weight saves one buffer read per neighbour.
//! * `uv`, `f`, `r`: six f32 per cell, `[u.xyz, v.xyz]`, the unknowns of the mixed form
//!   `u = σ L v`, `σ L u + p v = b` (see `field3d`), their right-hand sides and residuals.

/// Workgroup edge of the 3D stages (4³ = 64 invocations).
pub const WG: u32 = 4;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    /// This level's grid (the fine grid for `field_restrict` / `field_prolong`).
    pub nx: u32,
    pub ny: u32,
    pub nz: u32,
    /// Red-black colour, `(x + y + z) & 1`, relaxed by `field_smooth`.
    pub colour: u32,
    /// Scale of this level's graph Laplacian: 4^-level (coarse cells are 2^level wide).
    pub sigma: f32,
    /// `field_smooth`: 0 = collective (u, v) update, 1 = u rows only (v held).
    pub mode: u32,
    /// The next coarser grid (restriction / prolongation only).
    pub cnx: u32,
    pub cny: u32,
    pub cnz: u32,
    /// Number of cells in the compact list (coarsest-level direct solve only).
    pub count: u32,
}

impl Config {
    pub fn cells(&self) -> usize {
        (self.nx * self.ny * self.nz) as usize
    }
}

/// Workgroups covering an `nx·ny·nz` grid with 4³ groups.
pub fn groups3(nx: u32, ny: u32, nz: u32) -> [u32; 3] {
    [
        crate::gpu::engine::groups(nx, WG),
        crate::gpu::engine::groups(ny, WG),
        crate::gpu::engine::groups(nz, WG),
    ]
}

/// Calls `f(j, w)` for each in-grid 6-neighbour `j` of cell `(x, y, z)` linked to it with
/// weight `w > 0` (`links`: 3 per cell, the links to +x, +y, +z), in the shaders' order
/// (-x, +x, -y, +y, -z, +z).
#[inline]
pub fn for_links(
    cfg: &Config,
    links: &[f32],
    x: u32,
    y: u32,
    z: u32,
    mut f: impl FnMut(usize, f32),
) {
    let (nx, ny, nz) = (cfg.nx, cfg.ny, cfg.nz);
    let i = (x + nx * (y + ny * z)) as usize;
    let sy = nx as usize;
    let sz = (nx * ny) as usize;
    let cand = [
        (x > 0, i.wrapping_sub(1), 0usize),
        (x + 1 < nx, i + 1, 0),
        (y > 0, i.wrapping_sub(sy), 1),
        (y + 1 < ny, i + sy, 1),
        (z > 0, i.wrapping_sub(sz), 2),
        (z + 1 < nz, i + sz, 2),
    ];
    for (ok, j, a) in cand {
        if ok {
            let w = links[3 * i.min(j) + a];
            if w > 0.0 {
                f(j, w);
            }
        }
    }
}

/// Levels with fewer grid cells than this run their CPU mirror on the calling thread: the
/// coarse levels of a cycle are small and many (a W-cycle visits level l 2^l times), and
/// handing each of their passes to the thread pool cost more than the pass (measured on
/// the astronaut's 80x60x64 grid: a third of the smoothing time went to waking workers).
pub const SERIAL_CELLS: usize = 1 << 15;
/// Grid cells per parallel task at least.
pub const MIN_TASK_CELLS: usize = 1 << 13;

/// Calls `f(z, slab)` for each z-slab of `data` (`slab` values each, 6 per cell), in
/// parallel when the level is large enough for it to pay. The slabs are disjoint, so the
/// order does not change any result.
pub fn for_slabs(data: &mut [f32], slab: usize, f: impl Fn(usize, &mut [f32]) + Sync + Send) {
    use rayon::prelude::*;
    if slab == 0 {
        return;
    }
    if data.len() / 6 < SERIAL_CELLS {
        data.chunks_mut(slab).enumerate().for_each(|(z, s)| f(z, s));
    } else {
        let min = (6 * MIN_TASK_CELLS).div_ceil(slab).max(1);
        data.par_chunks_mut(slab)
            .enumerate()
            .with_min_len(min)
            .for_each(|(z, s)| f(z, s));
    }
}
