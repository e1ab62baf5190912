//! Hair segmentation from user strokes (C13 §2.1 segments the hair with Paint Selection
//! [Liu et al. 2009]; this is the GrabCut-style variant of that idea).
//!
//! Colour models are RGB Gaussian mixtures (full covariance): hair from the pixels under the
//! `direction` strokes, background from the `background` strokes, the image border and a
//! sparse sample of all unmarked pixels. A binary graph cut on the 8-connected pixel grid
//! (edge-aware GrabCut smoothness, stroke pixels hard-constrained, Boykov-Kolmogorov
//! max-flow) gives the labelling; the mixtures are re-fitted to it for a few rounds, and the
//! final mask is cleaned of small holes and stray islands.
//!
//! Everything is deterministic: sampling uses a fixed-seed [`Rng`], parallel work is
//! per-pixel and reductions run sequentially.

mod agree;
mod flow;
mod geodesic;
mod gmm;
mod strokes;
mod texture;

use crate::base::rng::Rng;
use crate::error::{Error, Result};
use crate::io::annot::{StrokeKind, Strokes};
use flow::{smoothness_weights, GridFlow};
use gmm::{data_terms, Gmm};
use image::{GrayImage, RgbImage};
pub use strokes::brush_pixels;
use strokes::off_model_strokes;
#[cfg(test)]
use strokes::raster_stroke;
use texture::{bin_nll, luminance, texture_bins};

/// Tuning of [`segment`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SegmentParams {
    /// Pixels whose centre lies within this distance (px) of a stroke are sure hair
    /// (direction strokes) or sure background (background strokes).
    pub brush_radius: f32,
    /// Width (px) of the image border sampled for the background colour model (with any
    /// background strokes and a sparse sample of the whole image). The border is only a
    /// colour sample, not a constraint, so hair touching the image edge can still be hair.
    pub border: u32,
    /// Gaussian components per colour model.
    pub components: usize,
    /// GrabCut-style rounds of re-fitting the colour models to the labelling; the graph is
    /// cut `iterations + 1` times.
    pub iterations: usize,
    /// Smoothness weight gamma (GrabCut uses 50).
    pub smoothness: f32,
    /// Weight of a colour step's luminance against its chroma in the smoothness's contrast
    /// (1 is GrabCut's RGB distance). Below 1 the cut is drawn to edges of colour more than
    /// to edges of shading, so it leaves the shadowed side of a lock with the lit side
    /// (see `flow::smoothness_weights`).
    pub luminance: f32,
    /// Hair islands touching no direction stroke and smaller than this (px) are dropped.
    pub min_island: u32,
    /// Enclosed non-hair regions smaller than this (px) and free of background strokes are
    /// filled.
    pub max_hole: u32,
    /// Weight of the strand-texture data term (see `texture.rs`) against the colour term;
    /// 0 segments by colour alone.
    pub texture: f32,
    /// Weight (nats) of the geodesic term (see `geodesic.rs`): with background strokes, a
    /// pixel nearer (in colour-weighted path length) to a background stroke than to a
    /// direction stroke leans to background, by up to this much. 0 turns it off.
    pub geodesic: f32,
    /// Weight of the term for agreement with the strokes' flow (see `agree.rs`): a pixel
    /// whose local orientation runs across the direction strokes near it leans to
    /// background, by up to this many times the log-ratio of the two learned histograms
    /// (never toward hair); 0 turns it off.
    pub agreement: f32,
    /// Pixels of a direction stroke that seems to lie off the hair (see
    /// [`off_model_strokes`]: over half its brush likelier background than hair) are left
    /// to the models instead of being sure hair, and kept out of the hair model's first fit.
    /// False keeps every stroke pixel sure hair, so a stroke drawn along the backdrop puts
    /// its strip into the mask (the behaviour before 2026-12-06). A stroke marked `sure` is
    /// never released.
    pub release_off_hair: bool,
}

impl Default for SegmentParams {
    fn default() -> Self {
        SegmentParams {
            brush_radius: 4.0,
            border: 3,
            components: 5,
            iterations: 4,
            smoothness: 50.0,
            luminance: 0.5,
            min_island: 2000,
            max_hole: 500,
            texture: 1.0,
            geodesic: 3.0,
            agreement: 3.0,
            release_off_hair: true,
        }
    }
}

impl SegmentParams {
    fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("segmentation parameters: {m}")));
        if !(self.brush_radius.is_finite() && self.brush_radius >= 0.0) {
            return bad(format!(
                "brush_radius must be a finite number >= 0, got {}",
                self.brush_radius
            ));
        }
        if !(self.smoothness.is_finite() && self.smoothness >= 0.0) {
            return bad(format!(
                "smoothness must be a finite number >= 0, got {}",
                self.smoothness
            ));
        }
        if !(self.luminance.is_finite() && self.luminance >= 0.0) {
            return bad(format!(
                "luminance must be a finite number >= 0, got {}",
                self.luminance
            ));
        }
        if !(self.geodesic.is_finite() && self.geodesic >= 0.0) {
            return bad(format!(
                "geodesic must be a finite number >= 0, got {}",
                self.geodesic
            ));
        }
        if !(self.texture.is_finite() && self.texture >= 0.0) {
            return bad(format!(
                "texture must be a finite number >= 0, got {}",
                self.texture
            ));
        }
        if !(self.agreement.is_finite() && self.agreement >= 0.0) {
            return bad(format!(
                "agreement must be a finite number >= 0, got {}",
                self.agreement
            ));
        }
        if self.components == 0 || self.components > 64 {
            return bad(format!(
                "components must be in 1..=64, got {}",
                self.components
            ));
        }
        Ok(())
    }
}

