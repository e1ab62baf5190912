//! Hair volume H and the directional constraints of C13 §2.1.
//!
//! C13: "we adopt the method proposed by Chai et al. [2012] to estimate the depths of the 2D
//! curves and further construct an initial hair model. This initial hair model and the head
//! model are rasterized together from both the front and back views to generate two depth maps
//! [...] We define the hair volume H as this closed volume *minus* the volume occupied by the
//! 3D head." Everything here is in volume space (x, y = image px, z = depth px toward the
//! camera; pixel (i, j) has its centre at (i + 0.5, j + 0.5)).
//!
//! Steps, all deterministic:
//! 1. [`rasterize_depth`]: front (max) and back (min) depth of triangle meshes per pixel
//!    centre, a GPU pass with a CPU mirror (`stages::depth_raster`).
//! 2. [`hair_shape_mesh`]: the initial hair shape after Chai et al. 2012 — the mask silhouette
//!    inflated by a Poisson solve, wrapped round the head, mirrored behind the head's centre
//!    plane, as a closed triangle mesh (see [`HairShapeParams`]).
//! 3. [`hair_volume`]: hair mesh + head mesh rasterised together; H = grid cells inside the
//!    mask and between the two depth maps, minus the head.
//! 4. [`lift_curves`]: directed 2D curves projected onto the front boundary of H, their
//!    tangents stored per cell as the constraints c_i of C13 Eq. 3.

use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Engine, Recording};
use crate::stages::depth_raster::{self, Config, BACK_EMPTY, FRONT_EMPTY, MAX_SPAN_PX};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

// ---------------------------------------------------------------------------------------------
// Grid and meshes
// ---------------------------------------------------------------------------------------------

pub use crate::base::grid::Grid;

/// A triangle mesh in volume space.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Mesh {
    pub verts: Vec<[f32; 3]>,
    pub tris: Vec<[u32; 3]>,
}

