//! What the two render passes (`strand_raster`, `mesh_raster`) share on the CPU side: their
//! uniform (`wgsl/shared/raster_common.wgsl`) and the fixed-point rasteriser the mirrors use
//! to reproduce a Vulkan rasteriser's coverage (viewport mapping, 1/256 px snapping, edge
//! functions with the top-left rule, per-sample depth planes and tests), tile by tile.
//! The rules themselves are listed in [`crate::render::raster`].

// Edges x samples loops index several arrays in lockstep over const-generic sizes; plain
// index loops read (and unroll) best there.
#![allow(clippy::needless_range_loop)]

use crate::render::raster::Texture;

/// The uniform of both shaders (WGSL `Config`, `wgsl/shared/raster_common.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub samples: u32,
    pub half_width: f32,
    pub ndc_scale_x: f32,
    pub ndc_scale_y: f32,
    /// 0: vertex colours; 1: photo colour; 2: photo colour with the HSV adjustment.
    pub photo: u32,
    pub photo_half_width: f32,
    pub hue_deg: f32,
    pub saturation: f32,
    pub value: f32,
    pub _pad: u32,
}

impl Config {
    /// A w x h frame of `samples` samples with strands `half_width` px wide, vertex colours
    /// and no HSV adjustment (the photo fields are set by whoever has a photo).
    pub fn frame(width: u32, height: u32, samples: u32, half_width: f32) -> Config {
        Config {
            width,
            height,
            samples,
            half_width,
            ndc_scale_x: 2.0 / width as f32,
            ndc_scale_y: 2.0 / height as f32,
            photo: 0,
            photo_half_width: 0.0,
            hue_deg: 0.0,
            saturation: 1.0,
            value: 1.0,
            _pad: 0,
        }
    }
}

/// Vulkan's standard 4x sample positions within a pixel (x right, y down).
pub const SAMPLE_POSITIONS_4: [[f32; 2]; 4] = [
    [0.375, 0.125],
    [0.875, 0.375],
    [0.125, 0.625],
    [0.625, 0.875],
];

/// Alpha-to-coverage's sample count for alpha `a` at n samples: floor(clamp(a)·n + 0.5),
/// truncated without the saturating fix-ups (the value is in [0.5, n + 0.5]); a NaN alpha
/// (i32::MIN) keeps no sample, as `as` gives.
#[inline(always)]
pub fn a2c_count(n: u32, a: f32) -> u32 {
    trunc_i32(a.clamp(0.0, 1.0) * n as f32 + 0.5).max(0) as u32
}

/// The alpha-to-coverage mask: k <= n samples starting at r, in order (mod n), for
/// n = 1 or 4 (powers of two).
#[inline]
pub fn a2c_mask(n: u32, r: u32, k: u32) -> u32 {
    let run = (1u32 << k) - 1;
    ((run << r) | (run >> (n - r))) & ((1u32 << n) - 1)
}

/// Sub-pixel grid vertices snap to (8 bits, as lavapipe).
pub const SUBPIXEL: f32 = 256.0;

/// Screen px -> framebuffer px through NDC and the viewport transform, with the f32
/// operations the vertex shader and the (y-flipped) Vulkan viewport perform.
pub struct Fb {
    pub sx: f32,
    pub sy: f32,
    pub hw: f32,
    pub hh: f32,
}

impl Fb {
    pub fn new(c: &Config) -> Fb {
        Fb {
            sx: c.ndc_scale_x,
            sy: c.ndc_scale_y,
            hw: c.width as f32 * 0.5,
            hh: c.height as f32 * 0.5,
        }
    }

    #[inline]
    pub fn map(&self, p: [f32; 2]) -> [f32; 2] {
        let nx = p[0] * self.sx - 1.0;
        let ny = 1.0 - p[1] * self.sy;
        [nx * self.hw + self.hw, ny * -self.hh + self.hh]
    }
}

