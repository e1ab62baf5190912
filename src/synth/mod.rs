//! Synthetic portraits with exact hair-orientation ground truth.
//!
//! A cartoon portrait (background, shoulders, face with eyes, brows, nose and mouth) whose hair
//! is drawn as thousands of thin anti-aliased strands integrated through a known analytic 2-D
//! growth field. The field itself, sampled at every hair pixel centre, is the ground truth
//! for the orientation stage; the strokes follow it too, so direction resolution can be
//! tested as well. Everything is deterministic for a (style, seed, size).
//!
//! Coordinates follow `annot`: pixel (i, j) has its centre at (i + 0.5, j + 0.5), x right,
//! y down. Orientation angles are measured from +x towards +y (clockwise on screen).

mod draw;
mod field;
mod scene;
pub mod synth3d;
pub mod video;

// Drawing helpers and looks shared with `synth3d`.
pub(crate) use draw::*;
use scene::Scene;

use crate::base::rng::Rng;
use crate::error::{Error, Result};
use crate::io::annot::{Landmarks, Stroke, StrokeKind, Strokes};
use image::{GrayImage, RgbImage};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::f32::consts::PI;
use std::path::Path;
use std::str::FromStr;

/// Hair style of a synthetic portrait.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Style {
    /// Centre part, hair flowing over the head and falling below the shoulders.
    Long,
    /// Short-ish cap spiralling out of a crown whorl (one singular point inside the mask).
    Whorl,
    /// Side part: orientation continuous across the part, growth direction flips there.
    SidePart,
    /// Crew-cut-like short strands radiating from the crown.
    Short,
    /// A fringe swept sideways across the forehead over side hair that falls from the crown:
    /// the orientation jumps by ≥ 45° along a known seam inside the hair (CZ06 Fig. 10); see
    /// [`seam`]. 2D only (not in [`Style::ALL`], no 3D or video version).
    Fringe,
}

impl Style {
    /// The styles every 2D, 3D and video test iterates over.
    pub const ALL: [Style; 4] = [Style::Long, Style::Whorl, Style::SidePart, Style::Short];
    /// Further 2D styles, named and parsed like the others but kept out of [`Style::ALL`] so
    /// the figures of the tests over it stay what they were.
    pub const EXTRA: [Style; 1] = [Style::Fringe];

    pub fn name(self) -> &'static str {
        match self {
            Style::Long => "long",
            Style::Whorl => "whorl",
            Style::SidePart => "sidepart",
            Style::Short => "short",
            Style::Fringe => "fringe",
        }
    }

    /// Whether the 3D synth (and so the synthetic video) has this style.
    pub fn has_3d(self) -> bool {
        Style::ALL.contains(&self)
    }
}

impl std::fmt::Display for Style {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Style {
    type Err = Error;
    fn from_str(s: &str) -> Result<Style> {
        Style::ALL
            .iter()
            .chain(Style::EXTRA.iter())
            .copied()
            .find(|st| st.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Style::ALL
                    .iter()
                    .chain(Style::EXTRA.iter())
                    .map(|st| st.name())
                    .collect();
                Error::Invalid(format!(
                    "unknown style \"{s}\" (expected one of {})",
                    names.join(", ")
                ))
            })
    }
}

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SynthParams {
    pub style: Style,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
}

impl SynthParams {
    pub const DEFAULT_SIZE: u32 = 512;
    /// The smallest size that still leaves room for strands between the face features.
    pub const MIN_SIZE: u32 = 64;

    /// `style` and `seed` at the default 512x512 size.
    pub fn new(style: Style, seed: u64) -> Self {
        SynthParams {
            style,
            seed,
            width: Self::DEFAULT_SIZE,
            height: Self::DEFAULT_SIZE,
        }
    }
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams::new(Style::Long, 1)
    }
}

/// A generated portrait and its ground truth.
#[derive(Clone, Debug)]
pub struct SynthCase {
    pub image: RgbImage,
    /// 255 = hair, 0 otherwise.
    pub mask: GrayImage,
    pub strokes: Strokes,
    pub landmarks: Landmarks,
    /// H*W, row-major: strand orientation in [0, pi), tangent (cos t, sin t) with x right and
    /// y down; NaN off hair.
    pub gt_theta: Vec<f32>,
    /// H*W*2, row-major: unit growth direction (root -> tip); NaN off hair.
    pub gt_dir: Vec<f32>,
    pub width: u32,
    pub height: u32,
}