impl Mesh {
    /// A closed UV ellipsoid: `n_lat` rings of latitude (>= 2), `n_lon` segments (>= 3);
    /// every vertex lies on the surface, so the faces lie inside it.
    pub fn ellipsoid(centre: [f32; 3], radii: [f32; 3], n_lat: u32, n_lon: u32) -> Mesh {
        let (n_lat, n_lon) = (n_lat.max(2), n_lon.max(3));
        let mut verts = vec![[centre[0], centre[1] - radii[1], centre[2]]];
        for i in 1..n_lat {
            let th = std::f32::consts::PI * i as f32 / n_lat as f32;
            for j in 0..n_lon {
                let ph = std::f32::consts::TAU * j as f32 / n_lon as f32;
                verts.push([
                    centre[0] + radii[0] * th.sin() * ph.cos(),
                    centre[1] - radii[1] * th.cos(),
                    centre[2] + radii[2] * th.sin() * ph.sin(),
                ]);
            }
        }
        let bottom = verts.len() as u32;
        verts.push([centre[0], centre[1] + radii[1], centre[2]]);
        let ring = |i: u32, j: u32| 1 + (i - 1) * n_lon + j % n_lon;
        let mut tris = Vec::new();
        for j in 0..n_lon {
            tris.push([0, ring(1, j + 1), ring(1, j)]);
            tris.push([bottom, ring(n_lat - 1, j), ring(n_lat - 1, j + 1)]);
        }
        for i in 1..n_lat - 1 {
            for j in 0..n_lon {
                let (a, b) = (ring(i, j), ring(i, j + 1));
                let (c, d) = (ring(i + 1, j + 1), ring(i + 1, j));
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        Mesh { verts, tris }
    }

    /// Appends `other`, re-indexing its triangles.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.verts.len() as u32;
        self.verts.extend_from_slice(&other.verts);
        self.tris.extend(
            other
                .tris
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Depth rasterisation
// ---------------------------------------------------------------------------------------------

/// Front (largest depth, nearest the camera) and back (smallest depth) per pixel centre,
/// row-major W*H. Uncovered pixels hold `-inf` in `front` and `+inf` in `back`.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthMaps {
    pub width: u32,
    pub height: u32,
    pub front: Vec<f32>,
    pub back: Vec<f32>,
}

impl DepthMaps {
    /// Whether some triangle covers pixel `i` (row-major index).
    pub fn covered(&self, i: usize) -> bool {
        self.front[i].is_finite()
    }

    /// Decodes the raw words of the pass ([`FRONT_EMPTY`] / [`BACK_EMPTY`] become ∓inf).
    pub fn from_words(width: u32, height: u32, front: &[u32], back: &[u32]) -> DepthMaps {
        let n = (width * height) as usize;
        let dec = |e: u32, empty: u32, inf: f32| {
            if e == empty {
                inf
            } else {
                depth_raster::decode_depth(e)
            }
        };
        DepthMaps {
            width,
            height,
            front: front[..n]
                .iter()
                .map(|&e| dec(e, FRONT_EMPTY, f32::NEG_INFINITY))
                .collect(),
            back: back[..n]
                .iter()
                .map(|&e| dec(e, BACK_EMPTY, f32::INFINITY))
                .collect(),
        }
    }
}

/// Largest image side the pass accepts (pixel indices and 1/16 px coordinates stay in i32).
pub const MAX_IMAGE_SIDE: u32 = 1 << 15;
/// Vertices must satisfy |x|, |y| < this (px) so that snapping to 1/16 px fits in i32.
pub const MAX_COORD: f32 = (1 << 26) as f32;

/// Flattens `meshes` into the pass's vertex and index buffers, checking what the pass relies
/// on: indices in range, finite coordinates, |x|, |y| < [`MAX_COORD`], and every triangle's
/// x and y span below [`MAX_SPAN_PX`] (2047.8 px; split larger triangles).
pub fn pack_meshes(meshes: &[&Mesh]) -> Result<(Vec<f32>, Vec<u32>)> {
    let mut verts = Vec::new();
    let mut tris = Vec::new();
    for (m_i, m) in meshes.iter().enumerate() {
        let base = (verts.len() / 3) as u32;
        for v in &m.verts {
            if !v.iter().all(|c| c.is_finite())
                || v[0].abs() >= MAX_COORD
                || v[1].abs() >= MAX_COORD
            {
                return Err(Error::Invalid(format!(
                    "mesh {m_i}: vertex {v:?} is not finite or beyond ±{MAX_COORD} px"
                )));
            }
            verts.extend_from_slice(v);
        }
        for (t_i, t) in m.tris.iter().enumerate() {
            if t.iter().any(|&i| i as usize >= m.verts.len()) {
                return Err(Error::Invalid(format!(
                    "mesh {m_i}: triangle {t_i} {t:?} indexes past {} vertices",
                    m.verts.len()
                )));
            }
            let p = t.map(|i| m.verts[i as usize]);
            for a in 0..2 {
                let lo = p[0][a].min(p[1][a]).min(p[2][a]);
                let hi = p[0][a].max(p[1][a]).max(p[2][a]);
                if hi - lo > MAX_SPAN_PX {
                    return Err(Error::Invalid(format!(
                        "mesh {m_i}: triangle {t_i} spans {} px along {}, over the {MAX_SPAN_PX} px \
                         the depth rasteriser accepts; subdivide it",
                        hi - lo,
                        ["x", "y"][a]
                    )));
                }
            }
            tris.extend(t.map(|i| i + base));
        }
    }
    Ok((verts, tris))
}

/// Records the depth pass over packed buffers (see [`pack_meshes`]) and returns the front and
/// back word buffers, initialised to [`FRONT_EMPTY`] / [`BACK_EMPTY`].
pub fn record_depth_raster(
    rec: &mut Recording,
    width: u32,
    height: u32,
    verts: &[f32],
    tris: &[u32],
) -> (BufProxy, BufProxy) {
    let n_tris = (tris.len() / 3) as u32;
    let wg = depth_raster::workgroups(n_tris);
    let cfg = Config {
        width,
        height,
        n_tris,
        groups_x: wg[0],
    };
    let bytes = 4 * width as u64 * height as u64;
    let u = rec.uniform("coif.depth_raster.cfg", &cfg);
    let v = rec.upload("coif.depth_raster.verts", verts);
    let t = rec.upload("coif.depth_raster.tris", tris);
    let front = rec.alloc("coif.depth_raster.front", bytes, FRONT_EMPTY);
    let back = rec.alloc("coif.depth_raster.back", bytes, BACK_EMPTY);
    rec.dispatch(&depth_raster::STAGE, wg, &[u, v, t, front, back], &[]);
    (front, back)
}

/// Front and back depth maps of `meshes` rasterised together on a `width` x `height` image.
pub fn rasterize_depth(
    engine: &Engine,
    width: u32,
    height: u32,
    meshes: &[&Mesh],
) -> Result<DepthMaps> {
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(Error::Invalid(format!(
            "depth maps of {width}x{height} pixels: each side must be 1..={MAX_IMAGE_SIDE}"
        )));
    }
    let (verts, tris) = pack_meshes(meshes)?;
    let mut rec = Recording::default();
    let (f, b) = record_depth_raster(&mut rec, width, height, &verts, &tris);
    rec.download(f);
    rec.download(b);
    let dl = engine.run(rec)?;
    Ok(DepthMaps::from_words(
        width,
        height,
        &dl.get::<u32>(f),
        &dl.get::<u32>(b),
    ))
}

// ---------------------------------------------------------------------------------------------
// Initial hair shape (after Chai et al. 2012)
// ---------------------------------------------------------------------------------------------

/// Parameters of the initial hair shape.
///
/// Construction (Chai et al. 2012 estimate strand depths so that the silhouette lies at the
/// head's mid-depth, the interior bulges smoothly toward the camera and the hair stays outside
/// the head; C13 reuses it to get a closed hair shape). On a lattice of `lattice_px` pixels:
/// - the silhouette is inflated by solving the Poisson problem Δu = -1 inside the mask,
///   u = 0 on its boundary (SOR), and taking the height h = `inflation`·sqrt(4u): for a
///   circular mask this is exactly a hemisphere, and in general a round, smooth bulge whose
///   boundary sits at the head's centre plane z_c, so the hair wraps round the head;
/// - front = z_c + max(h, t) and back = z_c - max(h, t) (the mirror about the centre plane),
///   with t = `thickness_cells` volume cells, so even the silhouette has a thickness of 2t;
/// - where the head is under the hair, front >= head front + t and back <= head back - t: a
///   layer of at least t over the head in front and behind it.
///
/// The lattice quads that contain a hair pixel centre give a front sheet and a reversed back
/// sheet joined along the boundary of the quad set by vertical walls: a closed mesh whose
/// projection covers every hair pixel centre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct HairShapeParams {
    /// Scale of the Poisson bulge (1 = hemisphere for a disc).
    pub inflation: f32,
    /// Smallest half-thickness of the hair, and smallest layer over the head, in volume cells.
    /// At least ~1 so every hair pixel gets a cell of H in front of the head.
    pub thickness_cells: f32,
    /// Lattice spacing of the hair mesh and of the Poisson solve, px.
    pub lattice_px: u32,
    /// SOR sweeps of the Poisson solve.
    pub poisson_sweeps: u32,
}

impl Default for HairShapeParams {
    fn default() -> Self {
        HairShapeParams {
            inflation: 1.0,
            thickness_cells: 1.0,
            lattice_px: 2,
            poisson_sweeps: 600,
        }
    }
}

/// Parameters of [`hair_volume`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VolumeParams {
    /// Cells along the grid's largest axis (C13: 80).
    pub cells: u32,
    /// Empty cells added on each side of the hair's bounding box.
    pub margin_cells: u32,
    /// A cell column belongs to the hair when at least this share of the pixels under it is
    /// hair. With the pixel under the cell's centre instead (about one half), the cells along
    /// the mask's edge whose centre falls just outside were lost, and with them a band up to
    /// half a cell (3 px at 512²) along the hair's edge that no strand could reach: the
    /// synthetic long hair's re-render went 21.7 -> 24.5 dB and its coverage IoU 0.962 ->
    /// 0.974 with 1/4 (issue 5 note).
    pub min_hair_fraction: f32,
    pub shape: HairShapeParams,
}