/// Round to the 1/256 px grid, ties to even (as lavapipe), without a libm call. On x86-64
/// SSE's conversion rounds in the default mode, to nearest even (Rust code never runs in
/// another), so it is one instruction; elsewhere adding 1.5·2^52 leaves no fraction bits, so
/// the FPU's own round-to-nearest-even does it. Corners are finite (the host clips them to a
/// guard band); v·256 is exact in f32.
#[inline(always)]
pub fn snap(v: f32) -> i64 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_cvtss_si64, _mm_set_ss};
        // SAFETY: SSE is part of x86-64.
        unsafe { _mm_cvtss_si64(_mm_set_ss(v * SUBPIXEL)) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        snap_portable(v)
    }
}

/// [`snap`] without SSE (and the reference its test compares the SSE form with).
#[cfg(any(test, not(target_arch = "x86_64")))]
fn snap_portable(v: f32) -> i64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    ((v * SUBPIXEL) as f64 + MAGIC - MAGIC) as i64
}

/// Sample positions of an N-sample pixel, in 1/256 px and in px.
pub fn sample_offsets<const N: usize>() -> ([[i64; 2]; N], [[f64; 2]; N]) {
    let pos: [[f32; 2]; N] = std::array::from_fn(|s| {
        if N == 4 {
            SAMPLE_POSITIONS_4[s]
        } else {
            [0.5, 0.5]
        }
    });
    (
        pos.map(|p| p.map(|v| (v * SUBPIXEL) as i64)),
        pos.map(|p| p.map(|v| v as f64)),
    )
}

pub type Offsets<const N: usize> = ([[i64; 2]; N], [[f64; 2]; N]);

/// A convex polygon of E edges set up for fixed-point coverage: a triangle, or a strand
/// quad when the two triangles' union provably equals it (see `strand_quad`).
pub struct Poly<const E: usize, const N: usize> {
    /// Edge k: inside when a·X + b·Y + c >= 0 (X, Y in 1/256 px); the top-left rule is
    /// folded into c.
    pub a: [i64; E],
    pub b: [i64; E],
    pub c: [i64; E],
    /// The sample positions (1/256 px) the offsets of [`Poly::sample_offsets`] and
    /// [`Poly::narrow`] are taken at: computed where they are used (a strand quad that is
    /// skipped, or drawn narrow in i32, never needs the i64 products).
    offs: [[i64; 2]; N],
    /// Inclusive pixel bounding box.
    pub bbox: [i32; 4],
}

impl<const E: usize, const N: usize> Poly<E, N> {
    /// `v` in order around a convex polygon, either way round. None when the area is 0
    /// and, with `cull_back`, for back faces (positive area in y-down fb coordinates =
    /// clockwise in NDC). (Always inlined: once per segment in the AVX2 tile loop.)
    #[inline(always)]
    pub fn new(v: [[i64; 2]; E], cull_back: bool, offs: &[[i64; 2]; N]) -> Option<Self> {
        let area: i64 = (0..E)
            .map(|k| {
                let (p, q) = (v[k], v[(k + 1) % E]);
                p[0] * q[1] - q[0] * p[1]
            })
            .sum();
        if area == 0 || (cull_back && area > 0) {
            return None;
        }
        let (mut a, mut b, mut c) = ([0i64; E], [0i64; E], [0i64; E]);
        for k in 0..E {
            // Walk the edges with the interior on the positive side.
            let (p, q) = if area > 0 {
                (v[k], v[(k + 1) % E])
            } else {
                (v[(k + 1) % E], v[k])
            };
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            a[k] = -dy;
            b[k] = dx;
            // Top edge (horizontal, interior below) or left edge (interior to the right)
            // include their samples; other edges exclude them.
            let top_left = dy < 0 || (dy == 0 && dx > 0);
            c[k] = -(a[k] * p[0] + b[k] * p[1]) - if top_left { 0 } else { 1 };
        }
        let mut bbox = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
        for p in &v {
            let (x, y) = (p[0].div_euclid(256) as i32, p[1].div_euclid(256) as i32);
            bbox = [
                bbox[0].min(x),
                bbox[1].min(y),
                bbox[2].max(x),
                bbox[3].max(y),
            ];
        }
        Some(Poly {
            a,
            b,
            c,
            offs: *offs,
            bbox,
        })
    }

    /// Edge values at the corner of pixel (px, py); add [`Poly::step`] per pixel right.
    #[inline]
    pub fn edges(&self, px: i32, py: i32) -> [i64; E] {
        let (x, y) = (px as i64 * 256, py as i64 * 256);
        std::array::from_fn(|k| self.a[k] * x + self.b[k] * y + self.c[k])
    }