/// Per-pixel seed label.
const FREE: u8 = 0;
const HAIR: u8 = 1;
const BACK: u8 = 2;

/// Segments the hair of `image` from the user's strokes: 255 = hair, 0 = not hair.
///
/// Needs at least one `direction` stroke touching the image. `comb` and `cut` strokes are
/// ignored. Where strokes of different kinds overlap, the later stroke wins. Warnings (see
/// [`segment_with_warnings`]) go to the log.
pub fn segment(image: &RgbImage, strokes: &Strokes, p: &SegmentParams) -> Result<GrayImage> {
    let (mask, warnings) = segment_with_warnings(image, strokes, p)?;
    for w in warnings {
        log::warn!("{w}");
    }
    Ok(mask)
}

/// [`segment`], with its warnings returned for a caller that records them (`coif analyze`
/// writes them into `analyze.json`): direction strokes that seem to lie off the hair.
pub fn segment_with_warnings(
    image: &RgbImage,
    strokes: &Strokes,
    p: &SegmentParams,
) -> Result<(GrayImage, Vec<String>)> {
    run(image, strokes, p, None)
}

/// The same graph cut with every model (colour mixtures, texture and flow-agreement
/// histograms) fitted to `mask` (255 = hair) and kept fixed, cut once. Given the true hair
/// mask it is an oracle: what these models can do at best when nothing about them is left
/// to estimate (`segment_real::…ceiling…` measures it on the real portraits).
pub fn segment_with_models_from(
    image: &RgbImage,
    strokes: &Strokes,
    p: &SegmentParams,
    mask: &GrayImage,
) -> Result<GrayImage> {
    if mask.dimensions() != image.dimensions() {
        return Err(Error::Invalid(format!(
            "the mask to fit the models to is {}x{}, the image {}x{}",
            mask.width(),
            mask.height(),
            image.width(),
            image.height()
        )));
    }
    let hair = mask.as_raw().iter().filter(|&&v| v > 127).count();
    if hair == 0 || hair == mask.as_raw().len() {
        return Err(Error::Invalid(
            "the mask to fit the models to needs both hair and other pixels".into(),
        ));
    }
    Ok(run(image, strokes, p, Some(mask))?.0)
}