impl Default for VolumeParams {
    fn default() -> Self {
        VolumeParams {
            cells: 80,
            margin_cells: 1,
            min_hair_fraction: 0.25,
            shape: HairShapeParams::default(),
        }
    }
}

/// Δu = -1 on the lattice nodes flagged in `inside` (u = 0 elsewhere), node spacing `s` px,
/// by lexicographic SOR with the optimal factor for the lattice size (deterministic).
fn poisson(inside: &[bool], nx: usize, ny: usize, s: f32, sweeps: u32) -> Vec<f32> {
    let mut u = vec![0.0f32; nx * ny];
    let omega = 2.0 / (1.0 + (std::f32::consts::PI / nx.max(ny) as f32).sin());
    let rhs = s * s;
    for _ in 0..sweeps {
        for j in 1..ny.saturating_sub(1) {
            for i in 1..nx - 1 {
                let k = j * nx + i;
                if !inside[k] {
                    continue;
                }
                let gs = 0.25 * (u[k - 1] + u[k + 1] + u[k - nx] + u[k + nx] + rhs);
                u[k] += omega * (gs - u[k]);
            }
        }
    }
    u
}

/// The closed initial hair mesh (see [`HairShapeParams`]). `mask` is W*H, true on hair;
/// `head` the head's depth maps on the same image; `centre_z` the depth of the head's
/// centre; `thickness_px` the value of t in px.
pub fn hair_shape_mesh(
    mask: &[bool],
    head: &DepthMaps,
    centre_z: f32,
    thickness_px: f32,
    params: &HairShapeParams,
) -> Result<Mesh> {
    let (w, h) = (head.width as usize, head.height as usize);
    if mask.len() != w * h || head.front.len() != w * h || head.back.len() != w * h {
        return Err(Error::Invalid(format!(
            "hair mask has {} pixels, head depth maps {}x{} ({} and {} values)",
            mask.len(),
            w,
            h,
            head.front.len(),
            head.back.len()
        )));
    }
    let ok = params.lattice_px != 0
        && params.inflation >= 0.0
        && params.inflation.is_finite()
        && thickness_px > 0.0
        && thickness_px.is_finite()
        && centre_z.is_finite();
    if !ok {
        return Err(Error::Invalid(format!(
            "hair shape: lattice {} px, inflation {}, thickness {thickness_px} px, centre depth \
             {centre_z}: need lattice >= 1, inflation >= 0, finite thickness > 0, finite centre",
            params.lattice_px, params.inflation
        )));
    }
    let s = params.lattice_px as usize;
    // Quads (qx, qy) span [qx s, (qx+1) s] x [qy s, (qy+1) s]; nodes sit at their corners.
    let (qw, qh) = (w.div_ceil(s), h.div_ceil(s));
    let (nx, ny) = (qw + 1, qh + 1);
    let mut quad = vec![false; qw * qh];
    for y in 0..h {
        for x in 0..w {
            if mask[y * w + x] {
                quad[(y / s) * qw + x / s] = true;
            }
        }
    }
    let has_quad = |qx: isize, qy: isize| {
        qx >= 0 && qy >= 0 && (qx as usize) < qw && (qy as usize) < qh && {
            quad[qy as usize * qw + qx as usize]
        }
    };
    // Interior nodes: all four quads around them are hair; the others bound the region.
    let mut inside = vec![false; nx * ny];
    let mut used = vec![false; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let around = [(-1, -1), (0, -1), (-1, 0), (0, 0)]
                .map(|(dx, dy)| has_quad(i as isize + dx, j as isize + dy));
            inside[j * nx + i] = around.iter().all(|&q| q);
            used[j * nx + i] = around.iter().any(|&q| q);
        }
    }
    let u = poisson(&inside, nx, ny, s as f32, params.poisson_sweeps);
    let t = thickness_px;
    // Node depths; the head is sampled conservatively over the (up to) four pixels that
    // touch the node.
    let mut id = vec![u32::MAX; nx * ny];
    let mut mesh = Mesh::default();
    let mut back_verts = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let k = j * nx + i;
            if !used[k] {
                continue;
            }
            let (x, y) = ((i * s) as f32, (j * s) as f32);
            let mut hf = f32::NEG_INFINITY;
            let mut hb = f32::INFINITY;
            for (px, py) in [(i * s, j * s), (i * s, (j * s).max(1) - 1)] {
                for px in [px, px.max(1) - 1] {
                    let (px, py) = (px.min(w - 1), py.min(h - 1));
                    hf = hf.max(head.front[py * w + px]);
                    hb = hb.min(head.back[py * w + px]);
                }
            }
            let bulge = (params.inflation * (4.0 * u[k].max(0.0)).sqrt()).max(t);
            let mut zf = centre_z + bulge;
            let mut zb = centre_z - bulge;
            if hf.is_finite() {
                zf = zf.max(hf + t);
                zb = zb.min(hb - t);
            }
            id[k] = mesh.verts.len() as u32;
            mesh.verts.push([x, y, zf]);
            back_verts.push([x, y, zb]);
        }
    }
    let n_front = mesh.verts.len() as u32;
    mesh.verts.extend(back_verts);
    let node = |i: usize, j: usize| id[j * nx + i];
    for qy in 0..qh {
        for qx in 0..qw {
            if !quad[qy * qw + qx] {
                continue;
            }
            // Corners in order round the quad; the same order for every quad keeps the
            // sheet consistently oriented.
            let c = [
                node(qx, qy),
                node(qx + 1, qy),
                node(qx + 1, qy + 1),
                node(qx, qy + 1),
            ];
            let b = c.map(|v| v + n_front);
            mesh.tris.push([c[0], c[1], c[2]]);
            mesh.tris.push([c[0], c[2], c[3]]);
            mesh.tris.push([b[0], b[2], b[1]]);
            mesh.tris.push([b[0], b[3], b[2]]);
            // Walls along edges with no hair quad across them close the mesh.
            let across = [(0, -1), (1, 0), (0, 1), (-1, 0)];
            for e in 0..4 {
                let (dx, dy) = across[e];
                if has_quad(qx as isize + dx, qy as isize + dy) {
                    continue;
                }
                let (fu, fv) = (c[e], c[(e + 1) % 4]);
                let (bu, bv) = (fu + n_front, fv + n_front);
                mesh.tris.push([fv, fu, bu]);
                mesh.tris.push([fv, bu, bv]);
            }
        }
    }
    Ok(mesh)
}