    #[inline]
    pub fn step(&self) -> [i64; E] {
        self.a.map(|a| a * 256)
    }

    /// Per edge, per sample: a·ox + b·oy, what [`Poly::mask`] adds to a pixel's edge values.
    pub fn sample_offsets(&self) -> [[i64; N]; E] {
        std::array::from_fn(|k| {
            std::array::from_fn(|s| self.a[k] * self.offs[s][0] + self.b[k] * self.offs[s][1])
        })
    }

    /// Bit s set when sample s of the pixel whose corner has edge values `e` is covered,
    /// given the polygon's [`Poly::sample_offsets`] `so`.
    /// Branch-free: coverage is data-dependent and mispredictions dominated.
    #[inline]
    pub fn mask(&self, e: &[i64; E], so: &[[i64; N]; E]) -> u32 {
        let mut m = 0;
        for s in 0..N {
            let mut inside = true;
            for k in 0..E {
                inside &= e[k] + so[k][s] >= 0;
            }
            m |= (inside as u32) << s;
        }
        m
    }

    /// The same set-up in i32, valid while every edge value visited fits (see
    /// `strand_quad`): the sample offsets, the step per pixel right and the step per row
    /// down. Then 4 samples go through one SIMD compare, and (i32 arithmetic being exact
    /// mod 2^32) any sum of these whose true value fits is exact in wrapping i32.
    #[inline(always)]
    pub fn narrow(&self) -> Narrow<E, N> {
        let (a, b) = (self.a.map(|v| v as i32), self.b.map(|v| v as i32));
        let so = std::array::from_fn(|k| {
            std::array::from_fn(|s| {
                a[k].wrapping_mul(self.offs[s][0] as i32)
                    .wrapping_add(b[k].wrapping_mul(self.offs[s][1] as i32))
            })
        });
        (
            so,
            a.map(|v| v.wrapping_mul(256)),
            b.map(|v| v.wrapping_mul(256)),
        )
    }

    /// [`Poly::edges`] in wrapping i32 (see [`Poly::narrow`]).
    #[inline(always)]
    pub fn edges32(&self, px: i32, py: i32) -> [i32; E] {
        self.edges(px, py).map(|v| v as i32)
    }
}

/// [`Poly::narrow`]'s set-up: per edge the sample offsets, the step right, the step down.
pub type Narrow<const E: usize, const N: usize> = ([[i32; N]; E], [i32; E], [i32; E]);

/// [`Poly::mask`] on i32 edge values.
#[inline]
pub fn mask32<const E: usize, const N: usize>(e: &[i32; E], so: &[[i32; N]; E]) -> u32 {
    let mut m = 0;
    for s in 0..N {
        let mut inside = true;
        for k in 0..E {
            inside &= e[k].wrapping_add(so[k][s]) >= 0;
        }
        m |= (inside as u32) << s;
    }
    m
}

/// v = c + gx·x + gy·y (fb px).
#[derive(Clone, Copy)]
pub struct Plane {
    pub c: f64,
    pub gx: f64,
    pub gy: f64,
}

impl Plane {
    /// The plane at the N sample positions of pixel (px, py), given the per-sample
    /// offsets `gx·ox + gy·oy`.
    #[inline]
    pub fn samples<const N: usize>(&self, px: i32, py: i32, off: &[f64; N]) -> [f32; N] {
        let zc = self.c + self.gx * px as f64 + self.gy * py as f64;
        std::array::from_fn(|i| (zc + off[i]) as f32)
    }

    pub fn offsets<const N: usize>(&self, offs: &[[f64; 2]; N]) -> [f64; N] {
        std::array::from_fn(|i| self.gx * offs[i][0] + self.gy * offs[i][1])
    }
}