impl SynthCase {
    /// Writes image.png, mask.png, strokes.json, landmarks.json, gt_theta.npy (H, W) and
    /// gt_dir.npy (H, W, 2) into `dir`, creating it; every file is written atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        crate::io::ensure_dir(dir)?;
        let (w, h) = (self.width as usize, self.height as usize);
        crate::io::write_png(&dir.join("image.png"), &self.image)?;
        crate::io::write_png(&dir.join("mask.png"), &self.mask)?;
        self.strokes.save(&dir.join("strokes.json"))?;
        self.landmarks.save(&dir.join("landmarks.json"))?;
        crate::io::npy::write_f32(&dir.join("gt_theta.npy"), &[h, w], &self.gt_theta)?;
        crate::io::npy::write_f32(&dir.join("gt_dir.npy"), &[h, w, 2], &self.gt_dir)?;
        Ok(())
    }

    /// Whether pixel (x, y) is hair.
    pub fn is_hair(&self, x: u32, y: u32) -> bool {
        self.mask.get_pixel(x, y)[0] > 127
    }
}

/// Pixels of `mask` (value > 127) whose distance to every non-mask pixel, and to the outside
/// of the image, is at least `min_dist` pixel-centre spacings. Row-major, W*H.
pub fn mask_interior(mask: &GrayImage, min_dist: f32) -> Vec<bool> {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let hair: Vec<bool> = mask.as_raw().iter().map(|&v| v > 127).collect();
    // Offsets strictly closer than `min_dist`: any non-hair pixel there disqualifies.
    let offs = crate::base::mask::disc(min_dist, true);
    crate::base::mask::erode_by(&hair, w, h, &offs, false)
}

/// The seam of a style with an orientation discontinuity inside the hair ([`Style::Fringe`]).
#[derive(Clone, Debug)]
pub struct Seam {
    /// W*H: hair pixels on the fringe's side of the seam.
    pub fringe: Vec<bool>,
    /// W*H: the seam's pixels: hair pixels with a 4-neighbour hair pixel on the other side.
    pub on: Vec<bool>,
    /// W*H: distance from each hair pixel's centre to the nearest seam pixel's centre, px
    /// (0 on the seam); NaN off hair.
    pub distance: Vec<f32>,
}

/// The seam of `p`'s portrait (the case [`synth`] makes from the same params), or None for
/// styles without one.
pub fn seam(p: &SynthParams) -> Option<Seam> {
    if p.style != Style::Fringe {
        return None;
    }
    let [mut geo_rng, mut look_rng, ..] = streams(p, style_salt(p.style));
    let scene = Scene::new(p, &mut geo_rng, &mut look_rng);
    let (w, h) = (p.width as usize, p.height as usize);
    let mut hair = vec![false; w * h];
    let mut fringe = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
            let k = y * w + x;
            hair[k] = scene.hair_sdf(px, py) < 0.0;
            fringe[k] = hair[k] && scene.field.in_fringe(px, py);
        }
    }
    let mut on = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            if !hair[k] {
                continue;
            }
            let nb = [
                (x > 0).then(|| k - 1),
                (x + 1 < w).then(|| k + 1),
                (y > 0).then(|| k - w),
                (y + 1 < h).then(|| k + w),
            ];
            on[k] = nb
                .into_iter()
                .flatten()
                .any(|j| hair[j] && fringe[j] != fringe[k]);
        }
    }
    let d = distance_to(&on, w, h);
    let distance = (0..w * h)
        .map(|k| if hair[k] { d[k] } else { f32::NAN })
        .collect();
    Some(Seam {
        fringe,
        on,
        distance,
    })
}

/// Exact Euclidean distance from every pixel centre to the nearest pixel of `set` (W*H,
/// row-major), px; +∞ everywhere when `set` is empty (Felzenszwalb and Huttenlocher's
/// separable transform).
pub fn distance_to(set: &[bool], w: usize, h: usize) -> Vec<f32> {
    assert_eq!(set.len(), w * h, "set has the image's size");
    const INF: f64 = 1e20;
    // Squared distances along each column, then along each row.
    let mut d2: Vec<f64> = set.iter().map(|&s| if s { 0.0 } else { INF }).collect();
    let mut col = vec![0.0f64; h];
    for x in 0..w {
        for y in 0..h {
            col[y] = d2[y * w + x];
        }
        let out = dt_1d(&col);
        for y in 0..h {
            d2[y * w + x] = out[y];
        }
    }
    for y in 0..h {
        let out = dt_1d(&d2[y * w..(y + 1) * w]);
        d2[y * w..(y + 1) * w].copy_from_slice(&out);
    }
    d2.iter()
        .map(|&v| {
            if v >= INF {
                f32::INFINITY
            } else {
                v.sqrt() as f32
            }
        })
        .collect()
}