// ---------------------------------------------------------------------------------------------
// Hair volume
// ---------------------------------------------------------------------------------------------

/// The head as the hair volume sees it, in volume space.
pub struct HeadInput<'a> {
    /// Closed head mesh (projected into volume space by the caller).
    pub mesh: &'a Mesh,
    /// Depth of the head's centre (the plane the hair silhouette is put on).
    pub centre_z: f32,
    /// Signed distance to the head, px, negative inside.
    pub sdf: &'a (dyn Fn([f32; 3]) -> f32 + Sync),
}

/// The hair volume H of C13 §2.1 and what it was built from.
#[derive(Clone, Debug)]
pub struct HairVolume {
    pub grid: Grid,
    /// One word per cell, 1 inside H.
    pub h: Vec<u32>,
    /// Front / back depth maps of the hair mesh and the head rasterised together, W*H,
    /// -inf / +inf where nothing covers the pixel.
    pub front: Vec<f32>,
    pub back: Vec<f32>,
    /// The head's own depth maps.
    pub head: DepthMaps,
    /// W*H, 1 on hair (mask value > 127).
    pub mask: Vec<u8>,
    pub width: u32,
    pub height: u32,
    /// The closed initial hair mesh.
    pub hair_mesh: Mesh,
    /// Cells in H.
    pub count: usize,
}

