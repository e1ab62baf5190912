//! PatchMatch inpainting (Barnes et al. 2009) with the coarse-to-fine EM of Wexler et al. 2007,
//! for the layers of C13 §4: the hair is cut out of the photo and the face and background
//! behind it are filled from the rest of the image.
//!
//! Per pyramid level (coarsest first) the nearest-neighbour field (NNF) of every target patch
//! (a patch overlapping the hole) is found among the source patches (inside the image, fully
//! outside the hole) by PatchMatch, then every hole pixel is re-estimated by voting, and the
//! two alternate for `em_iterations`. The field is upsampled to the next level and voted there
//! to start it. The heavy passes are the engine stages `pm_init`, `pm_cost`, `pm_search` and
//! `pm_vote` (GPU, or their CPU mirrors in parallel); the whole schedule is one recording, so
//! the GPU sees a single submission. The host only builds the pyramid and the per-level flags
//! (linear-time work).
//!
//! The coarsest level starts by onion peel (as Wexler et al. and Newson et al. 2014 do) rather
//! than from a smooth guess: hole colours are marked unknown and left out of patch distances,
//! and the EM steps fill the hole one ring at a time from its border inwards (ring k is voted
//! by the patches that see known pixels, weighted by how many). A smooth first guess (we tried
//! push-pull) makes flat patches the best match everywhere in the hole and leaves pale blobs.
//! Matching is exact integer arithmetic (`stages::pm_common`), so both backends pick the same
//! matches; only the float voting may differ in the last bits.
//!
//! Propagation is parallel: Barnes' scan-order propagation is sequential (each pixel uses the
//! neighbour updated just before it), which a GPU cannot do; every `pm_search` pass instead
//! reads the previous field and looks at the four neighbours at distance `step`
//! (jump flooding), and the host runs steps K, K/2, ..., 1 per PatchMatch iteration: a good
//! offset crosses the level in log2 K passes, where red-black or alternating sweeps would move
//! it one pixel per pass. Random search runs once per iteration, in the step-1 pass, as Barnes
//! does once per pixel per iteration.

use crate::base::mask::{dilate, NEIGHBOURS_8};
use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{BufProxy, Engine, Recording};
use crate::stages::pm_common::{
    pack_rgb, pack_xy, Config, HOLE, LAYER_SHIFT, MAX_PATCH, NONE, QMAX, SOURCE, TARGET, UNKNOWN,
};
use crate::stages::{pm_common, pm_cost, pm_init, pm_search, pm_vote};
use rayon::prelude::*;

/// Tuning of [`inpaint`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct InpaintParams {
    /// Patch side (odd, 3..=31).
    pub patch: u32,
    /// PatchMatch iterations (propagation sweep + random search) per EM step.
    pub iterations: u32,
    /// EM steps (search, then vote) per pyramid level.
    pub em_iterations: u32,
    pub seed: u64,
    /// The pyramid stops before a level whose larger side would fall below this (px).
    pub min_level_size: u32,
    /// Longest propagation jump on the levels after the coarsest (their field arrives
    /// upsampled, so only local refinement is needed); the coarsest uses half its size.
    pub refine_jump: u32,
    /// Voting weight exp(-Δm / (2 σ²)) of a patch whose mean squared difference per channel
    /// (sqrt-encoded, in [0, 1]) is Δm above the best patch covering the pixel.
    pub vote_sigma: f32,
}

impl Default for InpaintParams {
    fn default() -> Self {
        InpaintParams {
            patch: 7,
            iterations: 2,
            em_iterations: 3,
            seed: 0x5eed,
            min_level_size: 48,
            refine_jump: 4,
            vote_sigma: 0.05,
        }
    }
}

impl InpaintParams {
    fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("inpainting parameters: {m}")));
        if self.patch.is_multiple_of(2) || !(3..=MAX_PATCH).contains(&self.patch) {
            return bad(format!(
                "patch must be odd and in 3..={MAX_PATCH}, got {}",
                self.patch
            ));
        }
        if self.iterations == 0 || self.em_iterations == 0 {
            return bad(format!(
                "iterations and em_iterations must be >= 1, got {} and {}",
                self.iterations, self.em_iterations
            ));
        }
        if !(self.vote_sigma.is_finite() && self.vote_sigma > 0.0) {
            return bad(format!(
                "vote_sigma must be finite and > 0, got {}",
                self.vote_sigma
            ));
        }
        Ok(())
    }
}

