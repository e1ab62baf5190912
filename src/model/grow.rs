//! Strand growth in the 3D direction field (C13 §2.2, "Initial Hair Tracing") and the vertex
//! density used by refinement, both as GPU passes with CPU mirrors
//! ([`crate::stages::grow_rk2`], [`crate::stages::density_splat`]).
//!
//! Strands ([`StrandSet`]) live in grid coordinates (cell centre = index + 0.5), root → tip.
//!
//! Stop rule: a strand stops before a step whose end point lies in a cell (the cell holding
//! it, i.e. its nearest cell centre) outside the grid or outside H, where the interpolated
//! field at the start or midpoint of a step has length ≤ `min_speed`, or after `max_steps`
//! steps. The root is always the given seed, unchanged (roots on the scalp stay put).

use crate::base::grid::Grid;
use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::hair::strands::StrandSet;
use crate::stages::{density_splat, grow_rk2};
use serde::{Deserialize, Serialize};

/// Growth parameters (C13 §2.2: RK2, step half a cell, stop at a maximum length or on
/// leaving H).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GrowParams {
    /// Step length in cells (C13: half the grid width).
    pub step: f32,
    /// Maximum number of steps: the maximum strand length is `step · max_steps` cells.
    pub max_steps: u32,
    /// A vertex is stored every `record_every` steps (2 with a half-cell step: vertices one
    /// cell apart, the spacing Eq. 5's Laplacian and the refinement radius assume).
    pub record_every: u32,
    /// Growth stops where the interpolated field is no longer than this (D's units): there is
    /// no direction to follow (outside the constraints' reach, or opposing vectors cancel).
    pub min_speed: f32,
}

impl Default for GrowParams {
    fn default() -> Self {
        GrowParams {
            step: 0.5,
            max_steps: 240,
            record_every: 2,
            min_speed: 1e-3,
        }
    }
}

impl GrowParams {
    /// Maximum strand length in cells.
    pub fn max_length(&self) -> f32 {
        self.step * self.max_steps as f32
    }

    /// Vertex slots per strand.
    pub fn max_verts(&self) -> u32 {
        grow_rk2::max_verts(self.max_steps, self.record_every)
    }

    fn validate(&self) -> Result<()> {
        if !(self.step.is_finite() && self.step > 0.0) {
            return Err(Error::Invalid(format!(
                "grow step must be positive and finite, got {}",
                self.step
            )));
        }
        if self.record_every == 0 {
            return Err(Error::Invalid(
                "grow record_every must be at least 1".into(),
            ));
        }
        if !(self.min_speed.is_finite() && self.min_speed >= 0.0) {
            return Err(Error::Invalid(format!(
                "grow min_speed must be finite and >= 0, got {}",
                self.min_speed
            )));
        }
        // Keeps one strand's slots addressable and a tile of them bindable.
        if self.max_steps > 1 << 20 {
            return Err(Error::Invalid(format!(
                "grow max_steps {} is over the limit of {}",
                self.max_steps,
                1 << 20
            )));
        }
        Ok(())
    }
}

/// Checks a grid, its direction field D (3 values per cell, finite) and hair volume H.
pub fn validate_field(grid: &Grid, d: &[f32], h: &[u32]) -> Result<()> {
    if grid.dims.contains(&0) {
        return Err(Error::Invalid(format!(
            "grid dims must be positive, got {:?}",
            grid.dims
        )));
    }
    if !(grid.cell.is_finite() && grid.cell > 0.0) || grid.origin.iter().any(|v| !v.is_finite()) {
        return Err(Error::Invalid(format!(
            "grid cell must be positive and origin finite, got cell {} origin {:?}",
            grid.cell, grid.origin
        )));
    }
    let n = grid.len();
    // The shaders index D with 32-bit words.
    if (3 * n as u64) > u32::MAX as u64 {
        return Err(Error::Invalid(format!(
            "grid of {n} cells is too large for 32-bit indexing"
        )));
    }
    if d.len() != 3 * n {
        return Err(Error::Invalid(format!(
            "direction field has {} values, the grid needs 3 x {n}",
            d.len()
        )));
    }
    if h.len() != n {
        return Err(Error::Invalid(format!(
            "hair volume has {} cells, the grid has {n}",
            h.len()
        )));
    }
    if let Some(i) = d.iter().position(|v| !v.is_finite()) {
        return Err(Error::Invalid(format!(
            "direction field value {i} (cell {}) is not finite",
            i / 3
        )));
    }
    Ok(())
}