fn run(
    image: &RgbImage,
    strokes: &Strokes,
    p: &SegmentParams,
    fit_to: Option<&GrayImage>,
) -> Result<(GrayImage, Vec<String>)> {
    p.validate()?;
    let (w, h) = image.dimensions();
    if w == 0 || h == 0 {
        return Err(Error::Invalid(format!(
            "cannot segment an empty {w}x{h} image"
        )));
    }
    strokes
        .validate(None)
        .map_err(|m| Error::Invalid(format!("strokes: {m}")))?;
    if !strokes
        .strokes
        .iter()
        .any(|s| s.kind == StrokeKind::Direction)
    {
        return Err(Error::Invalid(
            "hair segmentation needs at least one direction stroke on the hair \
             (there are none)"
                .into(),
        ));
    }

    let (wu, hu) = (w as usize, h as usize);
    let n = wu * hu;
    // Seeds, and for each direction-stroke pixel the index of its stroke (for the warning).
    let mut seed = vec![FREE; n];
    let mut owner = vec![u32::MAX; n];
    for (si, s) in strokes.strokes.iter().enumerate() {
        let lab = match s.kind {
            StrokeKind::Direction => HAIR,
            StrokeKind::Background => BACK,
            StrokeKind::Comb | StrokeKind::Cut => continue,
        };
        for i in brush_pixels(s, p.brush_radius, w, h) {
            seed[i] = lab;
            owner[i] = if lab == HAIR { si as u32 } else { u32::MAX };
        }
    }
    if !seed.contains(&HAIR) {
        return Err(Error::Invalid(format!(
            "no direction stroke touches the {w}x{h} image (all lie outside it)"
        )));
    }

    let rgb: Vec<[f32; 3]> = image
        .pixels()
        .map(|q| [q[0] as f32, q[1] as f32, q[2] as f32])
        .collect();

    // Initial background samples: pixels under background strokes, the image border, and a
    // sparse sample of every pixel not marked as hair (Paint Selection's background model).
    // The global sample matters: a border-only model leaves regions such as the face in
    // neither model, the first cut gives them to whichever is less wrong (often the hair),
    // and re-estimation then locks that in. Hair pixels in the global sample are a minority
    // that the concentrated hair model still outweighs. Background strokes add to this
    // rather than replace it, so that one stroke on a hair-coloured object does not leave
    // the rest of the background unmodelled.
    let b = p.border as usize;
    let marked: Vec<usize> = (0..n).filter(|&i| seed[i] == BACK).collect();
    let border: Vec<usize> = (0..n)
        .filter(|&i| {
            let (x, y) = (i % wu, i / wu);
            seed[i] == FREE && (x < b || y < b || x + b >= wu || y + b >= hu)
        })
        .collect();
    let back_init: Vec<usize> = if marked.is_empty() && border.is_empty() {
        Vec::new()
    } else {
        // As many global samples as border or stroke pixels, on a fixed stride.
        let stride = (n / border.len().max(marked.len())).max(1);
        let global = (0..n).step_by(stride).filter(|&i| seed[i] == FREE);
        marked
            .iter()
            .chain(&border)
            .copied()
            .chain(global)
            .collect()
    };
    if back_init.is_empty() {
        return Err(Error::Invalid(if p.border == 0 {
            "no background colour samples: draw a background stroke or use a border > 0".into()
        } else {
            "no background colour samples: the direction strokes cover the whole image; \
             draw a background stroke"
                .into()
        }));
    }
    let mut hair_init: Vec<usize> = (0..n).filter(|&i| seed[i] == HAIR).collect();

    let mut rng = Rng::new(0x5e6_0001);
    let mut fg = Gmm::fit(&sample(&rgb, &hair_init, &mut rng), p.components, &mut rng);
    // The background is many materials (backdrop, skin, eyes, clothes) against the hair's
    // one, so it gets twice the components; with as many as the hair, skin shares a broad
    // component with clothes and loses to the hair's mid-tones on brown hair.
    let mut bg = Gmm::fit(
        &sample(&rgb, &back_init, &mut rng),
        2 * p.components,
        &mut rng,
    );
    // Strokes that seem to lie off the hair, judged before any cut (by the background
    // samples and the other strokes), so that their off-hair pixels neither seed the hair
    // model nor are forced into the mask. A user's stroke 3-12 px out on the backdrop
    // otherwise brings a strip of backdrop along (the embedded astronaut's stroke 4 did).
    let off = off_model_strokes(&rgb, &owner, strokes, wu, &bg, p.components);
    let released: Vec<usize> = off.iter().flat_map(|o| o.pixels.iter().copied()).collect();
    // Never all of them: a mask needs some sure hair to grow from.
    let release = p.release_off_hair && !released.is_empty() && hair_init.len() > released.len();
    if release {
        for &i in &released {
            seed[i] = FREE;
        }
        hair_init = (0..n).filter(|&i| seed[i] == HAIR).collect();
        fg = Gmm::fit(&sample(&rgb, &hair_init, &mut rng), p.components, &mut rng);
    }

    let (lum, lum_mean) = luminance(&rgb, wu, hu);
    let tex = texture_bins(&lum, &lum_mean, wu, hu);
    let mut tex_fg: [f32; texture::BINS] = bin_nll(&tex, &hair_init);
    let mut tex_bg: [f32; texture::BINS] = bin_nll(&tex, &back_init);
    let agr = if p.agreement > 0.0 {
        agree::agreement_bins(&lum_mean, strokes, wu, hu)
    } else {
        vec![0; n]
    };
    let mut agr_fg: [f32; agree::BINS] = bin_nll(&agr, &hair_init);
    let mut agr_bg: [f32; agree::BINS] = bin_nll(&agr, &back_init);

    // Only background strokes say where the background is; the border is no such evidence.
    let geo: Vec<f32> = if p.geodesic > 0.0 && !marked.is_empty() {
        let to_hair = geodesic::geodesic(
            &rgb,
            wu,
            hu,
            &seed.iter().map(|&s| s == HAIR).collect::<Vec<_>>(),
        );
        let to_back = geodesic::geodesic(
            &rgb,
            wu,
            hu,
            &seed.iter().map(|&s| s == BACK).collect::<Vec<_>>(),
        );
        to_hair
            .iter()
            .zip(&to_back)
            .map(|(&f, &b)| -p.geodesic * ((f - b) / (f + b + 1.0)).max(0.0))
            .collect()
    } else {
        vec![0.0; n]
    };

    if let Some(m) = fit_to {
        let (hair_px, back_px): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| m.as_raw()[i] > 127);
        fg = Gmm::fit(&sample(&rgb, &hair_px, &mut rng), p.components, &mut rng);
        bg = Gmm::fit(
            &sample(&rgb, &back_px, &mut rng),
            2 * p.components,
            &mut rng,
        );
        (tex_fg, tex_bg) = (bin_nll(&tex, &hair_px), bin_nll(&tex, &back_px));
        (agr_fg, agr_bg) = (bin_nll(&agr, &hair_px), bin_nll(&agr, &back_px));
    }
    let smooth = smoothness_weights(&rgb, wu, hu, p.smoothness, p.luminance);
    let mut flow = GridFlow::new(wu, hu);
    let mut label = vec![false; n];
    // Models fitted to a given mask stay as they are: one cut.
    let rounds = if fit_to.is_some() { 0 } else { p.iterations };
    for round in 0..=rounds {
        if round > 0 {
            // Re-fit to the labelling, warm-starting from the current mixtures.
            let hair_px: Vec<usize> = (0..n).filter(|&i| label[i]).collect();
            let back_px: Vec<usize> = (0..n).filter(|&i| !label[i]).collect();
            if !hair_px.is_empty() {
                fg.refine(&sample(&rgb, &hair_px, &mut rng));
                tex_fg = bin_nll(&tex, &hair_px);
                agr_fg = bin_nll(&agr, &hair_px);
            }
            if !back_px.is_empty() {
                bg.refine(&sample(&rgb, &back_px, &mut rng));
                tex_bg = bin_nll(&tex, &back_px);
                agr_bg = bin_nll(&agr, &back_px);
            }
        }
        let (dfg, dbg) = data_terms(&rgb, &fg, &bg);
        flow.reset(&smooth, |i| match seed[i] {
            HAIR => f32::INFINITY,
            BACK => f32::NEG_INFINITY,
            // Source = hair: the source link is paid when the pixel ends up background.
            _ => {
                let (t, a) = (tex[i] as usize, agr[i] as usize);
                dbg[i] - dfg[i]
                    + p.texture * (tex_bg[t] - tex_fg[t])
                    // One-sided: only evidence against hair (see `agree.rs`).
                    + p.agreement * (agr_bg[a] - agr_fg[a]).min(0.0)
                    + geo[i]
            }
        });
        flow.max_flow();
        let new: Vec<bool> = (0..n).map(|i| flow.is_source(i)).collect();
        let changed = new.iter().zip(&label).filter(|(a, b)| a != b).count();
        label = new;
        // Converged: fewer than 0.1% of the pixels moved.
        if round > 0 && changed * 1000 < n {
            break;
        }
    }

    let mut warnings = Vec::new();
    for o in off {
        let [x0, y0, x1, y1] = o.bbox;
        // Numbered among the direction strokes, as `analyze`'s own stroke warnings are.
        let k = strokes.strokes[..o.stroke]
            .iter()
            .filter(|s| s.kind == StrokeKind::Direction)
            .count();
        // Released, the stroke may also be a correction on hair no other stroke shows: say
        // how to keep it as drawn.
        let fate = if release {
            "those pixels were left to the colour models instead of being taken as hair: draw \
             it on the hair, or, if it is on hair no other stroke shows, mark it \"sure\": true \
             in the strokes file"
        } else {
            "stroke pixels are always hair here, so that strip is in the mask: draw it on the \
             hair"
        };
        warnings.push(format!(
            "direction stroke {}: {} of its {} pixels (within x {x0}-{x1}, y {y0}-{y1}) look \
             like background to the colour models (hair model from the other direction \
             strokes); {fate}",
            k, o.off, o.total
        ));
    }
    clean(&mut label, &seed, wu, hu, p.min_island, p.max_hole);
    check_share(&label, &seed, w, h)?;
    let data = label.iter().map(|&l| if l { 255 } else { 0 }).collect();
    Ok((
        GrayImage::from_raw(w, h, data).expect("w*h buffer"),
        warnings,
    ))
}

