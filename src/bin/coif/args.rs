//! The command line's arguments, and the jobs they ask for. Defaults come from the library's
//! parameter types, so the help text and a job built in code agree.

use clap::{Args, Parser, Subcommand};
use coif::analyze::orient::{OrientParams, SmoothFit, SmoothWeight};
use coif::analyze::AnalyzeParams;
use coif::gpu::engine::BackendChoice;
use coif::jobs::{
    AnalyzeJob, ClipSource, ConvertJob, EditJob, EditTool, ExportJob, ImportJob, Job, ModelJob,
    OrientJob, RenderJob, SynthVideoJob, TransferJob, VideoJob,
};
use coif::render::shade::{Light, ShadingModel};
use coif::synth;
use std::path::PathBuf;

mod batch;
mod simulate;
mod synth_args;
mod synth_hair;

#[derive(Parser)]
#[command(
    name = "coif",
    version,
    about = "Single-view 3D strand hair from a portrait and a few strokes (Chai et al. 2013)"
)]
pub struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
    /// Writes where the run's time went to FILE (.json): wall time per stage, GPU time per
    /// pass on adapters with timestamp queries, peak resident memory.
    #[arg(long, global = true, value_name = "FILE")]
    pub timings: Option<PathBuf>,
    /// Memory budget (e.g. 4G, 512M; K/M/G/T are powers of 1024): work estimated to need
    /// more is refused before it starts. Default: the cgroup limit, ulimit -v or
    /// MemAvailable, whichever is smallest.
    #[arg(long, global = true, value_name = "SIZE", value_parser = coif::base::budget::Budget::from_option)]
    pub max_memory: Option<coif::base::budget::Budget>,
    #[command(subcommand)]
    pub cmd: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Synthetic portrait with exact ground truth (orientation, growth direction, mask, strokes).
    Synth(synth_args::SynthArgs),
    /// Synthetic clip with exact ground truth: the 3D synthetic portrait under a known head
    /// motion (yaw/pitch within ±10°, a shift) and hair motion (strands turned about the view
    /// axis, roots and lengths kept): frames, masks, landmarks, per-frame strands, cameras,
    /// true flow and track.
    SynthVideo(SynthVideoArgs),
    /// Orientation and confidence maps of the hair (C13 §2.1).
    Orient(OrientArgs),
    /// The main job on the embedded default inputs: a synthetic case and the embedded
    /// astronaut photo through orientation, directed hair, 3D strands and renders; edits, a
    /// wind clip, and a short synthetic clip tracked and recoloured.
    Demo(DemoArgs),
    /// Directed hair from a photo, its hair mask and direction strokes (C13 §2.1): traced
    /// curves, their growth direction (Eq. 1-2) and a dense direction field.
    Analyze(AnalyzeArgs),
    /// Adapters, the backend `auto` would choose, and limits.
    Info,
    /// Converts a strand file: .hair .data .ply .obj in; .hair .data .ply .obj .usda out.
    Convert(ConvertArgs),
    /// Single-view 3D strand hair (C13 §2): analyze, head fit, hair volume, direction field
    /// (Eq. 3), RK2 growth from the scalp, cut-and-connect refinement (Eq. 4-5), colours.
    Model(ModelArgs),
    /// Writes a model's strands (`<model>/strands.hair`) as .hair .data .ply .obj or .usda.
    Export(ExportArgs),
    /// Reads a strand file (.hair .data .ply .obj) into a model folder (`strands.hair`,
    /// `model.json`).
    Import(ImportArgs),
    /// Renders a model back into its photo (C13 §4): inpainted background and head layers,
    /// anti-aliased strands, novel views, highlights and HSV recolouring. A simulated model
    /// renders every frame when --out is a folder.
    Render(RenderArgs),
    /// Simulates a model's hair (C13 §4 after Selle et al. 2008): mass-spring strands, wind
    /// from Perlin noise, head collisions, roots carried by a keyframed head motion.
    Simulate(simulate::SimulateArgs),
    /// Edits a model's strands with strokes on its photo (C13 appendix A): --comb turns
    /// strands toward the stroke direction, --cut shortens the strands that reach a stroke.
    Edit(EditArgs),
    /// Tracks a hair model through a clip (C13 §3): a model on the reference frame, carried
    /// through every frame by the head's motion and a warp that blends tracked features
    /// with orientation-field flow (Eq. 6-7). The output is a model folder with an
    /// animation that `render`, `export` and `transfer` read; a stopped run resumes.
    Video(VideoArgs),
    /// A hair image to its generative sketch (Chen and Zhu 2006 §4): curves of directed
    /// primitives (hair.czs, sketch.json, sketch.svg), the vector field filled in from them,
    /// shading bases and colour map, pictures and a report.
    Sketch(SketchArgs),
    /// Converts a sketch between its three files (.czs, .json, .svg), checking it: e.g. a
    /// sketch.svg edited in Inkscape back to a compact hair.czs.
    SketchConvert(SketchConvertArgs),
    /// A sketch back to a hair image (Chen and Zhu 2006 §3): the field filled in from the
    /// curves, texture along it, shading and colour from the sketch; over a photo if asked.
    SynthHair(synth_hair::SynthHairArgs),
    /// A sketch drawn as a cartoon (CZ06 Fig. 17): a brush stroke per curve, PNG or SVG.
    Cartoon(crate::cartoon_args::CartoonArgs),
    /// Edits a sketch: delete, move, add or flip curves, change contrast, edit shading bases.
    SketchEdit(crate::sketch_edit_args::SketchEditArgs),
    /// Hair replacement (C13 §4): another model's strands carried through a tracked clip
    /// (each follows its nearest tracked strand) and rendered into every frame.
    Transfer(TransferArgs),
    /// The jobs of a manifest (one JSON object per line), or one shard of them; a failing
    /// job is recorded in the summary and the rest carry on; --resume skips completed jobs;
    /// --jobs runs several at once.
    Batch(batch::BatchArgs),
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("clip").required(true).args(["frames", "video"])))]
pub struct VideoArgs {
    /// Folder of numbered frames (PNG or JPEG: 0000.png, frame_1.png, ...).
    #[arg(long)]
    frames: Option<PathBuf>,
    /// A video file, decoded with ffmpeg (when installed) into <out>/decoded/.
    #[arg(long)]
    video: Option<PathBuf>,
    /// Index of the reference frame (from 0) the model is built on.
    #[arg(long, default_value_t = 0)]
    reference: usize,
    /// Direction strokes on the reference frame (strokes.json).
    #[arg(long)]
    strokes: PathBuf,
    /// Hair mask of the reference frame (else segmented from the strokes).
    #[arg(long)]
    mask: Option<PathBuf>,
    /// Face landmarks of the reference frame.
    #[arg(long)]
    landmarks: Option<PathBuf>,
    /// Folder of landmark files named by frame (NNNN.json) for any frames; the others
    /// take the head's motion from features tracked on the face.
    #[arg(long)]
    landmark_dir: Option<PathBuf>,
    /// Feature points to add or correct in any frame (JSON: {"points": [{"id", "frame",
    /// "x", "y"}]}).
    #[arg(long)]
    points: Option<PathBuf>,
    /// Output folder (created; a run of the same inputs stopped half-way resumes).
    #[arg(long)]
    out: PathBuf,
    /// Weight of the feature warp in Eq. (6): 0.5 in the paper; 0 flow alone, 1 features alone.
    #[arg(long, default_value_t = coif::video::track::TrackParams::default().alpha)]
    alpha: f32,
    /// Arc length (m) over which the hair's own motion rises from 0 at the root (β of Eq. 7).
    #[arg(long, default_value_t = coif::video::track::TrackParams::default().beta_ramp_m)]
    beta_ramp: f32,
    /// Seed of the model's random choices.
    #[arg(long, default_value_t = coif::model::ModelParams::default().seed)]
    seed: u64,
    /// Scalp roots drawn for the reference model.
    #[arg(long, default_value_t = coif::model::ModelParams::default().roots)]
    roots: usize,
    #[command(flatten)]
    backend: BackendArgs,
}

