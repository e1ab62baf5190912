//! Memory estimates of the jobs whose inputs or options size large allocations, checked
//! against the engine's budget before a job reads its inputs or writes anything. Each figure
//! is derived from the structures that hold the data and was checked against measured peaks
//! (README, "Memory").

use super::{AnalyzeJob, Job, ModelJob, OrientJob, SketchJob};
use crate::analyze::orient::{self, OrientParams};
use crate::base::budget::{Bytes, Cause};
use crate::gpu::engine::Engine;
use crate::model::ModelParams;
use std::path::Path;

/// What any run holds before its data: the binary, its libraries, thread stacks, the
/// allocator's arenas (measured: a 64x64 `coif orient` peaks at 12 MiB).
pub const BASE_BYTES: u64 = 16 << 20;

/// Whole-image bytes per pixel of `coif orient`, besides its tiles: the decoded image and
/// its RGB copy (3 + 4 while converting), the gray image (4), the mask (1), orientation and
/// confidence (8), and while writing, the .npy bytes (4) and a picture (3).
pub const ORIENT_BYTES_PER_PX: u64 = 4 + 3 + 4 + 1 + 8 + 4 + 3;

/// Whole-image bytes per pixel the analysis adds to the orientation: the segmentation's
/// graph (its nodes, edges and flows), the traced curves' visit maps, the direction field
/// and its diffusion buffers, the pictures it writes. Measured, see the README.
pub const ANALYZE_BYTES_PER_PX: u64 = 200;

/// Bytes per cell of the hair volume's grid: the field's constraints and right-hand side,
/// the multigrid levels and the f64 solver vectors, the field itself, H, the density.
/// Measured, see the README.
pub const MODEL_BYTES_PER_CELL: u64 = 360;

/// Bytes per scalp root drawn: its vertex slots (12 B each, 121 at the default growth) in
/// the growth pass's buffer, the read-back and the caller's copy, then the strand (half
/// the slots on average); every root counted as kept.
pub fn bytes_per_root(p: &ModelParams) -> u64 {
    let slots = p.grow.max_verts() as u64;
    3 * 12 * slots + 6 * slots
}

/// Refuses `job` when its estimate is over `engine`'s budget.
pub fn check(engine: &Engine, job: &Job) -> crate::Result<()> {
    match job {
        Job::Orient(j) => check_orient(engine, j),
        Job::Analyze(j) => check_analyze(engine, j),
        Job::Model(j) => check_model(engine, j),
        Job::Sketch(j) => check_sketch(engine, j),
        _ => Ok(()),
    }
}

/// The image's size from its header alone; an unreadable file is left for the job to
/// report (None).
fn image_pixels(path: &Path) -> Option<(u32, u32)> {
    image::ImageReader::open(path)
        .ok()?
        .with_guessed_format()
        .ok()?
        .into_dimensions()
        .ok()
}

/// (estimate, detail) of the orientation of a `w` x `h` image.
fn orient_bytes(engine: &Engine, w: u32, h: u32, p: &OrientParams) -> crate::Result<(u64, String)> {
    let whole = w as u64 * h as u64 * ORIENT_BYTES_PER_PX;
    let tile = orient::tile_bytes(engine, w, h, p)?;
    let (tw, th, tiles) = orient::tiling(engine, w, h, p)?;
    Ok((
        BASE_BYTES + whole + tile,
        format!(
            "{} for the whole image, {} for {} on {}",
            Bytes(whole),
            Bytes(tile),
            if tiles > 1 {
                format!("each of {tiles} tiles of {tw}x{th} kept px")
            } else {
                "it in one piece".to_string()
            },
            if engine.is_gpu() {
                "the gpu"
            } else {
                "the cpu"
            }
        ),
    ))
}

fn check_image(
    engine: &Engine,
    image: &Path,
    p: &OrientParams,
    extra_per_px: u64,
) -> crate::Result<u64> {
    let Some((w, h)) = image_pixels(image) else {
        return Ok(0);
    };
    if w == 0 || h == 0 || p.validate().is_err() {
        return Ok(0);
    }
    let (bytes, detail) = orient_bytes(engine, w, h, p)?;
    let extra = w as u64 * h as u64 * extra_per_px;
    let detail = if extra > 0 {
        format!("{detail}, {} for the analysis", Bytes(extra))
    } else {
        detail
    };
    let what = format!("--image {} ({w}x{h} px)", image.display());
    engine
        .budget()
        .check(Cause::Input, &what, bytes + extra, &detail)?;
    Ok(bytes + extra)
}

fn check_orient(engine: &Engine, j: &OrientJob) -> crate::Result<()> {
    check_image(engine, &j.image, &j.params, 0).map(|_| ())
}

fn check_analyze(engine: &Engine, j: &AnalyzeJob) -> crate::Result<()> {
    check_image(engine, &j.image, &j.params.orient, ANALYZE_BYTES_PER_PX).map(|_| ())
}

/// Bytes the 3D stages of `coif model` add for `p`: (grid, roots).
pub fn model_bytes(p: &ModelParams) -> (u64, u64) {
    // The grid's largest axis has `cells` cells; the others are at most as long.
    let cells = (p.volume.cells as u64).saturating_pow(3);
    (
        cells.saturating_mul(MODEL_BYTES_PER_CELL),
        (p.roots as u64).saturating_mul(bytes_per_root(p)),
    )
}