/// Above this share of the image as hair, the segmentation has found no edge between hair
/// and the rest: a portrait's hair with its face, neck and some backdrop cannot fill 98%.
pub const MAX_HAIR_SHARE: f64 = 0.98;

/// Refuses a segmentation that marks (almost) everything as hair, or nothing beyond the
/// pixels under the direction strokes: either way the colours did not tell hair apart.
fn check_share(label: &[bool], seed: &[u8], w: u32, h: u32) -> Result<()> {
    let n = label.len();
    let hair = label.iter().filter(|&&l| l).count();
    let share = hair as f64 / n as f64;
    if share > MAX_HAIR_SHARE {
        return Err(Error::Invalid(format!(
            "the segmentation from the strokes marks {:.1}% of the {w}x{h} image as hair \
             (over {}%): the hair does not stand apart from the rest in colour (a \
             solid-colour image?); draw background strokes on what is not hair, or give a mask",
            100.0 * share,
            100.0 * MAX_HAIR_SHARE
        )));
    }
    let beyond = label
        .iter()
        .zip(seed)
        .filter(|(&l, &s)| l && s != HAIR)
        .count();
    if beyond == 0 {
        return Err(Error::Invalid(format!(
            "the segmentation from the strokes marks no hair in the {w}x{h} image beyond the \
             {hair} pixels under the direction strokes themselves: the colours do not tell \
             hair apart; draw the strokes on the hair, or give a mask"
        )));
    }
    Ok(())
}

/// Colour samples for fitting, at most `MAX_SAMPLES` drawn uniformly so that large regions
/// do not make fitting slow.
const MAX_SAMPLES: usize = 20_000;

fn sample(rgb: &[[f32; 3]], idx: &[usize], rng: &mut Rng) -> Vec<[f32; 3]> {
    if idx.len() <= MAX_SAMPLES {
        return idx.iter().map(|&i| rgb[i]).collect();
    }
    (0..MAX_SAMPLES)
        .map(|_| rgb[idx[rng.below(idx.len() as u32) as usize]])
        .collect()
}

// ----------------------------------------------------------------------------------------
// Clean-up