#[derive(Args)]
pub struct SketchArgs {
    /// Hair image (PNG or JPEG, 8-bit).
    #[arg(long)]
    image: PathBuf,
    /// Hair mask of the image's size (> 127 on hair).
    #[arg(long, conflicts_with = "whole")]
    mask: Option<PathBuf>,
    /// Direction strokes (strokes.json, LabelMe or SVG): segment the hair from them when no
    /// mask is given, and clamp the directions of the curves they run along.
    #[arg(long)]
    strokes: Option<PathBuf>,
    /// Take every pixel as hair (a crop of hair or fur), with neither mask nor strokes.
    #[arg(long)]
    whole: bool,
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    /// Curve penalty λ_NC of Eq. 5 (larger: fewer curves).
    #[arg(long, default_value_t = coif::sketch::pursuit::PursuitParams::default().lambda_nc)]
    curve_penalty: f32,
    /// Primitive penalty λ_B: the cost of each primitive of a curve (larger: fewer and
    /// shorter curves, a smaller file).
    #[arg(long, default_value_t = coif::sketch::pursuit::PursuitParams::default().lambda_b)]
    primitive_penalty: f32,
    /// Side angles from the paper's dictionary alone ({0, π/3, π/2, 2π/3} off the axis,
    /// CZ06 Eq. 3), without the 3.75° refinement: files 2-3x smaller, a coarser field.
    #[arg(long)]
    dictionary_sides: bool,
    /// μ, the energy one bit of hair.czs is worth when the side refinements (and, with
    /// --rate-contrast, the contrasts) are chosen again by rate and distortion (larger:
    /// smaller files, codes that follow their neighbours more); 0 keeps each primitive's own.
    #[arg(long, default_value_t = coif::sketch::pursuit::PursuitParams::default().bit_cost)]
    bit_cost: f32,
    /// Choose the contrasts' codes by rate and distortion too (a few % smaller hair.czs).
    #[arg(long)]
    rate_contrast: bool,
    /// A budget for hair.czs in bytes: where the sketch comes out larger, the primitive
    /// penalty is raised until it fits (the steps tried are in report.json); refused (exit
    /// 64) where not even a sketch without curves fits. Replaces --target-bytes.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    max_bytes: Option<u64>,
    /// The size hair.czs is brought under, where a sketch with curves can be (else it is kept
    /// as pursued, with a warning): by the sketch target's pruning, or as --max-bytes does
    /// where that stops short or is off; 0 leaves the size as it comes.
    #[arg(long, default_value_t = coif::sketch::run::DEFAULT_TARGET_BYTES as u64)]
    target_bytes: u64,
    /// The fill's mean distance from the dense field (degrees, over hair 5 px inside the
    /// region) the sketch is brought within: where it strays further, the curve penalty is
    /// halved (to 5 at least) and the analysis run again (the steps tried are in
    /// report.json); 0 keeps the curve penalty as given.
    #[arg(long, value_name = "DEG", value_parser = parse_non_negative,
          default_value_t = coif::sketch::run::DEFAULT_FILL_TARGET_DEG)]
    target_fill: f32,
    /// The size the sketch part of hair.czs (its curves) is brought under, bytes, where the
    /// fill stays within its target: the curves the fill needs least are dropped (the rounds
    /// are in report.json under sketch_target); 0 keeps every curve.
    #[arg(long, default_value_t = coif::sketch::run::DEFAULT_SKETCH_TARGET_BYTES as u64)]
    target_sketch_bytes: u64,
    /// How directions are chosen: swc (Swendsen-Wang cuts, CZ06 §4.2), icm, or prior (each
    /// curve by the direction prior alone; the ablation baselines).
    #[arg(long, default_value = "swc")]
    directions: String,
    /// Where the direction prior's crown sits across the hair: centroid (CZ06's generic
    /// prior: a side parting is left to the sketch and the curves' compatibility) or
    /// parting (over the parting the orientation field shows, else the mask's centroid).
    #[arg(long, default_value = "centroid")]
    crown: String,
    /// κ, the direction prior's weight per sketch pixel against the curves' compatibility
    /// (one per border pixel pair): larger trusts the prior (outward from the crown, bent
    /// down) more than the neighbouring curves.
    #[arg(long, default_value_t = coif::sketch::swc::DEFAULT_PRIOR_WEIGHT,
          value_parser = parse_positive)]
    prior_weight: f32,
    /// Swendsen-Wang proposals.
    #[arg(long, default_value_t = coif::sketch::swc::SwcParams::default().sweeps)]
    sweeps: usize,
    /// Shading bases K_L.
    #[arg(long, default_value_t = 10)]
    bases: usize,
    /// σ of the low band (px).
    #[arg(long, default_value_t = 8.0)]
    sigma_low: f32,
    /// Seed of the sampler and of the draws synthesis makes from the sketch.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    backend: BackendArgs,
}