/// What one pyramid level held and cost.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LevelReport {
    pub width: u32,
    pub height: u32,
    pub hole: usize,
    pub targets: usize,
    pub sources: usize,
    /// Propagation steps of one PatchMatch iteration (the last one also searches).
    pub steps: Vec<u32>,
    /// Onion-peel EM steps before the plain ones (coarsest level only).
    pub peel_layers: u32,
    pub dispatches: u32,
}

/// Figures of one [`inpaint`] run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct InpaintReport {
    pub hole_pixels: usize,
    /// Finest level first; empty when the hole was empty.
    pub levels: Vec<LevelReport>,
    pub dispatches: u32,
    /// Mean over the finest targets of their patch's mean squared difference per channel
    /// (sqrt-encoded, [0, 1]) to its match: how well the fill agrees with its sources.
    pub mean_patch_error: f32,
    pub backend: String,
}

/// One pyramid level as the stages see it.
#[derive(Clone, Debug)]
pub struct Level {
    pub width: u32,
    pub height: u32,
    pub hole: Vec<u8>,
    /// Linear RGB, w = 1.
    pub rgb: Vec<[f32; 4]>,
    /// Packed matching words ([`pack_rgb`]).
    pub px: Vec<u32>,
    /// [`HOLE`] | [`TARGET`] | [`SOURCE`] bits.
    pub flags: Vec<u32>,
    pub hole_count: usize,
    pub targets: usize,
    pub sources: usize,
    /// The first source in row order (packed), or [`NONE`].
    pub fallback: u32,
}

/// Per-pixel flags for a hole (nonzero = hole) and patch half-side `radius`: a target's
/// image-clipped patch overlaps the hole (the hole dilated by `radius`, Chebyshev); a source's
/// patch lies inside the image and off the dilated hole.
pub fn level_flags(width: u32, height: u32, hole: &[u8], radius: u32) -> Vec<u32> {
    let (w, h, r) = (width as usize, height as usize, radius as usize);
    let near = dilate(hole, w, h, r);
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let inside = x >= r && y >= r && x + r < w && y + r < h;
            let mut f = 0;
            if hole[i] != 0 {
                f |= HOLE;
            }
            if near[i] != 0 {
                f |= TARGET;
            } else if inside {
                f |= SOURCE;
            }
            f
        })
        .collect()
}

impl Level {
    pub fn new(width: u32, height: u32, rgb: Vec<[f32; 4]>, hole: Vec<u8>, radius: u32) -> Level {
        let flags = level_flags(width, height, &hole, radius);
        let px = rgb
            .par_iter()
            .map(|c| pack_rgb([c[0], c[1], c[2]]))
            .collect();
        let count = |bit: u32| flags.iter().filter(|&&f| f & bit != 0).count();
        let fallback = flags
            .iter()
            .position(|&f| f & SOURCE != 0)
            .map_or(NONE, |i| pack_xy(i as u32 % width, i as u32 / width));
        Level {
            width,
            height,
            hole_count: count(HOLE),
            targets: count(TARGET),
            sources: count(SOURCE),
            fallback,
            hole,
            rgb,
            px,
            flags,
        }
    }

    /// Half the size (floor): a coarse pixel is hole when any of its four children is, and
    /// otherwise the mean of them, so coarse sources are built from known pixels only.
    pub fn downsample(&self, radius: u32) -> Level {
        let (w, w2, h2) = (self.width as usize, self.width / 2, self.height / 2);
        let n2 = (w2 * h2) as usize;
        let mut rgb = vec![[0.0f32; 4]; n2];
        let mut hole = vec![0u8; n2];
        for i in 0..n2 {
            let (x, y) = (i % w2 as usize, i / w2 as usize);
            let kids = [
                (2 * y) * w + 2 * x,
                (2 * y) * w + 2 * x + 1,
                (2 * y + 1) * w + 2 * x,
                (2 * y + 1) * w + 2 * x + 1,
            ];
            let mut c = [0.0f32; 4];
            for &k in &kids {
                hole[i] |= (self.hole[k] != 0) as u8;
                for (a, b) in c.iter_mut().zip(self.rgb[k]) {
                    *a += 0.25 * b;
                }
            }
            c[3] = 1.0;
            rgb[i] = c;
        }
        Level::new(w2, h2, rgb, hole, radius)
    }