fn check_model(engine: &Engine, j: &ModelJob) -> crate::Result<()> {
    let p = &j.params;
    let (grid, roots) = model_bytes(p);
    let budget = engine.budget();
    // Each option alone first, so the message names the one that is too large.
    budget.check(
        Cause::Option,
        &format!("--cells {}", p.volume.cells),
        BASE_BYTES.saturating_add(grid),
        &format!(
            "up to {0}³ grid cells at {MODEL_BYTES_PER_CELL} B each",
            p.volume.cells
        ),
    )?;
    budget.check(
        Cause::Option,
        &format!("--roots {}", p.roots),
        BASE_BYTES.saturating_add(roots),
        &format!("{} B per root", bytes_per_root(p)),
    )?;
    let image = check_image(engine, &j.image, &p.analyze.orient, ANALYZE_BYTES_PER_PX)?;
    let total = image.saturating_add(grid).saturating_add(roots);
    budget.check(
        Cause::Input,
        &format!(
            "--image {} with --cells {} and --roots {}",
            j.image.display(),
            p.volume.cells,
            p.roots
        ),
        total,
        &format!(
            "{} for the image, {} for the grid, {} for the roots",
            Bytes(image),
            Bytes(grid),
            Bytes(roots)
        ),
    )
}

/// Bytes per pixel of `coif sketch`: the photo and its hair mask, the segmentation from the
/// strokes (the analysis' graph), the orientation field, the curves' maps and the pictures
/// it writes. Measured (README, "Memory"): 394 B/px from 256² to 512²; half again kept for
/// what the measurement did not vary (the hair's share of the image, the strokes).
pub const SKETCH_BYTES_PER_PX: u64 = 600;

/// Bytes per pixel of `coif synth-hair`: the filled field (θ, its vectors, ρ), the two
/// texture bands, the synthesised picture and a backdrop. Measured: 174 B/px from 256² to
/// 512² (README, "Memory"); the estimate keeps the same margin as the sketch's.
pub const SYNTH_HAIR_BYTES_PER_PX: u64 = 300;

fn check_sketch(engine: &Engine, j: &SketchJob) -> crate::Result<()> {
    let Some((w, h)) = image_pixels(&j.image) else {
        return Ok(());
    };
    let px = w as u64 * h as u64;
    // Measured: 27.5 MiB at no pixels (the segmentation's and the oracle's fixed tables).
    let bytes = 2 * BASE_BYTES + px * SKETCH_BYTES_PER_PX;
    engine.budget().check(
        Cause::Input,
        &format!("--image {} ({w}x{h} px)", j.image.display()),
        bytes,
        &format!("{SKETCH_BYTES_PER_PX} B per pixel"),
    )
}

/// Refuses to synthesise hair from `sketch` (its size is in the file, read first: it is
/// small) when the picture's working set is over the budget.
pub fn check_synth_hair(engine: &Engine, sketch: &Path, w: u32, h: u32) -> crate::Result<()> {
    let px = w as u64 * h as u64;
    engine.budget().check(
        Cause::Input,
        &format!("--sketch {} ({w}x{h} px)", sketch.display()),
        BASE_BYTES.saturating_add(px.saturating_mul(SYNTH_HAIR_BYTES_PER_PX)),
        &format!("{SYNTH_HAIR_BYTES_PER_PX} B per pixel"),
    )
}

/// Bytes per vertex a frame of `coif simulate` holds: the frame is the model's strands as
/// the skin moves them, a copy with every attribute (points 12, colours 12, thickness 4,
/// transparency 4, all counted as present). Measured: 32 B per vertex per frame, 2 to 12
/// frames of 1.25M vertices; a quarter more for the allocator.
pub const SIM_FRAME_BYTES_PER_VERTEX: u64 = 40;

/// Bytes per vertex `coif simulate` holds whatever the frame count: the loaded scene, the
/// skin (its rest copy, segment, parameter and offset per vertex), the simulated guides,
/// and while writing, a frame's positions and their encoded bytes. Measured: 157 B per
/// vertex (README, "Memory").
pub const SIM_FIXED_BYTES_PER_VERTEX: u64 = 200;

/// Refuses a simulation of `scene` whose frames, all held until they are written, would be
/// over the budget: the model first (it alone may be too large), then `--frames`.
pub fn check_simulate(
    engine: &Engine,
    scene: &crate::hair::scene::Scene,
    frames: u32,
) -> crate::Result<()> {
    let verts = scene.strands.points.len() as u64;
    let strands = scene.strands.counts.len() as u64;
    // The preview GIF grows by an encoded frame of the photo each frame (measured 0.4 B/px).
    let photo_px = scene.width as u64 * scene.height as u64;
    let fixed = BASE_BYTES + verts * SIM_FIXED_BYTES_PER_VERTEX;
    let per_frame = verts * SIM_FRAME_BYTES_PER_VERTEX + strands * 4 + photo_px;
    let budget = engine.budget();
    budget.check(
        Cause::Input,
        &format!("--model {} ({verts} vertices)", scene.dir.display()),
        fixed + per_frame,
        &format!("{SIM_FIXED_BYTES_PER_VERTEX} B per vertex and one frame"),
    )?;
    let n = frames as u64 + 1;
    budget.check(
        Cause::Option,
        &format!("--frames {frames}"),
        fixed.saturating_add(n.saturating_mul(per_frame)),
        &format!(
            "{n} frames of {} held until written, {} for the model",
            Bytes(per_frame),
            Bytes(fixed)
        ),
    )
}