#[derive(Args)]
pub struct SketchConvertArgs {
    /// A sketch: hair.czs, sketch.json or sketch.svg.
    #[arg(long)]
    sketch: PathBuf,
    /// The file to write; its extension (.czs, .json, .svg) names the format.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
pub struct TransferArgs {
    /// A tracked clip written by `coif video`.
    #[arg(long)]
    video_model: PathBuf,
    /// The hair to put in: a model folder written by `coif model` (same parametric head).
    #[arg(long)]
    model: PathBuf,
    /// Output folder: the new hair's scene with the clip's frames, render/NNNN.png and
    /// preview.gif.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    backend: BackendArgs,
}

#[derive(Args)]
pub struct RenderArgs {
    /// Model folder written by `coif model` (or `coif import`, with --strands-only).
    #[arg(long)]
    model: PathBuf,
    /// Output .png (8-bit sRGB; 16-bit with --16bit) or .jpg; a sidecar `<out>.json`
    /// records the camera, the settings, the adapter and timings.
    #[arg(long)]
    out: PathBuf,
    /// Turns the head about its vertical axis, degrees (positive: face toward image right).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    yaw: f32,
    /// Tilts the head, degrees (positive: face up).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pitch: f32,
    /// Rolls the head in the image plane, degrees (positive: counter-clockwise).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    roll: f32,
    /// A pinhole camera this far from the head centre (model units, metres) instead of the
    /// photo's weak-perspective camera.
    #[arg(long)]
    distance: Option<f32>,
    /// Output size relative to the photo.
    #[arg(long, default_value_t = 1.0)]
    scale: f32,
    /// Output size for models without a photo, WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    /// Hue shift of the hair colour, degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    hue: f32,
    /// Saturation scale of the hair colour.
    #[arg(long, default_value_t = 1.0)]
    saturation: f32,
    /// Value (brightness) scale of the hair colour.
    #[arg(long, default_value_t = 1.0)]
    value: f32,
    /// Amount of synthetic highlight (0 keeps the photo's own shading).
    #[arg(long, default_value_t = 0.0)]
    highlight: f32,
    /// Shading model of the highlights.
    #[arg(long, value_enum, default_value_t = ShadingArg::Marschner)]
    shading: ShadingArg,
    /// Light in view space "x,y,z[,intensity[,r,g,b]]" (x right, y up, z toward the
    /// camera); repeat for several lights.
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(Light))]
    light: Vec<Light>,
    /// Strand width in pixels at scale 1.
    #[arg(long, default_value_t = 1.0)]
    width: f32,
    /// Only the strands (no photo, no head), over --background or transparent.
    #[arg(long)]
    strands_only: bool,
    /// Background colour for --strands-only, "r,g,b" in 0..255.
    #[arg(long, value_parser = parse_rgb)]
    background: Option<[f32; 3]>,
    /// Extra strand vertices every this many photo pixels, coloured from the photo (0: the
    /// model's vertex colours only).
    #[arg(long, default_value_t = 0.0)]
    colour_spacing: f32,
    /// Strand colour of a composite render: the photo under every fragment, or C13's
    /// per-vertex samples.
    #[arg(long, value_enum, default_value_t = coif::render::ColourSource::Photo)]
    colour: coif::render::ColourSource,
    /// 16-bit PNG output.
    #[arg(long = "16bit")]
    sixteen: bool,
    /// Seed of the inpainting's random search.
    #[arg(long, default_value_t = coif::render::inpaint::InpaintParams::default().seed)]
    seed: u64,
    #[command(flatten)]
    backend: BackendArgs,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum ShadingArg {
    /// Marschner et al. 2003 (R, TT, TRT lobes).
    Marschner,
    /// Kajiya-Kay (cheaper: diffuse + shifted specular).
    KajiyaKay,
}