    /// Prepares the onion peel of the coarsest level (see the module notes): hole colours
    /// become [`UNKNOWN`] and each hole pixel's flags get its layer, the 8-connected distance
    /// to a known pixel. Returns the number of layers.
    pub fn mark_peel_layers(&mut self) -> u32 {
        let (w, h) = (self.width as i64, self.height as i64);
        let mut layer = vec![0u32; self.hole.len()];
        let mut front: Vec<usize> = (0..self.hole.len())
            .filter(|&i| self.hole[i] == 0)
            .collect();
        let mut depth = 0;
        while !front.is_empty() {
            depth += 1;
            let mut next = Vec::new();
            for &i in &front {
                let (x, y) = (i as i64 % w, i as i64 / w);
                for (dx, dy) in NEIGHBOURS_8 {
                    let (xx, yy) = (x + dx as i64, y + dy as i64);
                    if xx < 0 || yy < 0 || xx >= w || yy >= h {
                        continue;
                    }
                    let j = (yy * w + xx) as usize;
                    if self.hole[j] != 0 && layer[j] == 0 {
                        layer[j] = depth;
                        next.push(j);
                    }
                }
            }
            front = next;
        }
        for (i, &l) in layer.iter().enumerate() {
            if self.hole[i] != 0 {
                self.flags[i] |= l << LAYER_SHIFT;
                self.px[i] = UNKNOWN;
                self.rgb[i] = [0.0, 0.0, 0.0, 1.0];
            }
        }
        layer.into_iter().max().unwrap_or(0)
    }
}

/// Fewest sources a coarser level must keep to be used.
const MIN_COARSE_SOURCES: usize = 64;

/// The pyramid, finest first, and the number of onion-peel layers of the coarsest level
/// (whose hole colours are marked unknown). Fails when the finest level has no source patch.
pub fn build_pyramid(
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    hole: &[u8],
    p: &InpaintParams,
) -> Result<(Vec<Level>, u32)> {
    let r = p.patch / 2;
    // Hole pixels may hold anything (NaN included): zero them, the fill replaces them.
    let rgb4 = rgb
        .iter()
        .zip(hole)
        .map(|(c, &h)| {
            if h != 0 {
                [0.0, 0.0, 0.0, 1.0]
            } else {
                [c[0], c[1], c[2], 1.0]
            }
        })
        .collect();
    let hole01 = hole.iter().map(|&h| (h != 0) as u8).collect();
    let l0 = Level::new(width, height, rgb4, hole01, r);
    if l0.sources == 0 {
        return Err(Error::Invalid(format!(
            "nothing to inpaint from: no {0}x{0} patch of the {width}x{height} image lies \
             entirely outside the hole ({1} of {2} pixels are hole)",
            p.patch,
            l0.hole_count,
            width as u64 * height as u64
        )));
    }
    let mut levels = vec![l0];
    loop {
        let last = levels.last().expect("one level");
        let (w2, h2) = (last.width / 2, last.height / 2);
        if w2.max(h2) < p.min_level_size || w2.min(h2) < p.patch + 2 {
            break;
        }
        let c = last.downsample(r);
        if c.sources < MIN_COARSE_SOURCES || c.hole_count == 0 {
            break;
        }
        levels.push(c);
    }
    let layers = levels.last_mut().expect("one level").mark_peel_layers();
    Ok((levels, layers))
}

/// Propagation steps of one PatchMatch iteration: powers of two from K down to 1, K the
/// largest power of two <= half the level's larger side on the coarsest level and
/// `refine_jump` (clamped to that) on the others.
pub fn jump_steps(width: u32, height: u32, coarsest: bool, refine_jump: u32) -> Vec<u32> {
    let half = (width.max(height) / 2).max(1);
    let top = if coarsest {
        half
    } else {
        refine_jump.clamp(1, half)
    };
    let k = 1u32 << (31 - top.leading_zeros());
    std::iter::successors(Some(k), |&s| (s > 1).then_some(s / 2)).collect()
}

/// The seed folded to the 32 bits the stages use.
fn seed32(seed: u64) -> u32 {
    (seed ^ (seed >> 32)) as u32
}

/// A uniform for one dispatch, with a fresh pass id for the random numbers.
fn cfg_buf(rec: &mut Recording, c: Config, pass_id: &mut u32) -> BufProxy {
    let c = Config {
        pass_id: *pass_id,
        ..c
    };
    *pass_id += 1;
    rec.uniform("coif.pm.cfg", &c)
}

struct LevelBufs {
    flags: BufProxy,
    px: BufProxy,
    rgb: BufProxy,
    nnf: [BufProxy; 2],
    cost: [BufProxy; 2],
    /// Which of the pairs holds the current field.
    cur: usize,
}