/// Grows one strand from each seed (grid coordinates, inside the grid) along `sign[s]` · D
/// (each +1 or -1). The first vertex of every strand is its seed.
pub fn grow(
    engine: &Engine,
    grid: &Grid,
    d: &[f32],
    h: &[u32],
    seeds: &[[f32; 3]],
    signs: &[f32],
    p: &GrowParams,
) -> Result<StrandSet> {
    validate_field(grid, d, h)?;
    p.validate()?;
    if signs.len() != seeds.len() {
        return Err(Error::Invalid(format!(
            "{} signs for {} seeds",
            signs.len(),
            seeds.len()
        )));
    }
    if let Some(s) = signs.iter().position(|&v| v != 1.0 && v != -1.0) {
        return Err(Error::Invalid(format!(
            "sign {s} is {}, must be +1 or -1",
            signs[s]
        )));
    }
    for (s, g) in seeds.iter().enumerate() {
        if grid.cell_of(*g).is_none() {
            return Err(Error::Invalid(format!(
                "seed {s} at {g:?} (grid coordinates) is outside the {:?} grid",
                grid.dims
            )));
        }
    }
    if seeds.is_empty() {
        return Ok(StrandSet::default());
    }
    let max_verts = p.max_verts() as usize;
    let per_strand = 12 * max_verts as u64;
    // Tiles of strands keep the vertex buffer under the binding limit and the dispatch under
    // 65535 workgroups.
    let limit = engine.max_binding_bytes();
    let tile = ((limit / per_strand) as usize).min(65535 * grow_rk2::WORKGROUP as usize);
    if tile == 0 {
        return Err(Error::TooLarge {
            what: "one strand's vertex slots".into(),
            needed: per_strand,
            limit,
            limit_name: "largest buffer binding".into(),
            unit: "bytes",
        });
    }
    let mut rec = Recording::default();
    let dbuf = rec.upload("coif.grow.d", d);
    let hbuf = rec.upload("coif.grow.h", h);
    let mut outs = Vec::new();
    for (c, chunk) in seeds.chunks(tile).enumerate() {
        let cfg = grow_rk2::Config {
            nx: grid.dims[0],
            ny: grid.dims[1],
            nz: grid.dims[2],
            n_strands: chunk.len() as u32,
            max_steps: p.max_steps,
            record_every: p.record_every,
            max_verts: max_verts as u32,
            step: p.step,
            min_speed: p.min_speed,
        };
        let u = rec.uniform("coif.grow.cfg", &cfg);
        let sb = rec.upload("coif.grow.seeds", chunk);
        let start = c * tile;
        let gb = rec.upload("coif.grow.signs", &signs[start..start + chunk.len()]);
        let vb = rec.alloc("coif.grow.verts", chunk.len() as u64 * per_strand, SENTINEL);
        let cb = rec.alloc("coif.grow.counts", 4 * chunk.len() as u64, 0);
        rec.dispatch(
            &grow_rk2::STAGE,
            grow_rk2::workgroups(&cfg),
            &[u, dbuf, hbuf, sb, gb, vb, cb],
            &[],
        );
        rec.download(vb);
        rec.download(cb);
        outs.push((chunk.len(), vb, cb));
    }
    let dl = engine.run(rec)?;
    let mut strands = StrandSet::default();
    for (n, vb, cb) in outs {
        let verts = dl.get::<[f32; 3]>(vb);
        let counts = dl.get::<u32>(cb);
        for s in 0..n {
            let c = counts[s] as usize;
            if c == 0 || c > max_verts {
                return Err(Error::Gpu(format!(
                    "grow_rk2 reported {c} vertices for a strand with {max_verts} slots"
                )));
            }
            strands.push(&verts[s * max_verts..s * max_verts + c]);
        }
    }
    Ok(strands)
}

/// Vertices per grid cell (C13 Eq. 5's ρ): each vertex of `strands` adds 1 to the cell
/// holding it; vertices outside the grid add nothing.
pub fn splat_density(engine: &Engine, grid: &Grid, strands: &StrandSet) -> Result<Vec<u32>> {
    splat_verts(engine, grid, &strands.points)
}

/// As [`splat_density`], for loose vertices (grid coordinates).
pub fn splat_verts(engine: &Engine, grid: &Grid, verts: &[[f32; 3]]) -> Result<Vec<u32>> {
    let n = grid.len();
    if grid.dims.contains(&0) || n as u64 > u32::MAX as u64 {
        return Err(Error::Invalid(format!(
            "cannot splat into a grid of dims {:?}",
            grid.dims
        )));
    }
    let limit = engine.max_binding_bytes();
    // Tiles of vertices stay under the binding limit and 65535² workgroups.
    let tile = ((limit / 12) as usize).min(1 << 30);
    let mut rec = Recording::default();
    let dens = rec.alloc("coif.density", 4 * n as u64, 0);
    for chunk in verts.chunks(tile.max(1)) {
        let (cfg, wg) = density_splat::config(grid.dims, chunk.len() as u32);
        let u = rec.uniform("coif.density.cfg", &cfg);
        let vb = rec.upload("coif.density.verts", chunk);
        rec.dispatch(&density_splat::STAGE, wg, &[u, vb, dens], &[]);
    }
    rec.download(dens);
    let dl = engine.run(rec)?;
    let mut out = dl.get::<u32>(dens);
    out.truncate(n);
    Ok(out)
}