fn parse_non_negative(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("expected a finite number ≥ 0, got {s:?}")),
    }
}

fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a finite number > 0, got {s:?}")),
    }
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (a, b) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got {s:?}"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| format!("expected a positive width and height, got {s:?}"))
    };
    Ok((p(a)?, p(b)?))
}

fn parse_rgb(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected r,g,b in 0..255, got {s:?}"))?;
    match v.as_slice() {
        [r, g, b] if v.iter().all(|c| (0.0..=255.0).contains(c)) => {
            Ok([r / 255.0, g / 255.0, b / 255.0])
        }
        _ => Err(format!("expected r,g,b in 0..255, got {s:?}")),
    }
}

/// The inputs of `analyze` and `model`.
#[derive(Args)]
pub struct PhotoArgs {
    /// Portrait (PNG).
    #[arg(long)]
    image: PathBuf,
    /// strokes.json (version 1), or strokes drawn elsewhere: a labelme .json (linestrip
    /// shapes) or an .svg (polylines, line-segment paths); direction strokes root to tip.
    #[arg(long)]
    strokes: PathBuf,
    /// Hair mask, same size, > 127 on hair; without it the hair is segmented from the
    /// strokes (direction strokes are hair; background strokes, else the image border, are not).
    #[arg(long)]
    mask: Option<PathBuf>,
    /// A hair mask drawn by hand (same size, > 127 on hair): the mask used (segmented or
    /// given) is scored against it (IoU, missed and taken pixels, errors at and beyond the
    /// edge, boundary F-measure) into mask_agreement.json, with mask_vs_reference.png.
    #[arg(long, value_name = "PNG")]
    reference_mask: Option<PathBuf>,
}

#[derive(Args)]
pub struct ModelArgs {
    #[command(flatten)]
    input: PhotoArgs,
    /// landmarks.json (version 1: eyes, nose tip, mouth corners, chin); without it the head
    /// is placed by the default fit to the mask (frontal, sized by the mask's upper width).
    #[arg(long)]
    landmarks: Option<PathBuf>,
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    backend: BackendArgs,
    /// Seed of the random choices (roots, refinement seeds).
    #[arg(long, default_value_t = coif::model::ModelParams::default().seed)]
    seed: u64,
    /// Scalp roots drawn before the mask excludes the face (n_s).
    #[arg(long, default_value_t = coif::model::ModelParams::default().roots)]
    roots: usize,
    /// Cells along the hair volume's largest axis (C13: 80).
    #[arg(long, default_value_t = coif::model::volume::VolumeParams::default().cells)]
    cells: u32,
    /// Refinement iterations (C13: 4-5); 0 keeps the grown strands only.
    #[arg(long, default_value_t = coif::model::refine::RefineParams::default().max_iterations)]
    refine: u32,
}