/// 1D squared distance transform: min over q of (p − q)² + f(q) (lower envelope of parabolas).
fn dt_1d(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut out = vec![f64::INFINITY; n];
    // Parabolas with a finite apex only: an all-infinite line stays infinite.
    let finite: Vec<usize> = (0..n).filter(|&q| f[q] < 1e20).collect();
    if finite.is_empty() {
        return f.to_vec();
    }
    let mut v = vec![0usize; finite.len()];
    let mut z = vec![0.0f64; finite.len() + 1];
    let mut k = 0usize;
    v[0] = finite[0];
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let inter = |q: usize, p: usize| -> f64 {
        let (qf, pf) = (q as f64, p as f64);
        ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf))
    };
    for &q in &finite[1..] {
        let mut s = inter(q, v[k]);
        while s <= z[k] {
            k -= 1;
            s = inter(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (p, o) in out.iter_mut().enumerate() {
        while z[k + 1] < p as f64 {
            k += 1;
        }
        let d = p as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
    out
}

/// Smallest angle between two orientations (mod pi), in degrees.
pub fn orientation_error_deg(a: f32, b: f32) -> f32 {
    crate::eval::metrics::orient_diff(a, b).to_degrees()
}

/// Generates the portrait. Panics if a side is below [`SynthParams::MIN_SIZE`].
pub fn synth(p: &SynthParams) -> SynthCase {
    let [mut geo_rng, mut look_rng, mut strand_rng, mut stroke_rng] =
        streams(p, style_salt(p.style));

    let scene = Scene::new(p, &mut geo_rng, &mut look_rng);
    let (w, h) = (p.width as usize, p.height as usize);

    // Mask and ground truth: the analytic region and field at pixel centres.
    let mut mask = vec![0u8; w * h];
    let mut gt_theta = vec![f32::NAN; w * h];
    let mut gt_dir = vec![f32::NAN; w * h * 2];
    mask.par_chunks_mut(w)
        .zip(gt_theta.par_chunks_mut(w))
        .zip(gt_dir.par_chunks_mut(2 * w))
        .enumerate()
        .for_each(|(y, ((mrow, trow), drow))| {
            let py = y as f32 + 0.5;
            for x in 0..w {
                let px = x as f32 + 0.5;
                if scene.hair_sdf(px, py) < 0.0 {
                    mrow[x] = 255;
                    let d = scene.field.dir(px, py);
                    drow[2 * x] = d[0];
                    drow[2 * x + 1] = d[1];
                    trow[x] = theta_of(d);
                }
            }
        });

    let mut rgb = scene.render_base();
    scene.draw_hair(&mut rgb, &mask, &mut strand_rng);
    let strokes = scene.make_strokes(&mask, &gt_dir, &mut stroke_rng);

    let image = to_image(&rgb, p.width, p.height);
    SynthCase {
        image,
        mask: GrayImage::from_raw(p.width, p.height, mask).expect("mask size"),
        strokes,
        landmarks: scene.landmarks(),
        gt_theta,
        gt_dir,
        width: p.width,
        height: p.height,
    }
}

/// The longest prefix of a stroke whose points are hair (`mask` > 0) and whose segments agree
/// with the ground truth `gt_dir` within 12° at their midpoints, so sampling on the pixel grid
/// cannot contradict it. `unit` turns a segment into its direction (how each synth treats a
/// degenerate segment).
pub(crate) fn checked_prefix(
    pts: Vec<[f32; 2]>,
    mask: &[u8],
    gt_dir: &[f32],
    w: usize,
    h: usize,
    unit: impl Fn([f32; 2]) -> [f32; 2],
) -> Vec<[f32; 2]> {
    let at = |p: [f32; 2]| -> Option<usize> {
        let (ix, iy) = (p[0].floor() as i64, p[1].floor() as i64);
        (ix >= 0 && iy >= 0 && (ix as usize) < w && (iy as usize) < h)
            .then(|| iy as usize * w + ix as usize)
            .filter(|&i| mask[i] > 0)
    };
    let mut out: Vec<[f32; 2]> = Vec::new();
    for p in pts {
        if at(p).is_none() {
            break;
        }
        if let Some(&q) = out.last() {
            let m = [(p[0] + q[0]) * 0.5, (p[1] + q[1]) * 0.5];
            let Some(i) = at(m) else { break };
            let seg = unit([p[0] - q[0], p[1] - q[1]]);
            if seg[0] * gt_dir[2 * i] + seg[1] * gt_dir[2 * i + 1] < 12f32.to_radians().cos() {
                break;
            }
        }
        out.push(p);
    }
    out
}

/// The portrait's random streams (geometry, look, strands, strokes), forked from one root
/// salted per style, so that changing how one part draws numbers leaves the others alone.
/// Panics if a side is below [`SynthParams::MIN_SIZE`].
pub(crate) fn streams(p: &SynthParams, salt: u64) -> [Rng; 4] {
    assert!(
        p.width >= SynthParams::MIN_SIZE && p.height >= SynthParams::MIN_SIZE,
        "synthetic portraits need at least {0}x{0} pixels, got {1}x{2}",
        SynthParams::MIN_SIZE,
        p.width,
        p.height
    );
    let mut root = Rng::new(p.seed ^ salt);
    [1, 2, 3, 4].map(|k| root.fork(k))
}

fn style_salt(s: Style) -> u64 {
    // Different styles with the same seed should not share faces and colours exactly.
    match s {
        Style::Long => 0x4c6f_6e67,
        Style::Whorl => 0x5768_6f72,
        Style::SidePart => 0x5369_6465,
        Style::Short => 0x5368_6f72,
        Style::Fringe => 0x4672_696e,
    }
}

/// Orientation in [0, pi) of a direction.
pub(crate) fn theta_of(d: [f32; 2]) -> f32 {
    let t = (d[1] as f64)
        .atan2(d[0] as f64)
        .rem_euclid(std::f64::consts::PI) as f32;
    // Rounding to f32 can produce exactly pi; that orientation is 0.
    if t >= PI {
        0.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::FRAC_PI_2;

    fn case(style: Style, seed: u64) -> SynthCase {
        synth(&SynthParams::new(style, seed))
    }

    fn hair_fraction(c: &SynthCase) -> f64 {
        c.mask.pixels().filter(|p| p[0] > 127).count() as f64 / (c.width * c.height) as f64
    }

    #[test]
    fn style_names_round_trip() {
        for s in Style::ALL {
            assert_eq!(s.to_string().parse::<Style>().unwrap(), s);
        }
        let e = "curly".parse::<Style>().unwrap_err().to_string();
        assert!(e.contains("long, whorl, sidepart, short"), "{e}");
        assert_eq!(SynthParams::default().width, 512);
        assert_eq!(SynthParams::default().height, 512);
    }

    #[test]
    fn deterministic_per_seed() {
        for style in Style::ALL {
            let a = case(style, 7);
            let b = case(style, 7);
            assert_eq!(a.image.as_raw(), b.image.as_raw(), "{style}");
            assert_eq!(a.mask.as_raw(), b.mask.as_raw());
            assert_eq!(a.strokes, b.strokes);
            assert_eq!(a.landmarks, b.landmarks);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&a.gt_theta), bits(&b.gt_theta));
            assert_eq!(bits(&a.gt_dir), bits(&b.gt_dir));
            let c = case(style, 8);
            assert_ne!(a.image.as_raw(), c.image.as_raw(), "{style}");
        }
    }

    #[test]
    fn ground_truth_is_consistent() {
        for style in Style::ALL {
            for seed in 1..=3 {
                let c = case(style, seed);
                let n = (c.width * c.height) as usize;
                assert_eq!(c.gt_theta.len(), n);
                assert_eq!(c.gt_dir.len(), 2 * n);
                for i in 0..n {
                    let hair = c.mask.as_raw()[i] == 255;
                    let t = c.gt_theta[i];
                    let (dx, dy) = (c.gt_dir[2 * i], c.gt_dir[2 * i + 1]);
                    if !hair {
                        assert_eq!(c.mask.as_raw()[i], 0);
                        assert!(t.is_nan() && dx.is_nan() && dy.is_nan(), "{style} {i}");
                        continue;
                    }
                    assert!(t.is_finite() && dx.is_finite() && dy.is_finite());
                    assert!((0.0..PI).contains(&t), "{t}");
                    assert!((dx.hypot(dy) - 1.0).abs() < 1e-5);
                    let from_dir = dy.atan2(dx);
                    assert!(orientation_error_deg(from_dir, t) < 1e-3, "{style} {i}");
                }
            }
        }
    }

    /// 4-connected components of the mask.
    fn components(c: &SynthCase) -> usize {
        let (w, h) = (c.width as usize, c.height as usize);
        let hair: Vec<bool> = c.mask.as_raw().iter().map(|&v| v > 0).collect();
        let mut count = 0;
        crate::base::mask::for_each_component(&hair, w, h, true, false, |_, _| count += 1);
        count
    }

    #[test]
    fn checked_prefix_stops_off_hair_and_against_the_field() {
        let (w, h) = (10, 10);
        let mut mask = vec![255u8; w * h];
        mask[9 * w + 4] = 0;
        let gt: Vec<f32> = (0..w * h).flat_map(|_| [1.0, 0.0]).collect();
        let run = |pts: &[[f32; 2]], unit: fn([f32; 2]) -> [f32; 2]| {
            checked_prefix(pts.to_vec(), &mask, &gt, w, h, unit).len()
        };
        let zero = |v: [f32; 2]| {
            if v == [0.0; 2] {
                v
            } else {
                field::normalize(v)
            }
        };
        assert_eq!(
            run(&[[0.5, 0.5], [2.5, 0.5], [4.5, 0.6]], field::normalize),
            3
        );
        assert_eq!(
            run(&[[0.5, 0.5], [2.5, 0.5], [2.5, 3.5]], field::normalize),
            2
        );
        assert_eq!(run(&[[2.5, 9.5], [4.5, 9.5]], field::normalize), 1);
        assert_eq!(run(&[[0.5, 0.5], [0.5, 0.5]], field::normalize), 2);
        assert_eq!(run(&[[0.5, 0.5], [0.5, 0.5]], zero), 1);
    }

    #[test]
    fn streams_are_distinct_and_reproducible() {
        let p = SynthParams::new(Style::Long, 3);
        let mut a = streams(&p, 1);
        let mut b = streams(&p, 1);
        let first: Vec<u32> = a.iter_mut().map(|r| r.next_u32()).collect();
        assert_eq!(
            first,
            b.iter_mut().map(|r| r.next_u32()).collect::<Vec<_>>()
        );
        assert!(first
            .iter()
            .enumerate()
            .all(|(i, x)| !first[..i].contains(x)));
        assert_ne!(streams(&p, 2)[0].next_u32(), first[0]);
    }

    #[test]
    fn mask_shape_per_style() {
        for style in Style::ALL {
            for seed in 1..=3 {
                let c = case(style, seed);
                let f = hair_fraction(&c);
                let (lo, hi) = match style {
                    Style::Long => (0.25, 0.40),
                    Style::Whorl => (0.05, 0.12),
                    Style::SidePart => (0.06, 0.13),
                    Style::Short => (0.04, 0.09),
                    Style::Fringe => unreachable!("not in Style::ALL"),
                };
                println!("{style} seed {seed}: hair {:.1}% of the image", 100.0 * f);
                assert!((lo..=hi).contains(&f), "{style} seed {seed}: {f}");
                assert_eq!(components(&c), 1, "{style} seed {seed}: mask not connected");
                // The face is never hair.
                for name in crate::io::annot::REQUIRED_LANDMARKS {
                    let p = c.landmarks.get(name).unwrap();
                    assert!(
                        !c.is_hair(p[0] as u32, p[1] as u32),
                        "{style}: {name} on hair"
                    );
                }
                c.landmarks.validate(Some((c.width, c.height))).unwrap();
                let (le, re) = (
                    c.landmarks.get("left_eye").unwrap(),
                    c.landmarks.get("right_eye").unwrap(),
                );
                assert!(le[0] < re[0]);
            }
        }
    }

    #[test]
    fn strokes_follow_the_field() {
        for style in Style::ALL {
            for seed in 1..=3 {
                let c = case(style, seed);
                let w = c.width as usize;
                let n = c.strokes.strokes.len();
                assert!((4..=6).contains(&n), "{style} seed {seed}: {n} strokes");
                c.strokes.validate(Some((c.width, c.height))).unwrap();
                // 2 px: strokes on the narrow side of a part run close to its edge.
                let inner = mask_interior(&c.mask, 2.0);
                for (si, s) in c.strokes.strokes.iter().enumerate() {
                    assert_eq!(s.kind, StrokeKind::Direction);
                    let len: f32 = s
                        .points
                        .windows(2)
                        .map(|q| (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]))
                        .sum();
                    assert!((40.0..=200.0).contains(&len), "{style} {seed} {si}: {len}");
                    for q in &s.points {
                        let k = q[1] as usize * w + q[0] as usize;
                        assert!(
                            inner[k],
                            "{style} {seed} stroke {si}: point {q:?} near the edge"
                        );
                    }
                    for q in s.points.windows(2) {
                        let seg = (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]);
                        assert!((3.0..=12.0).contains(&seg), "{style} {seed}: segment {seg}");
                        let m = [(q[0][0] + q[1][0]) / 2.0, (q[0][1] + q[1][1]) / 2.0];
                        let k = m[1] as usize * w + m[0] as usize;
                        let g = [c.gt_dir[2 * k], c.gt_dir[2 * k + 1]];
                        let d = [(q[1][0] - q[0][0]) / seg, (q[1][1] - q[0][1]) / seg];
                        let cosang = d[0] * g[0] + d[1] * g[1];
                        assert!(
                            cosang > 20f32.to_radians().cos(),
                            "{style} {seed} stroke {si}: {:.1} deg off the growth direction",
                            cosang.clamp(-1.0, 1.0).acos().to_degrees()
                        );
                    }
                }
                if style == Style::SidePart {
                    let Some(part) = part_x(&c) else {
                        panic!("sidepart seed {seed}: no part found");
                    };
                    let left = c
                        .strokes
                        .strokes
                        .iter()
                        .any(|s| s.points.iter().all(|p| p[0] < part));
                    let right = c
                        .strokes
                        .strokes
                        .iter()
                        .any(|s| s.points.iter().all(|p| p[0] > part));
                    assert!(
                        left && right,
                        "sidepart seed {seed}: strokes on one side only"
                    );
                }
            }
        }
    }

    /// x of the part line: where gt_dir's x component flips sign along a row near the top.
    fn part_x(c: &SynthCase) -> Option<f32> {
        let w = c.width as usize;
        for y in 0..c.height as usize {
            let mut prev: Option<f32> = None;
            for x in 0..w {
                let k = y * w + x;
                let dx = c.gt_dir[2 * k];
                if dx.is_nan() {
                    prev = None;
                    continue;
                }
                if let Some(p) = prev {
                    // Left side grows left (-x), right side grows right: a jump from - to +.
                    if p < -0.9 && dx > 0.9 {
                        return Some(x as f32);
                    }
                }
                prev = Some(dx);
            }
        }
        None
    }

    #[test]
    fn sidepart_orientation_continuous_direction_flips() {
        for seed in 1..=3 {
            let c = case(Style::SidePart, seed);
            let w = c.width as usize;
            let part = part_x(&c).expect("a part") as usize;
            let mut checked = 0;
            for y in 0..c.height as usize {
                let (l, r) = (y * w + part - 1, y * w + part);
                if c.gt_theta[l].is_nan() || c.gt_theta[r].is_nan() {
                    continue;
                }
                let dot =
                    c.gt_dir[2 * l] * c.gt_dir[2 * r] + c.gt_dir[2 * l + 1] * c.gt_dir[2 * r + 1];
                if dot < 0.0 {
                    checked += 1;
                    assert!(dot < -0.95, "seed {seed} row {y}: not a clean flip");
                    let e = orientation_error_deg(c.gt_theta[l], c.gt_theta[r]);
                    assert!(e < 3.0, "seed {seed} row {y}: orientation jumps {e} deg");
                }
            }
            assert!(checked >= 20, "seed {seed}: part only {checked} px long");
        }
    }

    #[test]
    fn texture_everywhere_on_hair() {
        // No flat patches: the luma varies in every 7x7 window well inside the hair.
        for style in Style::ALL {
            for seed in 1..=2 {
                let c = case(style, seed);
                let (w, h) = (c.width as usize, c.height as usize);
                let luma = gray(&c.image);
                let inner = mask_interior(&c.mask, 3.0);
                let mut worst = (f32::INFINITY, 0, 0);
                for y in 3..h - 3 {
                    for x in 3..w - 3 {
                        if !inner[y * w + x] {
                            continue;
                        }
                        let (mut s, mut s2) = (0.0f32, 0.0f32);
                        for dy in -3i64..=3 {
                            for dx in -3i64..=3 {
                                let v =
                                    luma[(y as i64 + dy) as usize * w + (x as i64 + dx) as usize];
                                s += v;
                                s2 += v * v;
                            }
                        }
                        let sd = (s2 / 49.0 - (s / 49.0).powi(2)).max(0.0).sqrt();
                        if sd < worst.0 {
                            worst = (sd, x, y);
                        }
                    }
                }
                let (sd, x, y) = worst;
                println!("{style} seed {seed}: least 7x7 luma std dev {sd:.2} at ({x}, {y})");
                assert!(
                    sd > 2.0,
                    "{style} seed {seed}: flat hair patch at ({x}, {y}): {sd}"
                );
            }
        }
    }

    fn gray(img: &RgbImage) -> Vec<f32> {
        img.pixels()
            .map(|p| 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32)
            .collect()
    }

    /// Separable correlation: `kx` along rows, `ky` along columns (odd lengths, clamped edges).
    fn sep_filter(v: &[f32], w: usize, h: usize, kx: &[f32], ky: &[f32]) -> Vec<f32> {
        let (rx, ry) = ((kx.len() / 2) as i64, (ky.len() / 2) as i64);
        let clampi = |i: i64, n: usize| i.clamp(0, n as i64 - 1) as usize;
        let mut tmp = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                tmp[y * w + x] = (-rx..=rx)
                    .map(|i| kx[(i + rx) as usize] * v[y * w + clampi(x as i64 + i, w)])
                    .sum();
            }
        }
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                out[y * w + x] = (-ry..=ry)
                    .map(|i| ky[(i + ry) as usize] * tmp[clampi(y as i64 + i, h) * w + x])
                    .sum();
            }
        }
        out
    }

    fn gauss_blur(v: &[f32], w: usize, h: usize, sigma: f32) -> Vec<f32> {
        let r = (3.0 * sigma).ceil() as i64;
        let k: Vec<f32> = (-r..=r)
            .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
            .collect();
        let ks: f32 = k.iter().sum();
        let k: Vec<f32> = k.iter().map(|x| x / ks).collect();
        sep_filter(v, w, h, &k, &k)
    }

    /// Test-only orientation estimate: structure tensor of the luma (central differences,
    /// Gaussian sigma 3), orientation perpendicular to the dominant gradient.
    fn structure_tensor_theta(img: &RgbImage) -> Vec<f32> {
        st_theta(img, 3.0)
    }

    fn st_theta(img: &RgbImage, sigma: f32) -> Vec<f32> {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let l = gray(img);
        // Derivative-of-Gaussian gradients (sigma 1): central differences are direction
        // dependent at hair frequencies (they pull 20 deg stripes of 5 px period to 24 deg).
        let g: Vec<f32> = (-3i32..=3).map(|i| (-(i * i) as f32 / 2.0).exp()).collect();
        let gs: f32 = g.iter().sum();
        let g: Vec<f32> = g.iter().map(|v| v / gs).collect();
        let dg: Vec<f32> = (-3i32..=3)
            .map(|i| -(i as f32) * g[(i + 3) as usize])
            .collect();
        let gx = sep_filter(&l, w, h, &dg, &g);
        let gy = sep_filter(&l, w, h, &g, &dg);
        let (mut jxx, mut jxy, mut jyy) = (vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]);
        for k in 0..w * h {
            jxx[k] = gx[k] * gx[k];
            jxy[k] = gx[k] * gy[k];
            jyy[k] = gy[k] * gy[k];
        }
        let (jxx, jxy, jyy) = (
            gauss_blur(&jxx, w, h, sigma),
            gauss_blur(&jxy, w, h, sigma),
            gauss_blur(&jyy, w, h, sigma),
        );
        (0..w * h)
            .map(|k| {
                let phi = 0.5 * (2.0 * jxy[k]).atan2(jxx[k] - jyy[k]);
                (phi + FRAC_PI_2).rem_euclid(PI)
            })
            .collect()
    }

    #[test]
    fn texture_carries_the_orientation() {
        let mut report = Vec::new();
        let mut worst = 0.0f64;
        for style in Style::ALL {
            for seed in 1..=3 {
                let c = case(style, seed);
                let est = structure_tensor_theta(&c.image);
                let inner = mask_interior(&c.mask, 8.0);
                let (mut sum, mut n, mut big) = (0.0f64, 0usize, 0usize);
                for k in 0..est.len() {
                    if inner[k] {
                        let e = orientation_error_deg(est[k], c.gt_theta[k]);
                        sum += e as f64;
                        n += 1;
                        if e > 10.0 {
                            big += 1;
                        }
                    }
                }
                let mean = sum / n as f64;
                // For reference only: the orientation stage is judged from 5 px inside.
                let inner5 = mask_interior(&c.mask, 5.0);
                let (s5, n5) =
                    (0..est.len())
                        .filter(|&k| inner5[k])
                        .fold((0.0f64, 0usize), |a, k| {
                            (
                                a.0 + orientation_error_deg(est[k], c.gt_theta[k]) as f64,
                                a.1 + 1,
                            )
                        });
                report.push(format!(
                    "{style:>8} seed {seed}: mean {mean:.2} deg over {n} px, {:.2}% over 10 deg \
                     (from 5 px inside: {:.2} deg)",
                    100.0 * big as f64 / n as f64,
                    s5 / n5 as f64
                ));
                assert!(n > 2000, "{style} seed {seed}: only {n} interior pixels");
                worst = worst.max(mean);
            }
        }
        println!(
            "structure tensor (sigma 3) vs ground truth:\n{}",
            report.join("\n")
        );
        assert!(worst < 4.0, "mean error up to {worst:.2} deg");
    }

    #[test]
    fn fringe_has_a_seam_with_a_large_jump() {
        assert_eq!("fringe".parse::<Style>().unwrap(), Style::Fringe);
        assert!(!Style::ALL.contains(&Style::Fringe) && !Style::Fringe.has_3d());
        for seed in 1..=3 {
            let p = SynthParams::new(Style::Fringe, seed);
            let c = synth(&p);
            let sm = seam(&p).expect("the fringe has a seam");
            let (w, h) = (c.width as usize, c.height as usize);
            let hair: Vec<bool> = c.mask.as_raw().iter().map(|&v| v > 127).collect();
            assert_eq!(components(&c), 1, "seed {seed}: mask not connected");
            for name in crate::io::annot::REQUIRED_LANDMARKS {
                let q = c.landmarks.get(name).unwrap();
                assert!(!c.is_hair(q[0] as u32, q[1] as u32), "{name} on hair");
            }
            c.strokes.validate(Some((c.width, c.height))).unwrap();
            let (mut pairs, mut least) = (0usize, f32::INFINITY);
            for y in 0..h {
                for x in 0..w {
                    let k = y * w + x;
                    for j in [(x + 1 < w).then(|| k + 1), (y + 1 < h).then(|| k + w)]
                        .into_iter()
                        .flatten()
                    {
                        if hair[k] && hair[j] && sm.fringe[k] != sm.fringe[j] {
                            pairs += 1;
                            least = least.min(orientation_error_deg(c.gt_theta[k], c.gt_theta[j]));
                        }
                    }
                }
            }
            let n_hair = hair.iter().filter(|&&b| b).count();
            let n_fringe = sm.fringe.iter().filter(|&&b| b).count();
            let n_on = sm.on.iter().filter(|&&b| b).count();
            println!(
                "fringe seed {seed}: hair {:.1}% of the image, fringe {:.1}% of the hair, \
                 {n_on} seam px, {pairs} pairs across it, least jump {least:.1} deg",
                100.0 * n_hair as f64 / (w * h) as f64,
                100.0 * n_fringe as f64 / n_hair as f64
            );
            assert!(least >= 45.0, "seed {seed}: jump only {least} deg");
            assert!(pairs >= 200, "seed {seed}: seam only {pairs} pairs long");
            assert!((0.1..0.5).contains(&(n_fringe as f64 / n_hair as f64)));
            for ((d, on), hair) in sm.distance.iter().zip(&sm.on).zip(&hair) {
                assert_eq!(d.is_nan(), !hair);
                assert_eq!(*d == 0.0, *on);
            }
        }
        assert!(seam(&SynthParams::new(Style::Long, 1)).is_none());
    }

    #[test]
    fn distance_to_matches_brute_force() {
        let (w, h) = (23, 17);
        let mut set = vec![false; w * h];
        for (x, y) in [(3, 4), (20, 1), (11, 15), (12, 15)] {
            set[y * w + x] = true;
        }
        let d = distance_to(&set, w, h);
        for y in 0..h {
            for x in 0..w {
                let want = (0..w * h)
                    .filter(|&j| set[j])
                    .map(|j| ((j % w) as f32 - x as f32).hypot((j / w) as f32 - y as f32))
                    .fold(f32::INFINITY, f32::min);
                assert!((d[y * w + x] - want).abs() < 1e-4, "({x}, {y})");
            }
        }
        assert!(distance_to(&[false; 6], 3, 2)
            .iter()
            .all(|v| v.is_infinite()));
    }

    #[test]
    fn interior_and_error_helpers() {
        let mut m = GrayImage::new(20, 20);
        for y in 2..18 {
            for x in 2..18 {
                m.put_pixel(x, y, image::Luma([255]));
            }
        }
        let inner = mask_interior(&m, 3.0);
        assert!(inner[10 * 20 + 10]);
        assert!(inner[10 * 20 + 4]); // 3 px from the first non-hair column (x = 1)
        assert!(!inner[10 * 20 + 3]);
        assert!(!inner[10 * 20 + 1]);
        assert!(
            (orientation_error_deg(0.01, PI - 0.01) - 2f32 * 0.01f32.to_degrees()).abs() < 1e-3
        );
        assert!((orientation_error_deg(0.0, FRAC_PI_2) - 90.0).abs() < 1e-4);
    }

    #[test]
    fn write_produces_readable_files() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("case");
        let p = SynthParams {
            style: Style::Whorl,
            seed: 2,
            width: 200,
            height: 160,
        };
        let c = synth(&p);
        c.write(&out).unwrap();
        let img = image::open(out.join("image.png")).unwrap().to_rgb8();
        assert_eq!(img.as_raw(), c.image.as_raw());
        let mask = image::open(out.join("mask.png")).unwrap().to_luma8();
        assert_eq!(mask.as_raw(), c.mask.as_raw());
        let (shape, t) = crate::io::npy::read_f32(&out.join("gt_theta.npy")).unwrap();
        assert_eq!(shape, vec![160, 200]);
        assert_eq!(
            t.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            c.gt_theta.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        let (shape, d) = crate::io::npy::read_f32(&out.join("gt_dir.npy")).unwrap();
        assert_eq!(shape, vec![160, 200, 2]);
        assert_eq!(d.len(), c.gt_dir.len());
        let s = Strokes::load(&out.join("strokes.json"), Some((200, 160))).unwrap();
        assert_eq!(s, c.strokes);
        let l = Landmarks::load(&out.join("landmarks.json"), Some((200, 160))).unwrap();
        assert_eq!(l, c.landmarks);
    }

    #[test]
    fn small_and_odd_sizes_work() {
        for (w, h) in [(64, 64), (300, 200), (256, 384)] {
            for style in Style::ALL {
                let c = synth(&SynthParams {
                    style,
                    seed: 3,
                    width: w,
                    height: h,
                });
                assert_eq!(c.image.dimensions(), (w, h));
                assert!(hair_fraction(&c) > 0.02, "{style} {w}x{h}");
                c.strokes.validate(Some((w, h))).unwrap();
                c.landmarks.validate(Some((w, h))).unwrap();
            }
        }
    }

    #[test]
    fn fast_enough() {
        for style in Style::ALL {
            let t = std::time::Instant::now();
            let _ = case(style, 1);
            let dt = t.elapsed().as_secs_f64();
            println!("{style}: 512x512 in {:.0} ms", dt * 1e3);
            // Generous: the point is to catch accidental quadratic behaviour.
            assert!(dt < 3.0, "{style}: {dt} s");
        }
    }
}