/// Fills enclosed non-hair regions smaller than `max_hole` that hold no background stroke,
/// then drops hair islands smaller than `min_island` that hold no direction stroke. Hair is
/// 8-connected (as in the graph), non-hair 4-connected, so the two never cross.
fn clean(label: &mut [bool], seed: &[u8], w: usize, h: usize, min_island: u32, max_hole: u32) {
    for (target, eight) in [(false, false), (true, true)] {
        let mut flip = Vec::new();
        crate::base::mask::for_each_component(label, w, h, target, eight, |comp, border| {
            let keep_seed = comp
                .iter()
                .any(|&i| seed[i] == if target { HAIR } else { BACK });
            let drop = if target {
                !keep_seed && (comp.len() as u64) < min_island as u64
            } else {
                !keep_seed && !border && (comp.len() as u64) < max_hole as u64
            };
            if drop {
                flip.extend_from_slice(comp);
            }
        });
        for i in flip {
            label[i] = !target;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::annot::Stroke;
    use crate::synth::{synth, Style, SynthParams};

    fn iou(a: &GrayImage, b: &GrayImage) -> f64 {
        let (mut inter, mut uni) = (0u64, 0u64);
        for (p, q) in a.pixels().zip(b.pixels()) {
            let (x, y) = (p[0] > 127, q[0] > 127);
            inter += (x && y) as u64;
            uni += (x || y) as u64;
        }
        inter as f64 / uni.max(1) as f64
    }

    fn direction_only(s: &Strokes) -> Strokes {
        let only: Vec<Stroke> = s
            .strokes
            .iter()
            .filter(|s| s.kind == StrokeKind::Direction)
            .cloned()
            .collect();
        Strokes::new(only)
    }

    fn overlay_path(name: &str) -> Option<std::path::PathBuf> {
        std::env::var_os("COIF_SEGMENT_OUT").map(|d| std::path::Path::new(&d).join(name))
    }

    /// Image with hair where the mask says, red tint on false positives, blue on misses.
    fn save_overlay(img: &RgbImage, got: &GrayImage, truth: Option<&GrayImage>, name: &str) {
        let Some(path) = overlay_path(name) else {
            return;
        };
        let mut out = img.clone();
        for (x, y, px) in out.enumerate_pixels_mut() {
            let g = got.get_pixel(x, y)[0] > 127;
            let t = truth.map(|t| t.get_pixel(x, y)[0] > 127).unwrap_or(g);
            let tint = match (g, t) {
                (true, true) => [0.0, 255.0, 0.0],
                (true, false) => [255.0, 0.0, 0.0],
                (false, true) => [0.0, 0.0, 255.0],
                (false, false) => continue,
            };
            for c in 0..3 {
                px[c] = (px[c] as f32 * 0.55 + tint[c] * 0.45) as u8;
            }
        }
        crate::io::write_png(&path, &out).unwrap();
    }

    #[test]
    fn synthetic_portraits_iou() {
        let p = SegmentParams::default();
        let mut worst = 1.0f64;
        let mut failures = Vec::new();
        for style in Style::ALL {
            for seed in 1..=3 {
                let case = synth(&SynthParams::new(style, seed));
                let strokes = direction_only(&case.strokes);
                assert!(!strokes.strokes.is_empty());
                let t = std::time::Instant::now();
                let mask = segment(&case.image, &strokes, &p).unwrap();
                let ms = t.elapsed().as_secs_f64() * 1e3;
                let v = iou(&mask, &case.mask);
                println!("{style} seed {seed}: IoU {v:.4} ({ms:.0} ms)");
                save_overlay(
                    &case.image,
                    &mask,
                    Some(&case.mask),
                    &format!("{style}_{seed}.png"),
                );
                worst = worst.min(v);
                if v < 0.95 {
                    failures.push(format!("{style}/{seed}: {v:.4}"));
                }
            }
        }
        println!("worst IoU {worst:.4}");
        assert!(failures.is_empty(), "IoU below 0.95: {failures:?}");
    }

    #[test]
    fn explicit_background_strokes() {
        let case = synth(&SynthParams::new(Style::SidePart, 2));
        let mut strokes = direction_only(&case.strokes);
        let (w, h) = (case.width as f32, case.height as f32);
        // Background strokes on the backdrop (top corners), the face and the shirt.
        for pts in [
            vec![[10.0, 10.0], [w * 0.2, 10.0], [10.0, h * 0.3]],
            vec![[w - 10.0, 10.0], [w * 0.8, 10.0], [w - 10.0, h * 0.3]],
            vec![[w * 0.45, h * 0.55], [w * 0.55, h * 0.6]],
            vec![[w * 0.3, h - 10.0], [w * 0.7, h - 10.0]],
        ] {
            strokes
                .strokes
                .push(Stroke::new(StrokeKind::Background, pts));
        }
        // The strokes must actually lie off the hair for the test to mean anything.
        for s in &strokes.strokes[strokes.strokes.len() - 4..] {
            for q in &s.points {
                assert!(!case.is_hair(q[0] as u32, q[1] as u32), "{q:?} is on hair");
            }
        }
        let mask = segment(&case.image, &strokes, &SegmentParams::default()).unwrap();
        let v = iou(&mask, &case.mask);
        println!("sidepart seed 2 with background strokes: IoU {v:.4}");
        save_overlay(&case.image, &mask, Some(&case.mask), "sidepart_2_bg.png");
        assert!(v >= 0.95, "IoU {v:.4}");
        // Pixels under background strokes are never hair.
        for s in &strokes.strokes {
            if s.kind == StrokeKind::Background {
                for q in &s.points {
                    assert_eq!(mask.get_pixel(q[0] as u32, q[1] as u32)[0], 0);
                }
            }
        }
    }

    /// `case`'s image with a disc of radius `r` around `centre` (which must lie off the
    /// hair) copied from the hair around the pixel `src`, turned a quarter turn when
    /// `turned`; and the disc's pixels.
    fn paste_disc(
        case: &crate::synth::SynthCase,
        src: usize,
        centre: (i64, i64),
        r: i64,
        turned: bool,
    ) -> (RgbImage, Vec<(u32, u32)>) {
        let (sx, sy) = ((src % 512) as i64, (src / 512) as i64);
        let (cx, cy) = centre;
        let mut img = case.image.clone();
        let mut disc = Vec::new();
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                if (x - cx).pow(2) + (y - cy).pow(2) <= r * r {
                    assert!(!case.is_hair(x as u32, y as u32), "disc overlaps the hair");
                    let (dx, dy) = if turned {
                        (y - cy, cx - x)
                    } else {
                        (x - cx, y - cy)
                    };
                    let p = *case.image.get_pixel((sx + dx) as u32, (sy + dy) as u32);
                    img.put_pixel(x as u32, y as u32, p);
                    disc.push((x as u32, y as u32));
                }
            }
        }
        (img, disc)
    }

    /// The share of `disc`'s pixels that `m` marks as hair.
    fn hair_share(m: &GrayImage, disc: &[(u32, u32)]) -> f64 {
        disc.iter()
            .filter(|&&(x, y)| m.get_pixel(x, y)[0] > 127)
            .count() as f64
            / disc.len() as f64
    }

    /// A patch of real hair texture pasted onto the backdrop, away from every stroke, is
    /// segmented as hair (it is hair-coloured and large); one background stroke across it
    /// removes it while the true hair stays.
    #[test]
    fn background_stroke_removes_hair_coloured_object() {
        let case = synth(&SynthParams::new(Style::Long, 2));
        let interior = crate::synth::mask_interior(&case.mask, 32.0);
        let src = interior.iter().position(|&b| b).expect("a wide hair area");
        let (img, disc) = paste_disc(&case, src, (60, 60), 30, false);
        let frac = |m: &GrayImage| hair_share(m, &disc);
        let p = SegmentParams::default();
        let mut strokes = direction_only(&case.strokes);
        let without = segment(&img, &strokes, &p).unwrap();
        println!(
            "disc hair fraction without background stroke {:.3}",
            frac(&without)
        );
        assert!(frac(&without) > 0.8, "{}", frac(&without));
        strokes.strokes.push(Stroke::new(
            StrokeKind::Background,
            vec![[40.0, 60.0], [80.0, 60.0]],
        ));
        let with = segment(&img, &strokes, &p).unwrap();
        let v = iou(&with, &case.mask);
        println!(
            "disc hair fraction with background stroke {:.3}, IoU {v:.4}",
            frac(&with)
        );
        save_overlay(&img, &with, Some(&case.mask), "long_2_disc.png");
        assert!(frac(&with) < 0.05, "{}", frac(&with));
        assert!(v >= 0.95, "IoU {v:.4}");
    }

    /// The flow-agreement term's claim: a hair-coloured, strand-textured patch beside the
    /// hair whose strands run across the direction strokes near it goes to background, while
    /// the same patch with its strands along them is not pushed out by the term.
    #[test]
    fn strands_across_the_strokes_lean_to_background() {
        let case = synth(&SynthParams::new(Style::Long, 2));
        let strokes = direction_only(&case.strokes);
        let interior = crate::synth::mask_interior(&case.mask, 32.0);
        // The source: hair beside the left-hand stroke (x ≈ 150, y 228-359), which runs
        // down; the disc: on the backdrop left of the hair, level with it.
        let src = (0..512 * 512)
            .filter(|&i| interior[i])
            .min_by_key(|&i| ((i % 512) as i64 - 150).pow(2) + ((i / 512) as i64 - 300).pow(2))
            .expect("a wide hair area");
        for across in [false, true] {
            let (img, disc) = paste_disc(&case, src, (38, 300), 26, across);
            for a in [0.0, 3.0] {
                let p = SegmentParams {
                    agreement: a,
                    ..SegmentParams::default()
                };
                let m = segment(&img, &strokes, &p).unwrap();
                let f = hair_share(&m, &disc);
                let v = iou(&m, &case.mask);
                println!(
                    "strands {}, agreement {a}: disc hair fraction {f:.3}, IoU with the true \
                     mask {v:.4}",
                    if across { "across" } else { "along" }
                );
                if across && a > 0.0 {
                    save_overlay(&img, &m, Some(&case.mask), "long_2_across.png");
                    assert!(f < 0.05, "the disc across the strokes stays hair: {f:.3}");
                    assert!(v >= 0.95, "IoU {v:.4}");
                } else {
                    // Colour and texture say hair, and the term does not argue.
                    assert!(f > 0.8, "across {across}, agreement {a}: {f:.3}");
                }
            }
        }
    }

    #[test]
    fn deterministic() {
        let case = synth(&SynthParams::new(Style::Whorl, 3));
        let s = direction_only(&case.strokes);
        let p = SegmentParams::default();
        let a = segment(&case.image, &s, &p).unwrap();
        let b = segment(&case.image, &s, &p).unwrap();
        assert!(a.as_raw() == b.as_raw(), "two runs differ");
    }

    fn two_tone() -> RgbImage {
        // Left half dark "hair", right half light "background".
        RgbImage::from_fn(64, 48, |x, _| {
            if x < 32 {
                image::Rgb([40, 25, 10])
            } else {
                image::Rgb([180, 200, 220])
            }
        })
    }

    #[test]
    fn two_tone_image_splits_at_the_edge() {
        let img = two_tone();
        let s = Strokes::new(vec![Stroke::new(
            StrokeKind::Direction,
            vec![[16.0, 10.0], [16.0, 38.0]],
        )]);
        let m = segment(&img, &s, &SegmentParams::default()).unwrap();
        for (x, _, v) in m.enumerate_pixels() {
            assert_eq!(v[0] == 255, x < 32, "pixel column {x}");
        }
    }

    #[test]
    fn errors_are_clear() {
        let img = two_tone();
        let p = SegmentParams::default();
        let bg_only = Strokes::new(vec![Stroke::new(
            StrokeKind::Background,
            vec![[40.0, 10.0], [50.0, 30.0]],
        )]);
        let e = segment(&img, &bg_only, &p).unwrap_err().to_string();
        assert!(e.contains("at least one direction stroke"), "{e}");
        let off = Strokes::new(vec![Stroke::new(
            StrokeKind::Direction,
            vec![[500.0, 500.0], [600.0, 600.0]],
        )]);
        let e = segment(&img, &off, &p).unwrap_err().to_string();
        assert!(e.contains("outside"), "{e}");
        let dir = Strokes::new(vec![Stroke::new(
            StrokeKind::Direction,
            vec![[16.0, 10.0], [16.0, 38.0]],
        )]);
        let e = segment(&img, &dir, &SegmentParams { border: 0, ..p })
            .unwrap_err()
            .to_string();
        assert!(e.contains("no background colour samples"), "{e}");
        let e = segment(&img, &dir, &SegmentParams { components: 0, ..p })
            .unwrap_err()
            .to_string();
        assert!(e.contains("components"), "{e}");
        let nan = Strokes::new(vec![Stroke::new(
            StrokeKind::Direction,
            vec![[f32::NAN, 10.0], [16.0, 38.0]],
        )]);
        let e = segment(&img, &nan, &p).unwrap_err().to_string();
        assert!(e.contains("not finite"), "{e}");
    }

    /// A direction stroke drawn on the background is allowed and reported (strokes on the
    /// hair are not); its off-hair pixels are left to the models, or stay hair when asked.
    #[test]
    fn off_model_stroke_is_allowed_and_reported() {
        let img = two_tone();
        let line =
            |x: f32, y0: f32, y1: f32| Stroke::new(StrokeKind::Direction, vec![[x, y0], [x, y1]]);
        let s = Strokes::new(vec![
            line(10.0, 8.0, 20.0),
            line(20.0, 26.0, 40.0),
            line(50.0, 20.0, 26.0),
        ]);
        // With hair strokes on both colours and nothing marked background, all of the image
        // would be hair, which `segment` refuses: a background stroke keeps part of it out.
        let mut with_bg = s.clone();
        with_bg.strokes.push(Stroke::new(
            StrokeKind::Background,
            vec![[60.0, 4.0], [60.0, 44.0]],
        ));
        let m = segment(&img, &with_bg, &SegmentParams::default()).unwrap();
        assert_eq!(
            m.get_pixel(50, 22)[0],
            0,
            "the off-hair stroke's pixels are released"
        );
        let kept = SegmentParams {
            release_off_hair: false,
            ..SegmentParams::default()
        };
        let m_kept = segment(&img, &with_bg, &kept).unwrap();
        assert_eq!(
            m_kept.get_pixel(50, 22)[0],
            255,
            "stroke pixels are hard hair"
        );
        let (_, said_kept) = segment_with_warnings(&img, &with_bg, &kept).unwrap();
        assert!(said_kept[0].contains("always hair"), "{said_kept:?}");
        // The warning numbers the stroke among the direction strokes, whatever comes before.
        let mut bg_first = with_bg.clone();
        bg_first.strokes.rotate_right(1);
        let (_, said) = segment_with_warnings(&img, &bg_first, &SegmentParams::default()).unwrap();
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].starts_with("direction stroke 2: "), "{said:?}");
        assert!(said[0].contains("left to the colour models"), "{said:?}");
        assert_eq!(m.get_pixel(16, 20)[0], 255);

        // Marked sure (a correction on hair no other stroke shows), the same stroke is taken
        // as drawn, with no warning.
        let mut sure = with_bg.clone();
        sure.strokes[2].sure = true;
        let (m_sure, said) = segment_with_warnings(&img, &sure, &SegmentParams::default()).unwrap();
        assert!(said.is_empty(), "{said:?}");
        assert_eq!(m_sure.get_pixel(50, 22)[0], 255, "a sure stroke is hair");

        let mut owner = vec![u32::MAX; 64 * 48];
        for (si, st) in s.strokes.iter().enumerate() {
            raster_stroke(&st.points, 4.0, 64, 48, |i| owner[i] = si as u32);
        }
        let rgb: Vec<[f32; 3]> = img
            .pixels()
            .map(|q| [q[0] as f32, q[1] as f32, q[2] as f32])
            .collect();
        let right: Vec<[f32; 3]> = (0..64 * 48)
            .filter(|i| i % 64 >= 32)
            .map(|i| rgb[i])
            .collect();
        let bg = Gmm::fit(&right, 2, &mut Rng::new(1));
        let flagged = off_model_strokes(&rgb, &owner, &s, 64, &bg, 3);
        assert_eq!(flagged.len(), 1, "{flagged:?}");
        assert_eq!(flagged[0].stroke, 2);

        // Strokes along the edge: the one mostly over the background is reported, with the
        // bounds of the part that is; the one mostly on the hair is not.
        let edge = Strokes::new(vec![
            line(10.0, 8.0, 20.0),
            line(20.0, 26.0, 40.0),
            line(33.5, 30.0, 44.0),
            line(29.0, 4.0, 16.0),
        ]);
        let mut owner = vec![u32::MAX; 64 * 48];
        for (si, st) in edge.strokes.iter().enumerate() {
            raster_stroke(&st.points, 4.0, 64, 48, |i| owner[i] = si as u32);
        }
        let flagged = off_model_strokes(&rgb, &owner, &edge, 64, &bg, 3);
        assert_eq!(flagged.len(), 1, "{flagged:?}");
        let o = &flagged[0];
        assert_eq!(o.stroke, 2);
        assert!(o.off * 2 > o.total && o.off < o.total, "{o:?}");
        assert_eq!(o.bbox[0], 32, "{o:?}");
        assert!(o.bbox[1] >= 26 && o.bbox[3] <= 47, "{o:?}");
    }

    /// A stroke's own radius, where it has one, sets its brush: a thin background stroke
    /// across the hair takes a thin strip out of it, the default brush a wider one.
    #[test]
    fn a_strokes_radius_sets_its_brush() {
        let img = two_tone();
        let dir = Stroke::new(StrokeKind::Direction, vec![[16.0, 6.0], [16.0, 42.0]]);
        let mut across = Stroke::new(StrokeKind::Background, vec![[2.0, 24.0], [30.0, 24.0]]);
        let bg = Stroke::new(StrokeKind::Background, vec![[56.0, 4.0], [56.0, 44.0]]);
        let p = SegmentParams::default();
        let hair_in_row =
            |m: &GrayImage, y: u32| (0..32).filter(|&x| m.get_pixel(x, y)[0] > 0).count();
        let mut thin = across.clone();
        thin.radius = Some(1.0);
        across.radius = None;
        let wide = segment(
            &img,
            &Strokes::new(vec![dir.clone(), across, bg.clone()]),
            &p,
        )
        .unwrap();
        let thin_m = segment(&img, &Strokes::new(vec![dir, thin.clone(), bg]), &p).unwrap();
        // Rows 3 px from the stroke: outside a 1 px brush, inside the default 4 px one
        // (the direction stroke's own pixels stay hair where the two cross).
        for y in [21, 27] {
            assert_eq!(hair_in_row(&wide, y), 0, "row {y}, default brush");
            assert!(hair_in_row(&thin_m, y) > 20, "row {y}, 1 px brush");
        }
        // Centres within 1 px of y = 24 from x = 2 to 30: rows 23 and 24, columns 1-30.
        assert_eq!(brush_pixels(&thin, 4.0, 64, 48).len(), 60);
        thin.radius = None;
        assert!(brush_pixels(&thin, 4.0, 64, 48).len() > 4 * 60);
    }

    #[test]
    fn clean_fills_holes_and_drops_islands() {
        let (w, h) = (20usize, 20usize);
        let mut label = vec![false; w * h];
        let mut seed = vec![FREE; w * h];
        // Hair block with a 2x2 hole, a hair seed inside it, and a lone 3x3 island.
        for y in 2..12 {
            for x in 2..12 {
                label[y * w + x] = !(6..8).contains(&x) || !(6..8).contains(&y);
            }
        }
        seed[3 * w + 3] = HAIR;
        for y in 15..18 {
            for x in 15..18 {
                label[y * w + x] = true;
            }
        }
        clean(&mut label, &seed, w, h, 10, 10);
        assert!(label[6 * w + 6] && label[7 * w + 7], "hole filled");
        assert!(!label[16 * w + 16], "island dropped");
        // A hole marked by a background stroke stays open.
        let mut label2 = vec![false; w * h];
        for y in 2..12 {
            for x in 2..12 {
                label2[y * w + x] = !(6..8).contains(&x) || !(6..8).contains(&y);
            }
        }
        seed[6 * w + 6] = BACK;
        clean(&mut label2, &seed, w, h, 10, 10);
        assert!(!label2[6 * w + 6]);
    }
}