#[derive(Args)]
#[command(group = clap::ArgGroup::new("tool").required(true).args(["comb", "cut"]))]
pub struct EditArgs {
    /// Model folder written by `coif model` (it needs the camera).
    #[arg(long)]
    model: PathBuf,
    /// Output folder (created): the edited model, which `coif render` draws.
    #[arg(long)]
    out: PathBuf,
    /// Strokes file (strokes.json schema) with strokes of kind "comb", image px.
    #[arg(long)]
    comb: Option<PathBuf>,
    /// Strokes file (strokes.json schema) with strokes of kind "cut", image px.
    #[arg(long)]
    cut: Option<PathBuf>,
    /// Radius of influence, image px (a cut with 0 is clean, at the first crossing).
    #[arg(long, default_value_t = coif::edit::DEFAULT_RADIUS, allow_negative_numbers = true)]
    radius: f32,
    /// Seed of the cut's random choice of vertex.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Level of the strand hierarchy to edit (0: the strands; 1, 2, ...: cluster centres,
    /// about 16 members each, whose members follow with their detail).
    #[arg(long, default_value_t = 0)]
    level: usize,
    #[command(flatten)]
    backend: BackendArgs,
}

impl EditArgs {
    fn job(self) -> EditJob {
        let tool = match (self.comb, self.cut) {
            (Some(strokes), _) => EditTool::Comb { strokes },
            (None, Some(strokes)) => EditTool::Cut {
                strokes,
                seed: self.seed,
            },
            // The argument group requires exactly one of them.
            (None, None) => unreachable!("clap requires --comb or --cut"),
        };
        EditJob {
            model: self.model,
            out: self.out,
            tool,
            radius: self.radius,
            level: self.level,
        }
    }
}

#[derive(Args)]
pub struct ExportArgs {
    /// Model folder written by `coif model` or `coif import`.
    #[arg(long)]
    model: PathBuf,
    /// Strand file to write; the format follows the extension.
    #[arg(long)]
    to: PathBuf,
}

#[derive(Args)]
pub struct ImportArgs {
    /// Strand file to read (.hair .data .ply .obj).
    input: PathBuf,
    /// Model folder to write (created).
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
pub struct ConvertArgs {
    /// Strand file to read.
    input: PathBuf,
    /// Strand file to write; the format follows the extension.
    output: PathBuf,
}

#[derive(Args)]
pub struct SynthVideoArgs {
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value = "long")]
    style: synth::Style,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Number of frames (2..=10000).
    #[arg(long, default_value_t = 60)]
    frames: usize,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 256)]
    size: u32,
    /// Ground-truth strands.
    #[arg(long, default_value_t = synth::synth3d::Synth3dOptions::default().strands)]
    strands: usize,
    /// Frames per second (the motion's periods are in seconds).
    #[arg(long, default_value_t = synth::video::VideoParams::DEFAULT_FPS)]
    fps: f32,
    /// Scale of the lock-scale hair turn, degrees (neighbouring locks swinging out of step);
    /// 0 leaves the head-sized waves alone.
    #[arg(long, default_value_t = synth::video::LOCK_TURN_DEG)]
    lock_turn: f32,
    /// Camera noise: σ (grey levels) of Gaussian noise on every channel of every frame,
    /// fresh per frame; 0 keeps clean renders.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    noise: f32,
    /// JPEG quality (1-100) every frame goes through after the noise, as a compressed clip;
    /// 0 keeps lossless frames.
    #[arg(long, default_value_t = 0)]
    jpeg: u8,
}

#[derive(Args, Clone)]
pub struct BackendArgs {
    /// auto: a hardware GPU if present, else cpu. gpu: wgpu on any adapter (lavapipe too).
    #[arg(long, value_enum, default_value = "auto")]
    pub(crate) backend: BackendChoice,
}