/// Fills the hole (nonzero bytes of `hole`) of a linear RGB image by PatchMatch; pixels
/// outside the hole are returned unchanged. An empty hole returns the image as is.
pub fn inpaint(
    engine: &Engine,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    hole: &[u8],
    p: &InpaintParams,
) -> Result<(Vec<[f32; 3]>, InpaintReport)> {
    p.validate()?;
    let n = width as u64 * height as u64;
    if n == 0 || width > 32768 || height > 32768 {
        return Err(Error::Invalid(format!(
            "cannot inpaint a {width}x{height} image: each side must be 1..=32768"
        )));
    }
    if rgb.len() as u64 != n || hole.len() as u64 != n {
        return Err(Error::Invalid(format!(
            "inpainting a {width}x{height} image needs {n} pixels and {n} hole-mask bytes, \
             got {} and {}",
            rgb.len(),
            hole.len()
        )));
    }
    if let Some(i) = (0..rgb.len()).find(|&i| hole[i] == 0 && !rgb[i].iter().all(|v| v.is_finite()))
    {
        return Err(Error::Invalid(format!(
            "pixel ({}, {}) outside the hole is not finite: {:?}",
            i as u32 % width,
            i as u32 / width,
            rgb[i]
        )));
    }
    let hole_pixels = hole.iter().filter(|&&h| h != 0).count();
    let mut report = InpaintReport {
        hole_pixels,
        levels: Vec::new(),
        dispatches: 0,
        mean_patch_error: 0.0,
        backend: engine.describe(),
    };
    if hole_pixels == 0 {
        return Ok((rgb.to_vec(), report));
    }
    let (levels, peel_layers) = build_pyramid(width, height, rgb, hole, p)?;
    let r = p.patch / 2;
    let seed = seed32(p.seed);
    let vote_k = 1.0 / (2.0 * p.vote_sigma * p.vote_sigma * 3.0 * (QMAX * QMAX) as f32);

    let mut rec = Recording::default();
    let bufs: Vec<LevelBufs> = levels
        .iter()
        .map(|l| {
            let bytes = 4 * l.width as u64 * l.height as u64;
            LevelBufs {
                flags: rec.upload("coif.pm.flags", &l.flags),
                px: rec.upload("coif.pm.px", &l.px),
                rgb: rec.upload("coif.pm.rgb", &l.rgb),
                nnf: [
                    rec.alloc("coif.pm.nnf_a", bytes, SENTINEL),
                    rec.alloc("coif.pm.nnf_b", bytes, SENTINEL),
                ],
                cost: [
                    rec.alloc("coif.pm.cost_a", bytes, SENTINEL),
                    rec.alloc("coif.pm.cost_b", bytes, SENTINEL),
                ],
                cur: 0,
            }
        })
        .collect();
    let mut bufs = bufs;
    let mut pass_id = 0u32;
    let n_levels = levels.len();
    for li in (0..n_levels).rev() {
        let l = &levels[li];
        let coarsest = li == n_levels - 1;
        let base = Config {
            width: l.width,
            height: l.height,
            radius: r,
            seed,
            fallback: l.fallback,
            ..Default::default()
        };
        let wg = pm_common::workgroups(&base);
        let mut dispatches = 0u32;
        let b = &bufs[li];
        let (nnf0, rgb, px, flags) = (b.nnf[0], b.rgb, b.px, b.flags);
        // Start the field: random on the coarsest level, else upsampled and voted (plain
        // average: no distances exist before the hole has colours at this level).
        if coarsest {
            let u = cfg_buf(&mut rec, base, &mut pass_id);
            rec.dispatch(&pm_init::STAGE, wg, &[u, flags, flags, nnf0], &[]);
            dispatches += 1;
        } else {
            let cl = &levels[li + 1];
            let cb = &bufs[li + 1];
            let c = Config {
                coarse_width: cl.width,
                coarse_height: cl.height,
                ..base
            };
            let u = cfg_buf(&mut rec, c, &mut pass_id);
            rec.dispatch(&pm_init::STAGE, wg, &[u, flags, cb.nnf[cb.cur], nnf0], &[]);
            let u = cfg_buf(&mut rec, base, &mut pass_id);
            rec.dispatch(
                &pm_vote::STAGE,
                wg,
                &[u, flags, nnf0, b.cost[0], rgb, px],
                &[],
            );
            dispatches += 2;
        }
        let steps = jump_steps(l.width, l.height, coarsest, p.refine_jump);
        let mut cur = 0usize;
        // One EM step: distances for the current colours, PatchMatch, vote. Onion peel on
        // the coarsest level first (layer 1, 2, ...), then plain EM steps (layer 0).
        let peel = if coarsest { peel_layers } else { 0 };
        for layer in (1..=peel).chain(std::iter::repeat_n(0, p.em_iterations as usize)) {
            let u = cfg_buf(&mut rec, base, &mut pass_id);
            rec.dispatch(
                &pm_cost::STAGE,
                wg,
                &[u, flags, px, b.nnf[cur], b.cost[cur]],
                &[],
            );
            dispatches += 1;
            for _ in 0..p.iterations {
                for &step in &steps {
                    let c = Config {
                        step,
                        search_radius: if step == 1 { l.width.max(l.height) } else { 0 },
                        ..base
                    };
                    let u = cfg_buf(&mut rec, c, &mut pass_id);
                    rec.dispatch(
                        &pm_search::STAGE,
                        wg,
                        &[
                            u,
                            flags,
                            px,
                            b.nnf[cur],
                            b.cost[cur],
                            b.nnf[1 - cur],
                            b.cost[1 - cur],
                        ],
                        &[],
                    );
                    cur = 1 - cur;
                    dispatches += 1;
                }
            }
            let c = Config {
                vote_k,
                layer,
                ..base
            };
            let u = cfg_buf(&mut rec, c, &mut pass_id);
            rec.dispatch(
                &pm_vote::STAGE,
                wg,
                &[u, flags, b.nnf[cur], b.cost[cur], rgb, px],
                &[],
            );
            dispatches += 1;
        }
        bufs[li].cur = cur;
        report.levels.push(LevelReport {
            width: l.width,
            height: l.height,
            hole: l.hole_count,
            targets: l.targets,
            sources: l.sources,
            steps,
            peel_layers: if coarsest { peel_layers } else { 0 },
            dispatches,
        });
        report.dispatches += dispatches;
    }
    report.levels.reverse();
    let b0 = &bufs[0];
    let (rgb_b, cost_b) = (b0.rgb, b0.cost[b0.cur]);
    rec.download(rgb_b);
    rec.download(cost_b);
    let dl = engine.run(rec)?;
    let out4 = dl.get::<[f32; 4]>(rgb_b);
    let cost = dl.get::<u32>(cost_b);
    let l0 = &levels[0];
    let g = pm_common::Geom {
        w: width as i32,
        h: height as i32,
        r: r as i32,
    };
    let mut err_sum = 0.0f64;
    for (i, &f) in l0.flags.iter().enumerate() {
        if f & TARGET != 0 {
            let (x, y) = ((i as u32 % width) as i32, (i as u32 / width) as i32);
            err_sum += cost[i] as f64 / (g.patch_count(x, y) as f64 * 3.0 * (QMAX * QMAX) as f64);
        }
    }
    report.mean_patch_error = (err_sum / l0.targets.max(1) as f64) as f32;
    let out = (0..rgb.len())
        .map(|i| {
            if hole[i] != 0 {
                let c = out4[i];
                [c[0], c[1], c[2]]
            } else {
                rgb[i]
            }
        })
        .collect();
    Ok((out, report))
}