/// The same fetch at texel coordinates (s, r) = px - 0.5.
pub fn bilinear_at(t: &Texture, s: f32, r: f32) -> [f32; 4] {
    let (w, h) = (t.width as i32, t.height as i32);
    let (fs, fr) = (s.floor(), r.floor());
    let (ax, ay) = (s - fs, r - fr);
    let (i, j) = (fs as i32, fr as i32);
    let tex = |i: i32, j: i32| {
        let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
        t.texels[(j * w + i) as usize]
    };
    let mix = |a: [f32; 4], b: [f32; 4], t: f32| -> [f32; 4] {
        std::array::from_fn(|k| a[k] * (1.0 - t) + b[k] * t)
    };
    let (i1, j1) = (i.saturating_add(1), j.saturating_add(1));
    let top = mix(tex(i, j), tex(i1, j), ax);
    let bottom = mix(tex(i, j1), tex(i1, j1), ax);
    mix(top, bottom, ay)
}

/// One tile's samples: colour (premultiplied, pixel-major) and depth.
#[derive(Default)]
pub struct TileBuf<const N: usize> {
    pub x0: i32,
    pub y0: i32,
    pub w: i32,
    pub h: i32,
    pub color: Vec<[[f32; 4]; N]>,
    pub depth: Vec<[f32; N]>,
    /// Per sample, the draw rank of what it holds (0: background or mesh; a strand segment
    /// its first vertex's index + 1): an exact depth tie goes to the lower rank, which is
    /// what drawing in rank order with `Less` does, so primitives may be drawn in any order
    /// (the CPU driver draws each tile's segments front to back) with the same result.
    pub rank: Vec<[u32; N]>,
    /// Per [`ZBLOCK`]² block of pixels, a bound on the farthest depth of its samples (it only
    /// falls between refreshes, so a stale value is still a bound): a primitive no nearer
    /// than every block it touches cannot pass a depth test there and is skipped whole.
    pub zmax: Vec<f32>,
    /// Blocks written since their `zmax` was last computed: a flag per block and the list
    /// of the flagged ones (a refresh visits those only).
    pub zdirty: Vec<bool>,
    pub dirty: Vec<u32>,
}

/// Whether the AVX2 builds of the CPU rasteriser's loops can run here (checked once;
/// `COIF_NO_AVX2=1` turns them off, to run the baseline x86-64 build).
#[cfg(target_arch = "x86_64")]
pub fn has_avx2() -> bool {
    static HAS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *HAS.get_or_init(|| {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::env::var_os("COIF_NO_AVX2").is_none()
    })
}

/// `x as i32` for an `x` the caller knows to be finite and in range, without the
/// saturation and NaN fix-ups `as` adds: SSE's truncating conversion on x86-64 (defined
/// for every input: outside the range it gives i32::MIN), `as` elsewhere.
#[inline(always)]
pub fn trunc_i32(x: f32) -> i32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_cvttss_si32, _mm_set_ss};
        // SAFETY: SSE is part of x86-64.
        unsafe { _mm_cvttss_si32(_mm_set_ss(x)) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        x as i32
    }
}

/// Side in pixels of the depth blocks of [`TileBuf::zmax`]: 2 bounds a 1 px strand's
/// footprint more tightly than 4 (62% of segment set-ups skipped against 59% on the raster
/// bench, ~4% faster), and the refresh visits written blocks only, so more of them cost
/// little.
pub const ZBLOCK: i32 = 2;

/// Blocks past the end of [`TileBuf::zmax`] (never written): [`TileBuf::hidden`] reads a
/// row's bounds eight at a time.
pub const ZMAX_PAD: usize = 7;

/// Pixels past the end of [`TileBuf::depth`], read and never used by the strand loop's
/// last group of a tile (at most 8 pixels: 8 lanes of 1 sample, or a window of 4 pixels).
pub const TILE_PAD: usize = 8;

/// Slack of the depth-bound tests ([`TileBuf::hidden`], [`TileBuf::pixel_hidden`]) for the
/// rounding of per-sample depths to f32.
pub const DEPTH_ROUNDING: f32 = 1e-6;