#[derive(Args, Clone)]
pub struct OrientOpts {
    /// Gabor orientations (multiple of 4, up to 64).
    #[arg(long, default_value_t = OrientParams::default().kernel.n_orient)]
    orientations: u32,
    /// Gabor sigma across the strand (px).
    #[arg(long, default_value_t = OrientParams::default().kernel.sigma_x)]
    sigma_x: f32,
    /// Gabor sigma along the strand (px).
    #[arg(long, default_value_t = OrientParams::default().kernel.sigma_y)]
    sigma_y: f32,
    /// Gabor wavelength (px).
    #[arg(long, default_value_t = OrientParams::default().kernel.lambda)]
    lambda: f32,
    /// Gabor kernel size (odd).
    #[arg(long, default_value_t = OrientParams::default().kernel.ksize)]
    ksize: u32,
    /// DoG prefilter: fine sigma (px).
    #[arg(long, default_value_t = OrientParams::default().dog_sigma_fine)]
    dog_fine: f32,
    /// DoG prefilter: coarse sigma (px); 0 disables the prefilter.
    #[arg(long, default_value_t = OrientParams::default().dog_sigma_coarse)]
    dog_coarse: f32,
    /// Refinement passes (Gabor bank re-applied to the confidence map).
    #[arg(long, default_value_t = OrientParams::default().refine_iters)]
    refine: u32,
    /// Sigma of the confidence-weighted double-angle smoothing (px); 0 disables it.
    #[arg(long, default_value_t = OrientParams::default().smooth_sigma)]
    smooth: f32,
    /// What the smoothing fits in each window: linear (intercept and slope, the default) or
    /// constant (the weighted mean, as before 2026-12-04).
    #[arg(long, value_enum, default_value_t = OrientParams::default().smooth_fit)]
    smooth_fit: SmoothFit,
    /// What weights each orientation in the smoothing: image (its Gabor confidence squared,
    /// the default) or refined (times the refined confidence, as before 2026-12-04).
    #[arg(long, value_enum, default_value_t = OrientParams::default().smooth_weight)]
    smooth_weight: SmoothWeight,
    /// Scale in degrees of the linear fit's robust second round (an orientation that far
    /// from the first round's fit keeps half its weight); 0: one round.
    #[arg(long, default_value_t = OrientParams::default().smooth_robust_deg)]
    smooth_robust: f32,
    /// Power of each orientation's weight in the robust fit's first round, its guide (below
    /// 1 a lone high-contrast line such as a parting cannot carry the guide); 1: the same
    /// weight as the second round.
    #[arg(long, default_value_t = OrientParams::default().smooth_guide_power)]
    smooth_guide_power: f32,
    /// Radius (px) within which a whorl (a point the hair turns once around) takes a fitted
    /// spiral instead of the smoothed field, blended out to twice it; 0: no model.
    #[arg(long, default_value_t = OrientParams::default().singular_radius)]
    singular_radius: f32,
}

impl OrientOpts {
    fn params(&self) -> OrientParams {
        let mut p = OrientParams::default();
        p.kernel.n_orient = self.orientations;
        p.kernel.sigma_x = self.sigma_x;
        p.kernel.sigma_y = self.sigma_y;
        p.kernel.lambda = self.lambda;
        p.kernel.ksize = self.ksize;
        p.dog_sigma_fine = self.dog_fine;
        p.dog_sigma_coarse = self.dog_coarse;
        p.refine_iters = self.refine;
        p.smooth_sigma = self.smooth;
        p.smooth_fit = self.smooth_fit;
        p.smooth_weight = self.smooth_weight;
        p.smooth_robust_deg = self.smooth_robust;
        p.smooth_guide_power = self.smooth_guide_power;
        p.singular_radius = self.singular_radius;
        p
    }
}

#[derive(Args)]
pub struct OrientArgs {
    /// Portrait (PNG or any format the `image` crate reads as 8-bit).
    #[arg(long)]
    image: PathBuf,
    /// Hair mask, same size, nonzero (> 127) on hair. Without it every pixel is hair.
    #[arg(long)]
    mask: Option<PathBuf>,
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    backend: BackendArgs,
    #[command(flatten)]
    opts: OrientOpts,
    /// Largest buffer binding to use, in bytes (tiles the image below the device limit).
    #[arg(long)]
    max_binding_bytes: Option<u64>,
    /// A `coif synth` folder: score the orientation against its `gt_theta.npy` and
    /// `mask.png` (mean error in degrees, printed).
    #[arg(long)]
    truth: Option<PathBuf>,
}

#[derive(Args)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    #[command(flatten)]
    backend: BackendArgs,
}

#[derive(Args)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    input: PhotoArgs,
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    backend: BackendArgs,
    #[command(flatten)]
    opts: OrientOpts,
    /// Neighbourhood radius of the direction vote, C13 Eq. (1) (px).
    #[arg(long, default_value_t = coif::analyze::resolve::ResolveParams::default().radius)]
    radius: f32,
    /// Weight of a user stroke in the vote, C13's w_m.
    #[arg(long, default_value_t = coif::analyze::resolve::ResolveParams::default().stroke_weight)]
    stroke_weight: f32,
    /// Cut traced curves where they cross a line of strand ends (a parting the orientation
    /// runs through) whose along/across derivative ratio exceeds this; 0 turns it off.
    #[arg(long, value_name = "RATIO", value_parser = parse_non_negative,
          default_value_t = coif::analyze::parting::PartingParams::default().threshold)]
    parting: f32,
    /// Also cut where the ratio exceeds this (at most --parting; 0: never) at peaks that line
    /// up with a cut above --parting: curves on the two sides of such a line then do not vote
    /// on each other's direction.
    #[arg(long, value_name = "RATIO", value_parser = parse_non_negative,
          default_value_t = coif::analyze::parting::PartingParams::default().line_threshold)]
    parting_line: f32,
    /// Without --mask: the graph cut's smoothness γ (GrabCut's 50); lower lets the mask's
    /// edge follow weaker colour edges.
    #[arg(long, value_name = "GAMMA", value_parser = parse_non_negative,
          default_value_t = coif::analyze::segment::SegmentParams::default().smoothness)]
    segment_smoothness: f32,
    /// Without --mask: weight of a colour step's luminance against its chroma in the cut's
    /// contrast (1: GrabCut's RGB distance); below 1 the cut keeps off shading edges inside
    /// the hair.
    #[arg(long, value_name = "WEIGHT", value_parser = parse_non_negative,
          default_value_t = coif::analyze::segment::SegmentParams::default().luminance)]
    segment_luminance: f32,
    /// Without --mask: every pixel under a direction stroke is sure hair, even for a stroke
    /// that seems to lie off the hair (by default the pixels of such a stroke that look like
    /// background are left to the colour models, and the warning says so; `"sure": true` on
    /// a stroke in the strokes file does this for that stroke alone).
    #[arg(long)]
    segment_trust_strokes: bool,
}