// ---------------------------------------------------------------------------------------------
// Cheap fills
// ---------------------------------------------------------------------------------------------

/// Push-pull fill (Gortler et al. 1996): known pixels are averaged down a pyramid to 1x1 and
/// the unknown ones interpolated back up (bilinear, blended by the coverage of each level).
/// Smooth, with no structure: the head texture's far back and the start of
/// [`diffusion_fill`]. `wrap_x` makes rows periodic (a texture whose
/// u wraps around the head). With no known pixel at all every pixel comes back black.
pub fn push_pull(
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    known: &[bool],
    wrap_x: bool,
) -> Vec<[f32; 3]> {
    struct Lv {
        w: usize,
        h: usize,
        col: Vec<[f32; 3]>,
        wt: Vec<f32>,
    }
    let (w0, h0) = (width as usize, height as usize);
    let mut lv = vec![Lv {
        w: w0,
        h: h0,
        col: (0..w0 * h0)
            .map(|i| if known[i] { rgb[i] } else { [0.0; 3] })
            .collect(),
        wt: known.iter().map(|&k| k as u8 as f32).collect(),
    }];
    while lv.last().is_some_and(|l| l.w > 1 || l.h > 1) {
        let f = lv.last().expect("a level");
        let (w2, h2) = (f.w.div_ceil(2), f.h.div_ceil(2));
        let mut col = vec![[0.0f32; 3]; w2 * h2];
        let mut wt = vec![0.0f32; w2 * h2];
        for y in 0..h2 {
            for x in 0..w2 {
                let (mut sw, mut sc) = (0.0f32, [0.0f32; 3]);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (mut cx, cy) = (2 * x + dx, 2 * y + dy);
                    if cx >= f.w {
                        if !wrap_x {
                            continue;
                        }
                        cx -= f.w;
                    }
                    if cy >= f.h {
                        continue;
                    }
                    let k = cy * f.w + cx;
                    sw += f.wt[k];
                    for (a, b) in sc.iter_mut().zip(f.col[k]) {
                        *a += f.wt[k] * b;
                    }
                }
                if sw > 0.0 {
                    col[y * w2 + x] = sc.map(|s| s / sw);
                }
                wt[y * w2 + x] = sw.min(1.0);
            }
        }
        lv.push(Lv {
            w: w2,
            h: h2,
            col,
            wt,
        });
    }
    for l in (0..lv.len() - 1).rev() {
        let (lo, hi) = lv.split_at_mut(l + 1);
        let (f, c) = (&mut lo[l], &hi[0]);
        for y in 0..f.h {
            for x in 0..f.w {
                let i = y * f.w + x;
                if f.wt[i] >= 1.0 {
                    continue;
                }
                // Bilinear in the coarse level at this pixel's centre.
                let gx = (x as f32 + 0.5) * c.w as f32 / f.w as f32 - 0.5;
                let gy =
                    ((y as f32 + 0.5) * c.h as f32 / f.h as f32 - 0.5).clamp(0.0, (c.h - 1) as f32);
                let (x0, y0) = (gx.floor(), gy.floor());
                let (tx, ty) = (gx - x0, gy - y0);
                let xi = |k: i64| -> usize {
                    if wrap_x {
                        k.rem_euclid(c.w as i64) as usize
                    } else {
                        k.clamp(0, c.w as i64 - 1) as usize
                    }
                };
                let (xa, xb) = (xi(x0 as i64), xi(x0 as i64 + 1));
                let (ya, yb) = (y0 as usize, (y0 as usize + 1).min(c.h - 1));
                let mut up = [0.0f32; 3];
                for (k, u) in up.iter_mut().enumerate() {
                    let top = c.col[ya * c.w + xa][k] * (1.0 - tx) + c.col[ya * c.w + xb][k] * tx;
                    let bot = c.col[yb * c.w + xa][k] * (1.0 - tx) + c.col[yb * c.w + xb][k] * tx;
                    *u = top * (1.0 - ty) + bot * ty;
                }
                let a = f.wt[i];
                for (k, u) in up.iter().enumerate() {
                    f.col[i][k] = a * f.col[i][k] + (1.0 - a) * u;
                }
                f.wt[i] = 1.0;
            }
        }
    }
    lv.swap_remove(0).col
}