impl HairVolume {
    /// Row-major pixel index of a volume-space point, if it is inside the image.
    pub fn pixel(&self, x: f32, y: f32) -> Option<usize> {
        let (px, py) = (x.floor(), y.floor());
        if px >= 0.0 && py >= 0.0 && px < self.width as f32 && py < self.height as f32 {
            Some(py as usize * self.width as usize + px as usize)
        } else {
            None
        }
    }

    /// The front-most H cell of grid column (i, j): the first H cell from the front.
    pub fn front_cell(&self, i: u32, j: u32) -> Option<u32> {
        (0..self.grid.dims[2])
            .rev()
            .find(|&k| self.h[self.grid.index(i, j, k)] != 0)
    }
}

/// A grid whose largest axis has `cells` cells, `margin` of them on each side, the others
/// centred on the box [lo, hi].
fn fit_grid(lo: [f32; 3], hi: [f32; 3], cells: u32, margin: u32) -> Grid {
    let ext: [f32; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(1e-3));
    let inner = (cells - 2 * margin) as f32;
    let cell = ext.iter().fold(0.0f32, |m, &e| m.max(e)) / inner;
    let dims: [u32; 3] = std::array::from_fn(|a| {
        let n = (ext[a] / cell * (1.0 - 1e-5)).ceil() as u32;
        (n + 2 * margin).clamp(1, cells)
    });
    let origin = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]) - 0.5 * dims[a] as f32 * cell);
    Grid { dims, origin, cell }
}