impl<const N: usize> TileBuf<N> {
    /// Sizes the tile at (x0, y0), w x h, with every depth 1, every depth bound fresh, and no
    /// colour yet (the caller fills `color` with the background, w·h pixels).
    pub fn reset(&mut self, x0: i32, y0: i32, w: i32, h: i32) {
        (self.x0, self.y0, self.w, self.h) = (x0, y0, w, h);
        let npx = (w * h) as usize;
        self.color.clear();
        // Padded by TILE_PAD pixels: the strand loop reads its pixels' depths a group at a
        // time, and a group may run past the tile's last pixel.
        self.depth.clear();
        self.depth.resize(npx + TILE_PAD, [1.0; N]);
        self.rank.clear();
        self.rank.resize(npx, [0; N]);
        self.zmax.clear();
        let nb = ((w + ZBLOCK - 1) / ZBLOCK) * ((h + ZBLOCK - 1) / ZBLOCK);
        self.zmax.resize(nb as usize + ZMAX_PAD, 1.0);
        self.zdirty.clear();
        self.zdirty.resize(nb as usize, false);
        self.dirty.clear();
    }

    /// Recomputes the farthest depth of every block written since the last refresh.
    #[inline(always)]
    pub fn refresh_zmax(&mut self) {
        let bw = (self.w + ZBLOCK - 1) / ZBLOCK;
        for &b in &self.dirty {
            let b = b as usize;
            self.zdirty[b] = false;
            let (bx, by) = (b as i32 % bw * ZBLOCK, b as i32 / bw * ZBLOCK);
            // Per-sample lanes, reduced at the end: depths are never NaN (1 or a value that
            // passed a test within [0, 1]), so a plain compare is `max`, and independent
            // lanes vectorise where `f32::max`'s NaN handling made one serial chain (a fifth
            // of the tile loop's time in the profile).
            let mut m = [f32::NEG_INFINITY; N];
            for ly in by..(by + ZBLOCK).min(self.h) {
                let row = (ly * self.w) as usize;
                for px in &self.depth[row + bx as usize..row + (bx + ZBLOCK).min(self.w) as usize] {
                    for s in 0..N {
                        m[s] = if px[s] > m[s] { px[s] } else { m[s] };
                    }
                }
            }
            self.zmax[b] = m
                .iter()
                .fold(f32::NEG_INFINITY, |a, &b| if b > a { b } else { a });
        }
        self.dirty.clear();
    }

    /// True when depth `z_near` (the nearest a primitive gets, depth-buffer units) is no
    /// nearer than any sample in tile pixels [lx0, lx1] x [ly0, ly1]: then no sample of it
    /// passes `Less`. The margin covers the rounding of per-sample depths to f32.
    /// (Always inlined: called per segment from the AVX2 tile loop.)
    #[inline(always)]
    pub fn hidden(&self, lx0: i32, ly0: i32, lx1: i32, ly1: i32, z_near: f32) -> bool {
        let z = z_near - DEPTH_ROUNDING;
        // (Tile-local coordinates are never negative.)
        let block = |v: i32| v as usize / ZBLOCK as usize;
        let (bx0, by0, bx1, by1) = (block(lx0), block(ly0), block(lx1), block(ly1));
        // Up to eight blocks a row (most boxes): two compares of four bounds a row, so a
        // row's work has no loop of its own (whose trip count no predictor guesses: 5-7%
        // of the cpu render against the plain loops). Not hidden when some bound is not
        // <= z (a NaN bound or z included), as in the plain loops.
        #[cfg(target_arch = "x86_64")]
        if bx1 - bx0 < 8 {
            use std::arch::x86_64::*;
            let bw = self.blocks_wide();
            let lanes = (1 << (bx1 - bx0 + 1)) - 1;
            // SAFETY: SSE is part of x86-64; `zmax` is padded by ZMAX_PAD past its last
            // block, so the eight bounds from (by, bx0) lie in it (bounds-checked below).
            unsafe {
                let zv = _mm_set1_ps(z);
                for by in by0..=by1 {
                    let at = &self.zmax[by * bw + bx0..by * bw + bx0 + 8];
                    let far = |k: usize| {
                        _mm_movemask_ps(_mm_cmpnle_ps(_mm_loadu_ps(at.as_ptr().add(k)), zv))
                    };
                    if (far(0) | (far(4) << 4)) & lanes != 0 {
                        return false;
                    }
                }
            }
            return true;
        }
        self.hidden_plain([bx0, by0, bx1, by1], z)
    }

    /// Blocks a row of [`TileBuf::zmax`] holds.
    #[inline(always)]
    fn blocks_wide(&self) -> usize {
        ((self.w + ZBLOCK - 1) / ZBLOCK) as usize
    }