/// A plain diffusion (harmonic) fill, the baseline PatchMatch is measured against: push-pull
/// start, then `sweeps` successive over-relaxation sweeps of the 4-neighbour Laplace equation
/// over the hole, known pixels fixed.
pub fn diffusion_fill(
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    hole: &[u8],
    sweeps: u32,
) -> Vec<[f32; 3]> {
    let known: Vec<bool> = hole.iter().map(|&h| h == 0).collect();
    let mut v = push_pull(width, height, rgb, &known, false);
    let (w, h) = (width as usize, height as usize);
    let idx: Vec<usize> = (0..w * h).filter(|&i| !known[i]).collect();
    const OMEGA: f32 = 1.8;
    for _ in 0..sweeps {
        for &i in &idx {
            let (x, y) = (i % w, i / w);
            let (mut s, mut n) = ([0.0f32; 3], 0.0f32);
            let mut add = |j: usize| {
                for c in 0..3 {
                    s[c] += v[j][c];
                }
                n += 1.0;
            };
            if x > 0 {
                add(i - 1);
            }
            if x + 1 < w {
                add(i + 1);
            }
            if y > 0 {
                add(i - w);
            }
            if y + 1 < h {
                add(i + w);
            }
            for c in 0..3 {
                v[i][c] += OMEGA * (s[c] / n - v[i][c]);
            }
        }
    }
    v
}