/// The hair volume (C13 §2.1). `mask` is W*H (value > 127 = hair). The head mesh is
/// rasterised, the initial hair mesh built over it ([`hair_shape_mesh`]) and both rasterised
/// together; the grid covers the mask's bounding box and the depth range over the mask with
/// `params.cells` cells on its largest axis plus margins. Cell c is in H when at least
/// `params.min_hair_fraction` of the pixels under its x-y footprint are hair (covered by the
/// depth maps), its depth extent [z_c - cell/2, z_c + cell/2] overlaps [back, front] at the
/// hair pixel nearest its centre (so a column is never lost between two cell centres) and
/// its centre is outside the head (`head.sdf > 0`).
///
/// Errors: mask size not W*H, empty mask, non-finite centre depth, bad parameters, a mask
/// that does not overlap the head's front map, an empty H, and what the rasteriser refuses.
pub fn hair_volume(
    engine: &Engine,
    mask: &[u8],
    width: u32,
    height: u32,
    head: &HeadInput,
    params: &VolumeParams,
) -> Result<HairVolume> {
    let n = width as usize * height as usize;
    if mask.len() != n || n == 0 {
        return Err(Error::Invalid(format!(
            "hair mask has {} values for a {width}x{height} image",
            mask.len()
        )));
    }
    if params.cells < 2 * params.margin_cells + 2 {
        return Err(Error::Invalid(format!(
            "hair volume: {} cells cannot hold {} margin cells on each side",
            params.cells, params.margin_cells
        )));
    }
    if !(params.min_hair_fraction > 0.0 && params.min_hair_fraction <= 1.0) {
        return Err(Error::Invalid(format!(
            "hair volume: min_hair_fraction {} must lie in (0, 1]",
            params.min_hair_fraction
        )));
    }
    if !(params.shape.thickness_cells > 0.0 && params.shape.thickness_cells.is_finite()) {
        return Err(Error::Invalid(format!(
            "hair volume: thickness {} cells must be finite and positive",
            params.shape.thickness_cells
        )));
    }
    if !head.centre_z.is_finite() {
        return Err(Error::Invalid(format!(
            "head centre depth {} is not finite",
            head.centre_z
        )));
    }
    let hair: Vec<bool> = mask.iter().map(|&m| m > 127).collect();
    let w = width as usize;
    let mut bb_lo = [f32::INFINITY; 2];
    let mut bb_hi = [f32::NEG_INFINITY; 2];
    for (i, _) in hair.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = ((i % w) as f32, (i / w) as f32);
        bb_lo = [bb_lo[0].min(x), bb_lo[1].min(y)];
        bb_hi = [bb_hi[0].max(x + 1.0), bb_hi[1].max(y + 1.0)];
    }
    if !bb_lo[0].is_finite() {
        return Err(Error::Invalid("the hair mask is empty".into()));
    }
    let head_maps = rasterize_depth(engine, width, height, &[head.mesh])?;
    if !(0..n).any(|i| hair[i] && head_maps.covered(i)) {
        return Err(Error::Invalid(
            "the hair mask does not overlap the head's front depth map: the head is not \
             under the hair"
                .into(),
        ));
    }
    // t is measured in cells of a grid that t itself widens along z: iterate to a fixed
    // point (the cell size grows by a factor 2·thickness/cells at most per round).
    let inner = (params.cells - 2 * params.margin_cells) as f32;
    let mut cell = (bb_hi[0] - bb_lo[0]).max(bb_hi[1] - bb_lo[1]) / inner;
    let mut built = None;
    for _ in 0..8 {
        let t = params.shape.thickness_cells * cell;
        let mesh = hair_shape_mesh(&hair, &head_maps, head.centre_z, t, &params.shape)?;
        let maps = rasterize_depth(engine, width, height, &[&mesh, head.mesh])?;
        let (mut zlo, mut zhi) = (f32::INFINITY, f32::NEG_INFINITY);
        for i in (0..n).filter(|&i| hair[i] && maps.covered(i)) {
            zlo = zlo.min(maps.back[i]);
            zhi = zhi.max(maps.front[i]);
        }
        let grid = fit_grid(
            [bb_lo[0], bb_lo[1], zlo],
            [bb_hi[0], bb_hi[1], zhi],
            params.cells,
            params.margin_cells,
        );
        let done = grid.cell <= cell * 1.01;
        cell = grid.cell;
        built = Some((grid, mesh, maps));
        if done {
            break;
        }
    }
    let (grid, hair_mesh, maps) = built.expect("at least one round");
    let plane = grid.dims[0] as usize * grid.dims[1] as usize;
    let half = 0.5 * grid.cell;
    // Per cell column: the hair pixel that stands for it (see `min_hair_fraction`).
    let columns: Vec<Option<usize>> = (0..plane)
        .into_par_iter()
        .map(|ij| {
            let c = grid.centre([
                (ij % grid.dims[0] as usize) as u32,
                (ij / grid.dims[0] as usize) as u32,
                0,
            ]);
            let span = |v: f32, n: u32| {
                (
                    ((v - half).floor().max(0.0) as u32).min(n),
                    ((v + half).ceil().max(0.0) as u32).min(n),
                )
            };
            let ((x0, x1), (y0, y1)) = (span(c[0], width), span(c[1], height));
            let (mut total, mut on, mut best) = (0u32, 0u32, None);
            let mut best_d = f32::INFINITY;
            for y in y0..y1 {
                for x in x0..x1 {
                    total += 1;
                    let i = y as usize * w + x as usize;
                    if hair[i] && maps.covered(i) {
                        on += 1;
                        let d = (x as f32 + 0.5 - c[0]).powi(2) + (y as f32 + 0.5 - c[1]).powi(2);
                        if d < best_d {
                            best_d = d;
                            best = Some(i);
                        }
                    }
                }
            }
            best.filter(|_| on as f32 >= params.min_hair_fraction * total as f32)
        })
        .collect();
    let mut h = vec![0u32; grid.len()];
    h.par_chunks_mut(plane).enumerate().for_each(|(k, slab)| {
        for (ij, out) in slab.iter_mut().enumerate() {
            let Some(p) = columns[ij] else {
                continue;
            };
            let c = grid.centre([
                (ij % grid.dims[0] as usize) as u32,
                (ij / grid.dims[0] as usize) as u32,
                k as u32,
            ]);
            if maps.covered(p)
                && c[2] - half <= maps.front[p]
                && c[2] + half >= maps.back[p]
                && (head.sdf)(c) > 0.0
            {
                *out = 1;
            }
        }
    });
    let count = h.iter().filter(|&&v| v != 0).count();
    if count == 0 {
        return Err(Error::Invalid(
            "the hair volume is empty: no cell inside the mask lies between the depth maps \
             outside the head"
                .into(),
        ));
    }
    Ok(HairVolume {
        grid,
        h,
        front: maps.front,
        back: maps.back,
        head: head_maps,
        mask: hair.iter().map(|&m| m as u8).collect(),
        width,
        height,
        hair_mesh,
        count,
    })
}