/// What the command line asks for.
pub enum Request {
    /// Jobs run in order on one engine.
    Jobs {
        jobs: Vec<Job>,
        backend: BackendChoice,
        max_binding_bytes: Option<u64>,
        /// A line printed before the jobs run (with the engine's description).
        banner: Option<&'static str>,
    },
    Info,
    Batch(coif::batch::BatchOptions),
}

impl Request {
    fn one(job: Job, backend: BackendChoice) -> Request {
        Request::Jobs {
            jobs: vec![job],
            backend,
            max_binding_bytes: None,
            banner: None,
        }
    }
}

impl Command {
    pub fn request(self) -> anyhow::Result<Request> {
        // Jobs that run no pass open the CPU backend, which cannot fail.
        let cpu = BackendChoice::Cpu;
        Ok(match self {
            Command::Synth(a) => a.request(),
            Command::SynthVideo(a) => {
                let mut params = synth::video::VideoParams::new(a.style, a.seed, a.size, a.frames);
                params.strands = a.strands;
                params.fps = a.fps;
                params.lock_turn_deg = a.lock_turn;
                params.noise = a.noise;
                params.jpeg = a.jpeg;
                Request::one(Job::SynthVideo(SynthVideoJob { out: a.out, params }), cpu)
            }
            Command::Sketch(a) => {
                use coif::jobs::{HairRegion, SketchJob};
                let region = match (a.mask, a.whole, &a.strokes) {
                    (Some(m), _, _) => HairRegion::Mask(m),
                    (None, true, _) => HairRegion::Whole,
                    (None, false, Some(s)) => HairRegion::Strokes(s.clone()),
                    (None, false, None) => {
                        return Err(coif::Error::Invalid(
                            "coif sketch needs the hair region: --mask, --strokes or --whole"
                                .into(),
                        )
                        .into())
                    }
                };
                use coif::sketch::run::ByteBudget;
                let mut params = coif::sketch::run::SketchParams::default();
                params.pursuit.lambda_nc = a.curve_penalty;
                params.pursuit.lambda_b = a.primitive_penalty;
                params.pursuit.refine_sides = !a.dictionary_sides;
                params.pursuit.bit_cost = a.bit_cost;
                params.pursuit.rate_contrast = a.rate_contrast;
                params.budget = ByteBudget::from_options(
                    a.max_bytes.map(|b| b as usize),
                    Some(a.target_bytes as usize),
                );
                params.fill_target = (a.target_fill > 0.0).then_some(a.target_fill);
                params.sketch_target =
                    (a.target_sketch_bytes > 0).then_some(a.target_sketch_bytes as usize);
                params.method = a.directions.parse()?;
                params.swc.prior.crown = a.crown.parse()?;
                params.swc.prior.kappa = a.prior_weight;
                params.swc.sweeps = a.sweeps;
                params.bases = a.bases;
                params.sigma_l = a.sigma_low;
                params.seed = a.seed;
                Request::Jobs {
                    jobs: vec![Job::Sketch(SketchJob {
                        image: a.image,
                        region,
                        strokes: a.strokes,
                        out: a.out,
                        params,
                    })],
                    backend: a.backend.backend,
                    max_binding_bytes: None,
                    banner: None,
                }
            }
            Command::SynthHair(a) => a.request(),
            Command::Batch(a) => a.request(),
            Command::Cartoon(a) => a.request()?,
            Command::SketchConvert(a) => Request::one(
                Job::SketchConvert(coif::jobs::SketchConvertJob {
                    input: a.sketch,
                    out: a.out,
                }),
                cpu,
            ),
            Command::SketchEdit(a) => a.request()?,
            Command::Orient(a) => Request::Jobs {
                jobs: vec![Job::Orient(OrientJob {
                    image: a.image,
                    mask: a.mask,
                    out: a.out,
                    params: a.opts.params(),
                    truth: a.truth,
                })],
                backend: a.backend.backend,
                max_binding_bytes: a.max_binding_bytes,
                banner: None,
            },
            Command::Demo(a) => Request::Jobs {
                jobs: coif::jobs::demo(&a.out),
                backend: a.backend.backend,
                max_binding_bytes: None,
                banner: Some("coif demo"),
            },
            Command::Analyze(a) => {
                let mut params = AnalyzeParams {
                    orient: a.opts.params(),
                    ..Default::default()
                };
                params.resolve.radius = a.radius;
                params.resolve.stroke_weight = a.stroke_weight;
                params.parting.threshold = a.parting;
                params.parting.line_threshold = a.parting_line;
                params.segment.smoothness = a.segment_smoothness;
                params.segment.luminance = a.segment_luminance;
                params.segment.release_off_hair = !a.segment_trust_strokes;
                let job = AnalyzeJob {
                    image: a.input.image,
                    strokes: a.input.strokes,
                    mask: a.input.mask,
                    out: a.out,
                    params,
                    reference_mask: a.input.reference_mask,
                };
                Request::one(Job::Analyze(job), a.backend.backend)
            }
            Command::Info => Request::Info,
            Command::Convert(a) => Request::one(
                Job::Convert(ConvertJob {
                    input: a.input,
                    output: a.output,
                }),
                cpu,
            ),
            Command::Model(a) => {
                let mut params = coif::model::ModelParams {
                    seed: a.seed,
                    roots: a.roots,
                    ..Default::default()
                };
                params.volume.cells = a.cells;
                params.refine.max_iterations = a.refine;
                let job = ModelJob {
                    image: a.input.image,
                    strokes: a.input.strokes,
                    mask: a.input.mask,
                    landmarks: a.landmarks,
                    reference_mask: a.input.reference_mask,
                    out: a.out,
                    params,
                };
                Request::one(Job::Model(job), a.backend.backend)
            }
            Command::Export(a) => Request::one(
                Job::Export(ExportJob {
                    model: a.model,
                    to: a.to,
                }),
                cpu,
            ),
            Command::Import(a) => Request::one(
                Job::Import(ImportJob {
                    input: a.input,
                    out: a.out,
                }),
                cpu,
            ),
            Command::Simulate(a) => {
                let backend = a.backend.backend;
                Request::one(Job::Simulate(a.job()), backend)
            }
            Command::Edit(a) => {
                let backend = a.backend.backend;
                Request::one(Job::Edit(a.job()), backend)
            }
            Command::Render(a) => {
                let backend = a.backend.backend;
                Request::one(Job::Render(a.job()?), backend)
            }
            Command::Video(a) => {
                let source = match (a.frames, a.video) {
                    (Some(d), _) => ClipSource::Frames(d),
                    (None, Some(v)) => ClipSource::Video(v),
                    (None, None) => unreachable!("clap requires one of --frames and --video"),
                };
                let model = coif::model::ModelParams {
                    seed: a.seed,
                    roots: a.roots,
                    ..Default::default()
                };
                let track = coif::video::track::TrackParams {
                    alpha: a.alpha,
                    beta_ramp_m: a.beta_ramp,
                    ..Default::default()
                };
                Request::one(
                    Job::Video(VideoJob {
                        source,
                        ann: coif::video::run::Annotations {
                            reference: a.reference,
                            strokes: a.strokes,
                            mask: a.mask,
                            landmarks: a.landmarks,
                            landmark_dir: a.landmark_dir,
                            points: a.points,
                        },
                        out: a.out,
                        model,
                        track,
                    }),
                    a.backend.backend,
                )
            }
            Command::Transfer(a) => Request::one(
                Job::Transfer(TransferJob {
                    video_model: a.video_model,
                    model: a.model,
                    out: a.out,
                    render: Default::default(),
                }),
                a.backend.backend,
            ),
        })
    }
}

impl RenderArgs {
    fn job(self) -> anyhow::Result<RenderJob> {
        let mut p = coif::render::RenderParams {
            yaw_deg: self.yaw,
            pitch_deg: self.pitch,
            roll_deg: self.roll,
            distance: self.distance,
            scale: self.scale,
            size: self.size,
            strands_only: self.strands_only,
            background: self.background,
            colour_spacing_px: self.colour_spacing,
            colour: self.colour,
            ..Default::default()
        };
        p.raster.strand_width = self.width;
        p.shade.hue = self.hue;
        p.shade.saturation = self.saturation;
        p.shade.value = self.value;
        p.shade.amount = self.highlight;
        p.shade.model = match self.shading {
            ShadingArg::Marschner => ShadingModel::Marschner,
            ShadingArg::KajiyaKay => ShadingModel::KajiyaKay,
        };
        if !self.light.is_empty() {
            p.shade.lights = self.light;
        }
        p.inpaint.seed = self.seed;
        p.head_texture.inpaint.seed = self.seed;
        Ok(RenderJob {
            model: self.model,
            out: self.out,
            params: p,
            sixteen: self.sixteen,
        })
    }
}