    /// [`TileBuf::hidden`]'s test on blocks [bx0, bx1] x [by0, by1] against depth `z`, a
    /// bound at a time: for wider boxes, and the reference of the SSE form in the tests.
    #[inline(always)]
    fn hidden_plain(&self, [bx0, by0, bx1, by1]: [usize; 4], z: f32) -> bool {
        let bw = self.blocks_wide();
        // A row of blocks at a time (one bounds check a row, not one a block), the row's
        // blocks without a branch each; plain loops, as `RangeInclusive` iterators were an
        // out-of-line fold in the profile.
        let mut by = by0;
        while by <= by1 {
            let mut all = true;
            for &m in &self.zmax[by * bw + bx0..by * bw + bx1 + 1] {
                all &= m <= z;
            }
            if !all {
                return false;
            }
            by += 1;
        }
        true
    }

    /// [`TileBuf::hidden`] for the one tile pixel of index `i`, against its own samples
    /// rather than its block's bound.
    #[inline(always)]
    pub fn pixel_hidden(&self, i: usize, z_near: f32) -> bool {
        let z = z_near - DEPTH_ROUNDING;
        let d = &self.depth[i];
        let mut far = d[0];
        for s in 1..N {
            far = if d[s] > far { d[s] } else { far };
        }
        far <= z
    }

    /// Depth-tests and writes the samples in `mask` of tile pixel (lx, ly) for a primitive
    /// of rank 0 (the mesh, drawn first and in order): `Less` against the buffer, and
    /// outside [0, 1] nothing (the GPU clips the primitive). Branch-free selects, for the
    /// same reason as `Tri::mask`.
    #[inline]
    pub fn write(&mut self, lx: i32, ly: i32, mask: u32, c: [f32; 4], z: [f32; N]) {
        let i = (ly * self.w + lx) as usize;
        let pass = self.passing(i, mask, z, 0);
        self.write_passed(lx, ly, pass, c, z, 0);
    }

    /// The samples of `mask` at tile pixel index `i` that a primitive of draw rank `rank`
    /// wins: nearer (`Less`), or as near with a lower rank than what the sample holds (see
    /// [`TileBuf::rank`]); outside [0, 1] nothing. Testing before shading lets a fragment
    /// hidden in every sample skip its colour (with heavy overdraw, most do).
    #[inline(always)]
    pub fn passing(&self, i: usize, mask: u32, z: [f32; N], rank: u32) -> u32 {
        let (depth, held) = (&self.depth[i], &self.rank[i]);
        let mut pass = 0;
        for s in 0..N {
            let zs = z[s];
            let wins = (zs < depth[s]) | ((zs == depth[s]) & (rank < held[s]));
            let p = ((mask >> s) & 1 == 1) & (0.0..=1.0).contains(&zs) & wins;
            pass |= (p as u32) << s;
        }
        pass
    }

    /// Writes colour `c`, depth `z` and draw rank `rank` to the samples in `pass` (from
    /// [`TileBuf::passing`]) of tile pixel (lx, ly). (Always inlined: called per fragment
    /// from the AVX2 tile loop.)
    #[inline(always)]
    pub fn write_passed(
        &mut self,
        lx: i32,
        ly: i32,
        pass: u32,
        c: [f32; 4],
        z: [f32; N],
        rank: u32,
    ) {
        let i = (ly * self.w + lx) as usize;
        let bw = (self.w + ZBLOCK - 1) / ZBLOCK;
        let b = (ly / ZBLOCK * bw + lx / ZBLOCK) as usize;
        if !self.zdirty[b] {
            self.zdirty[b] = true;
            self.dirty.push(b as u32);
        }
        let (depth, held, color) = (&mut self.depth[i], &mut self.rank[i], &mut self.color[i]);
        for s in 0..N {
            let p = (pass >> s) & 1 == 1;
            depth[s] = if p { z[s] } else { depth[s] };
            held[s] = if p { rank } else { held[s] };
            let m = 0u32.wrapping_sub(p as u32);
            for k in 0..4 {
                color[s][k] = f32::from_bits((c[k].to_bits() & m) | (color[s][k].to_bits() & !m));
            }
        }
    }