// ---------------------------------------------------------------------------------------------
// Curve constraints
// ---------------------------------------------------------------------------------------------

/// A directional constraint of C13 Eq. 3: linear cell index and unit 3D tangent.
pub type Constraint = (u32, [f32; 3]);

/// Projects directed 2D curves (root → tip, image px) onto the front boundary of H and
/// returns the lifted 3D polylines (volume space) and the directional constraints of C13
/// Eq. 3 as (cell index, unit tangent).
///
/// A point is kept when its pixel is hair and its grid column holds H; its depth is the front
/// depth map at that pixel clamped into the front-most H cell of the column, so the point lies
/// on the smooth front surface and in the first H cell from the front (C13: "project the 2D
/// directed curves [...] onto the curved boundary surface of H"). Dropped points split a curve:
/// each run of >= 2 consecutive kept points becomes one polyline, in input order (a lone point
/// has no tangent and is left out). Tangents are central differences of the lifted points
/// (one-sided at run ends); the directed tangents falling into one cell are summed and
/// normalised, one constraint per cell, sorted by cell index (cells whose tangents cancel are
/// left out).
pub fn lift_curves(
    curves: &[Vec<[f32; 2]>],
    vol: &HairVolume,
) -> (Vec<Vec<[f32; 3]>>, Vec<Constraint>) {
    let g = &vol.grid;
    let lift = |p: [f32; 2]| -> Option<([f32; 3], u32)> {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        let pix = vol.pixel(p[0], p[1])?;
        if vol.mask[pix] == 0 || !vol.front[pix].is_finite() {
            return None;
        }
        let gx = ((p[0] - g.origin[0]) / g.cell).floor();
        let gy = ((p[1] - g.origin[1]) / g.cell).floor();
        if !(gx >= 0.0 && gy >= 0.0 && gx < g.dims[0] as f32 && gy < g.dims[1] as f32) {
            return None;
        }
        let (i, j) = (gx as u32, gy as u32);
        let k = vol.front_cell(i, j)?;
        let lo = g.origin[2] + k as f32 * g.cell;
        // Strictly inside the cell so that the point's cell is the front cell itself.
        let z = vol.front[pix].clamp(lo, lo + g.cell * 0.999);
        Some(([p[0], p[1], z], g.index(i, j, k) as u32))
    };
    let mut lines = Vec::new();
    let mut sums: BTreeMap<u32, [f64; 3]> = BTreeMap::new();
    let mut flush = |run: &mut Vec<([f32; 3], u32)>, lines: &mut Vec<Vec<[f32; 3]>>| {
        if run.len() >= 2 {
            let m = run.len();
            for (k, &(_, cell)) in run.iter().enumerate() {
                let (a, b) = (run[k.saturating_sub(1)].0, run[(k + 1).min(m - 1)].0);
                let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if len > 1e-6 {
                    let s = sums.entry(cell).or_insert([0.0; 3]);
                    for a in 0..3 {
                        s[a] += (d[a] / len) as f64;
                    }
                }
            }
            lines.push(run.iter().map(|r| r.0).collect());
        }
        run.clear();
    };
    for curve in curves {
        let mut run = Vec::new();
        for &p in curve {
            match lift(p) {
                Some(r) => run.push(r),
                None => flush(&mut run, &mut lines),
            }
        }
        flush(&mut run, &mut lines);
    }
    let constraints = sums
        .into_iter()
        .filter_map(|(cell, s)| {
            let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
            (len > 1e-6).then(|| (cell, s.map(|v| (v / len) as f32)))
        })
        .collect();
    (lines, constraints)
}