    /// Pixel range of `bbox` inside the tile, as local coordinates.
    pub fn clip(&self, bbox: [i32; 4]) -> Option<(i32, i32, i32, i32)> {
        let x0 = (bbox[0] - self.x0).max(0);
        let y0 = (bbox[1] - self.y0).max(0);
        let x1 = (bbox[2] - self.x0).min(self.w - 1);
        let y1 = (bbox[3] - self.y0).min(self.h - 1);
        (x0 <= x1 && y0 <= y1).then_some((x0, y0, x1, y1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `snap` rounds to the 1/256 px grid with ties to even, as the portable form does,
    /// on ties, near-ties and far corners; and the check can fail (ties away from zero
    /// differ).
    #[test]
    fn snap_rounds_ties_to_even() {
        let mut vals = vec![
            0.0f32,
            -0.0,
            1.0 / 512.0,
            3.0 / 512.0,
            -1.0 / 512.0,
            1e6,
            -4096.5,
        ];
        for k in -3000..3000 {
            let v = k as f32 / 512.0;
            vals.extend([
                v,
                f32::from_bits(v.to_bits() + 1),
                f32::from_bits(v.to_bits().max(1) - 1),
            ]);
        }
        for &v in &vals {
            assert_eq!(snap(v), snap_portable(v), "{v}");
        }
        assert_eq!(snap(1.0 / 512.0), 0);
        assert_eq!(snap(3.0 / 512.0), 2);
        assert_ne!(
            snap(1.0 / 512.0),
            (1.0f32 / 512.0 * SUBPIXEL).round() as i64
        );
    }

    /// The SSE test of up to eight blocks a row agrees with the plain loops on random
    /// bounds and boxes of every width (wider ones take the plain loops themselves), NaN
    /// bounds and depths included; and the comparison can fail (a test with `<` instead of
    /// `<=` differs on ties).
    #[test]
    fn hidden_by_sse_matches_the_plain_loops() {
        let mut rng = crate::base::rng::Rng::new(5);
        let mut b = TileBuf::<4>::default();
        b.reset(0, 0, 37, 29);
        let nb = b.zmax.len() - ZMAX_PAD;
        let (mut hidden, mut shown, mut ties) = (0, 0, 0);
        for round in 0..2000 {
            for m in &mut b.zmax[..nb] {
                // Coarse levels so that ties with z occur.
                *m = match rng.below(100) {
                    0 => f32::NAN,
                    k => (k as f32 / 200.0 + if round % 2 == 0 { 0.0 } else { 0.5 }).min(1.0),
                };
            }
            let (x0, y0) = (rng.below(37) as i32, rng.below(29) as i32);
            // Mostly small boxes, as segments have, some up to the tile.
            let (wx, wy) = (
                rng.below((37 - x0) as u32) + 1,
                rng.below((29 - y0) as u32) + 1,
            );
            let (x1, y1) = (x0 + rng.below(wx) as i32, y0 + rng.below(wy) as i32);
            let z = match rng.below(10) {
                0 => f32::NAN,
                k => k as f32 / 10.0 + DEPTH_ROUNDING,
            };
            let block = |v: i32| (v / ZBLOCK) as usize;
            let boxed = [block(x0), block(y0), block(x1), block(y1)];
            let want = b.hidden_plain(boxed, z - DEPTH_ROUNDING);
            assert_eq!(
                b.hidden(x0, y0, x1, y1, z),
                want,
                "box ({x0}, {y0})-({x1}, {y1}) at depth {z}"
            );
            if want {
                hidden += 1;
            } else {
                shown += 1;
            }
            // Whether a strict test would differ here (a bound equal to z in the box).
            let zt = z - DEPTH_ROUNDING;
            let bw = b.blocks_wide();
            let strict = (boxed[1]..=boxed[3]).all(|by| {
                b.zmax[by * bw + boxed[0]..=by * bw + boxed[2]]
                    .iter()
                    .all(|&m| m < zt)
            });
            ties += (strict != want) as u32;
        }
        assert!(
            hidden > 100 && shown > 100,
            "{hidden} hidden, {shown} shown"
        );
        assert!(ties > 0, "no tie: the comparison could not tell < from <=");
    }

    /// The depth bounds only skip what the per-sample test would reject: a primitive
    /// nearer than one sample of a block is never hidden, and a block stays conservative
    /// (never below its farthest sample) between refreshes.
    #[test]
    fn hidden_only_when_every_sample_is_nearer() {
        let mut b = TileBuf::<4>::default();
        b.reset(0, 0, 10, 9);
        b.color.resize(90, [[0.0; 4]; 4]);
        assert!(
            !b.hidden(0, 0, 9, 8, 0.99),
            "cleared tile (depth 1) hides nothing"
        );
        // Fill the block at the origin with depth 0.5 except one sample at 0.7.
        let e = ZBLOCK - 1;
        for ly in 0..ZBLOCK {
            for lx in 0..ZBLOCK {
                b.write(lx, ly, 0b1111, [1.0; 4], [0.5; 4]);
            }
        }
        b.depth[(e * 10 + e) as usize][2] = 0.7;
        // Before a refresh the stale bound (1.0) hides nothing.
        assert!(!b.hidden(0, 0, e, e, 0.8));
        b.refresh_zmax();
        assert_eq!(b.zmax[0], 0.7);
        assert!(b.hidden(0, 0, e, e, 0.8));
        assert!(!b.hidden(0, 0, e, e, 0.6), "nearer than the 0.7 sample");
        assert!(
            !b.hidden(0, 0, e, e, 0.7),
            "ties pass nothing, but the margin keeps them"
        );
        // A range reaching an unwritten block is not hidden.
        assert!(!b.hidden(0, 0, e + 1, e, 0.8));
        // A refresh recomputes only what was written since: the block keeps its bound
        // until a write marks it again.
        b.depth[0][0] = 0.9;
        b.refresh_zmax();
        assert_eq!(b.zmax[0], 0.7, "not written since the last refresh");
        b.write(0, 0, 0b0010, [1.0; 4], [0.2; 4]);
        b.refresh_zmax();
        assert_eq!(b.zmax[0], 0.9);
        // Partial blocks at the tile's edge are sized to the tile.
        let side = |n: i32| (n + ZBLOCK - 1) / ZBLOCK;
        assert_eq!(b.zmax.len(), (side(10) * side(9)) as usize + ZMAX_PAD);
    }

    /// An exact depth tie goes to the lower draw rank, whichever is drawn first, so a tile
    /// drawn in any order ends as the GPU's input order with `Less` leaves it; the mesh
    /// (rank 0, drawn first) keeps its ties.
    #[test]
    fn depth_ties_go_to_the_lower_rank_in_any_order() {
        let mut b = TileBuf::<4>::default();
        b.reset(0, 0, 2, 1);
        b.color.resize(2, [[0.0; 4]; 4]);
        let (early, late) = ([1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]);
        // Pixel 0: the later strand (rank 9) drawn first, then the earlier (rank 3).
        let i = 0;
        let p = b.passing(i, 0b1111, [0.5; 4], 9);
        b.write_passed(0, 0, p, late, [0.5; 4], 9);
        assert_eq!(
            b.passing(i, 0b1111, [0.5; 4], 3),
            0b1111,
            "lower rank wins a tie"
        );
        b.write_passed(0, 0, 0b1111, early, [0.5; 4], 3);
        assert_eq!(
            b.passing(i, 0b1111, [0.5; 4], 9),
            0,
            "higher rank loses a tie"
        );
        assert_eq!(b.passing(i, 0b0110, [0.4, 0.5, 0.4, 0.6], 9), 0b0100);
        assert_eq!(b.color[0], [early; 4]);
        // Pixel 1: the mesh (rank 0) holds its ties against every strand.
        b.write(1, 0, 0b1111, late, [0.5; 4]);
        assert_eq!(b.passing(1, 0b1111, [0.5; 4], 1), 0);
        assert_eq!(b.passing(1, 0b1111, [0.5, 0.5, 0.49, 0.5], 1), 0b0100);
        // Outside [0, 1] nothing passes, whatever the rank.
        assert_eq!(b.passing(1, 0b1111, [-0.1, 1.5, 0.2, 0.3], 1), 0b1100);
    }
}
