//! The `coif` command line.

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use coif::analyze::orient::{GrayImage, OrientParams};
use coif::gpu::engine::{BackendChoice, Engine};
use coif::io::images as imgio;
use coif::{synth, Error};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "coif",
    version,
    about = "Single-view 3D strand hair from a portrait and a few strokes (Chai et al. 2013)"
)]
struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    cmd: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Synthetic portrait with exact ground truth (orientation, growth direction, mask, strokes).
    Synth(SynthArgs),
    /// Orientation and confidence maps of the hair (C13 §2.1).
    Orient(OrientArgs),
    /// The main job on the embedded default inputs: synth + orient on a synthetic case and on
    /// the embedded astronaut photo.
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
    /// anti-aliased strands, novel views, highlights and HSV recolouring.
    Render(RenderArgs),
}

#[derive(Args)]
struct RenderArgs {
    /// Model folder written by `coif model` (or `coif import`, with --strands-only).
    #[arg(long)]
    model: PathBuf,
    /// Output PNG (8-bit sRGB; 16-bit with --16bit); a sidecar `<out>.json` records the
    /// camera, the settings, the adapter and timings.
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
    #[arg(long, allow_hyphen_values = true)]
    light: Vec<String>,
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
enum ShadingArg {
    /// Marschner et al. 2003 (R, TT, TRT lobes).
    Marschner,
    /// Kajiya-Kay (cheaper: diffuse + shifted specular).
    KajiyaKay,
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

#[derive(Args)]
struct ModelArgs {
    /// Portrait (PNG).
    #[arg(long)]
    image: PathBuf,
    /// strokes.json (version 1), a labelme .json or an .svg; direction strokes root to tip.
    #[arg(long)]
    strokes: PathBuf,
    /// Hair mask, same size, > 127 on hair; without it the hair is segmented from the strokes.
    #[arg(long)]
    mask: Option<PathBuf>,
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
struct ExportArgs {
    /// Model folder written by `coif model` or `coif import`.
    #[arg(long)]
    model: PathBuf,
    /// Strand file to write; the format follows the extension.
    #[arg(long)]
    to: PathBuf,
}

#[derive(Args)]
struct ImportArgs {
    /// Strand file to read (.hair .data .ply .obj).
    input: PathBuf,
    /// Model folder to write (created).
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
struct ConvertArgs {
    /// Strand file to read.
    input: PathBuf,
    /// Strand file to write; the format follows the extension.
    output: PathBuf,
}

#[derive(Args)]
struct SynthArgs {
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value = "long")]
    style: synth::Style,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// 3D ground truth: a strand model grown on the parametric head and rendered through a
    /// known camera (writes gt_strands.hair and camera.json too).
    #[arg(long)]
    gt3d: bool,
}

#[derive(Args, Clone)]
struct BackendArgs {
    /// auto: a hardware GPU if present, else cpu. gpu: wgpu on any adapter (lavapipe too).
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendChoice,
}

#[derive(Args, Clone)]
struct OrientOpts {
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
        p
    }
}

#[derive(Args)]
struct OrientArgs {
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
}

#[derive(Args)]
struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    #[command(flatten)]
    backend: BackendArgs,
}

fn main() {
    // Headless Vulkan loaders print "XDG_RUNTIME_DIR is invalid" to stderr for every
    // instance; pointing it at the temp folder keeps batch logs clean. Single-threaded here.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none_or(|d| !Path::new(&d).is_dir()) {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    }
    let cli = Cli::parse();
    let level = match cli.verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(level))
        .format_timestamp(None)
        .init();
    if let Err(e) = run(cli.cmd) {
        eprintln!("coif: error: {e:#}");
        let code = e
            .chain()
            .find_map(|c| c.downcast_ref::<Error>())
            .map_or(1, Error::exit_code);
        std::process::exit(code);
    }
}

fn run(cmd: Command) -> anyhow::Result<()> {
    match cmd {
        Command::Synth(a) => cmd_synth(a),
        Command::Render(a) => cmd_render(a),
        Command::Orient(a) => cmd_orient(a),
        Command::Demo(a) => cmd_demo(a),
        Command::Analyze(a) => cmd_analyze(a),
        Command::Info => cmd_info(),
        Command::Convert(a) => cmd_convert(a),
        Command::Model(a) => cmd_model(a),
        Command::Export(a) => cmd_export(a),
        Command::Import(a) => cmd_import(a),
    }
}

fn cmd_synth(a: SynthArgs) -> anyhow::Result<()> {
    if !(64..=4096).contains(&a.size) {
        return Err(Error::Invalid(format!("--size {} is outside 64..=4096", a.size)).into());
    }
    let sp = synth::SynthParams {
        style: a.style,
        seed: a.seed,
        width: a.size,
        height: a.size,
    };
    let what = if a.gt3d {
        let c = coif::synth::synth3d::synth3d(&sp);
        c.write(&a.out)?;
        format!(
            "3D ground truth: {} strands, camera yaw {:.1}°",
            c.gt.len(),
            c.yaw_deg
        )
    } else {
        synth::synth(&sp).write(&a.out)?;
        "2D ground truth".to_string()
    };
    println!(
        "synth: {} seed {} ({}x{}, {what}) -> {}",
        a.style,
        a.seed,
        a.size,
        a.size,
        a.out.display()
    );
    Ok(())
}

/// The photo and its optional mask (1 on hair), checked against each other and against the
/// Gabor kernel size.
fn load_image_and_mask(
    image: &Path,
    mask: Option<&Path>,
    ksize: u32,
) -> anyhow::Result<(image::RgbImage, Option<Vec<u8>>)> {
    let rgb = imgio::load_rgb(image)?;
    if rgb.width() < ksize || rgb.height() < ksize {
        return Err(Error::bad_file(
            image,
            format!(
                "image is {}x{} px, smaller than the {ksize}x{ksize} Gabor kernel",
                rgb.width(),
                rgb.height()
            ),
        )
        .into());
    }
    let m = match mask {
        Some(m) => Some(imgio::load_mask(m, rgb.width(), rgb.height(), image)?),
        None => None,
    };
    Ok((rgb, m))
}

/// Everything `coif orient` writes, computed before anything is written.
struct OrientRun {
    map: coif::analyze::orient::OrientMap,
    params: OrientParams,
    backend: String,
    seconds: f64,
}

fn orient_files(
    engine: &Engine,
    image: &Path,
    mask: Option<&Path>,
    params: &OrientParams,
) -> anyhow::Result<OrientRun> {
    let (rgb, mask_px) = load_image_and_mask(image, mask, params.kernel.ksize)?;
    let gray = GrayImage::from_rgb(&rgb);
    let t = Instant::now();
    let map = coif::analyze::orient::orient(engine, &gray, mask_px.as_deref(), params)
        .with_context(|| format!("orientation of {}", image.display()))?;
    Ok(OrientRun {
        map,
        params: *params,
        backend: engine.describe(),
        seconds: t.elapsed().as_secs_f64(),
    })
}

fn write_orient(out: &Path, image: &Path, r: &OrientRun) -> anyhow::Result<()> {
    coif::io::ensure_dir(out)?;
    let (w, h) = (r.map.width, r.map.height);
    let shape = [h as usize, w as usize];
    coif::io::npy::write_f32(&out.join("orientation.npy"), &shape, &r.map.theta)?;
    coif::io::npy::write_f32(&out.join("confidence.npy"), &shape, &r.map.confidence)?;
    coif::io::write_png(
        &out.join("orientation.png"),
        &coif::io::vis::orientation(w, h, &r.map.theta, &r.map.confidence),
    )?;
    coif::io::write_png(
        &out.join("confidence.png"),
        &coif::io::vis::confidence(w, h, &r.map.confidence),
    )?;
    let meta = serde_json::json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        "image": image.display().to_string(),
        "backend": r.backend,
        "params": r.params,
        "seconds": r.seconds,
        "orientation": "radians in [0, pi), x right, y down; NaN off the mask",
    });
    coif::io::write_atomic(
        &out.join("orient.json"),
        serde_json::to_string_pretty(&meta)?.as_bytes(),
    )?;
    Ok(())
}

fn cmd_orient(a: OrientArgs) -> anyhow::Result<()> {
    let params = a.opts.params();
    params.validate()?;
    let mut engine = Engine::new(a.backend.backend)?;
    if let Some(b) = a.max_binding_bytes {
        engine.set_max_binding_bytes(b);
    }
    let r = orient_files(&engine, &a.image, a.mask.as_deref(), &params)?;
    write_orient(&a.out, &a.image, &r)?;
    println!(
        "orient: {}x{} on {} in {:.2} s -> {}",
        r.map.width,
        r.map.height,
        r.backend,
        r.seconds,
        a.out.display()
    );
    Ok(())
}

fn cmd_demo(a: DemoArgs) -> anyhow::Result<()> {
    let engine = Engine::new(a.backend.backend)?;
    println!("coif demo on {}", engine.describe());
    let params = OrientParams::default();
    let bar = indicatif::ProgressBar::new(9).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
            .expect("static template"),
    );
    // 1. A synthetic portrait with ground truth.
    bar.set_message("synthesising the long-hair case");
    let case_dir = a.out.join("synth-long");
    let case = synth::synth(&synth::SynthParams {
        style: synth::Style::Long,
        seed: 1,
        width: 512,
        height: 512,
    });
    case.write(&case_dir)?;
    bar.inc(1);
    // 2. Orientation of the synthetic case, scored against its ground truth.
    bar.set_message("orientation of the synthetic case");
    let synth_out = a.out.join("orient-synth-long");
    let r = orient_files(
        &engine,
        &case_dir.join("image.png"),
        Some(&case_dir.join("mask.png")),
        &params,
    )?;
    write_orient(&synth_out, &case_dir.join("image.png"), &r)?;
    let err = coif::eval::metrics::orientation_error(&r.map, &case.gt_theta, &case.mask, 5);
    bar.inc(1);
    // 3. The embedded astronaut photo.
    bar.set_message("orientation of the astronaut photo");
    let astro_dir = a.out.join("astronaut");
    coif::io::ensure_dir(&astro_dir)?;
    let astro_png = astro_dir.join("image.png");
    coif::io::write_atomic(&astro_png, coif::io::assets::ASTRONAUT_PNG)?;
    let astro_strokes = astro_dir.join("strokes.json");
    coif::io::write_atomic(
        &astro_strokes,
        coif::io::assets::ASTRONAUT_STROKES.as_bytes(),
    )?;
    let astro_out = a.out.join("orient-astronaut");
    let r2 = orient_files(&engine, &astro_png, None, &params)?;
    write_orient(&astro_out, &astro_png, &r2)?;
    bar.inc(1);
    // 4. Directed hair: the synthetic case (mask segmented from its strokes) and the photo.
    let aparams = coif::analyze::AnalyzeParams::default();
    let mut lines = Vec::new();
    for (name, img, strokes) in [
        (
            "synth-long",
            case_dir.join("image.png"),
            case_dir.join("strokes.json"),
        ),
        ("astronaut", astro_png.clone(), astro_strokes.clone()),
    ] {
        bar.set_message(format!("directed hair of {name}"));
        let out = a.out.join(format!("analyze-{name}"));
        let t = Instant::now();
        let (rgb, an) = run_analyze(&engine, &img, &strokes, None, &aparams)?;
        write_analysis(&out, &img, &rgb, &an, &engine.describe())?;
        lines.push(format!(
            "  directed hair       {}  ({:.2} s; {} curve pieces, mask segmented from the strokes)",
            out.display(),
            t.elapsed().as_secs_f64(),
            an.traced.len()
        ));
        bar.inc(1);
    }
    // 5. 3D strand models: the synthetic case with its mask and landmarks, and the photo
    // from its strokes alone (mask segmented, default head fit).
    let mparams = coif::model::ModelParams::default();
    for (name, img, strokes, mask, landmarks) in [
        (
            "synth-long",
            case_dir.join("image.png"),
            case_dir.join("strokes.json"),
            Some(case_dir.join("mask.png")),
            Some(case_dir.join("landmarks.json")),
        ),
        (
            "astronaut",
            astro_png.clone(),
            astro_strokes.clone(),
            None,
            None,
        ),
    ] {
        bar.set_message(format!("3D strands of {name}"));
        let out = a.out.join(format!("model-{name}"));
        let t = Instant::now();
        let (rgb, an) = run_analyze(&engine, &img, &strokes, mask.as_deref(), &mparams.analyze)?;
        let lm = match &landmarks {
            Some(l) => Some(coif::io::annot::Landmarks::load(l, Some(rgb.dimensions()))?),
            None => None,
        };
        write_analysis(&out, &img, &rgb, &an, &engine.describe())?;
        let m = coif::model::model_from_analysis(&engine, &rgb, an, lm.as_ref(), &mparams)?;
        write_model(&out, &img, &rgb, &m, &mparams, &engine)?;
        lines.push(format!(
            "  3D strands          {}  ({:.2} s; {} strands, preview.png)",
            out.display(),
            t.elapsed().as_secs_f64(),
            m.strands.len()
        ));
        bar.inc(1);
        // 6. Renders of the model: the original view, a novel view and a recolouring.
        bar.set_message(format!("rendering {name}"));
        let t = Instant::now();
        let rm = coif::render::RenderModel::from_model(&m, &rgb, &out);
        let mut dyed = coif::render::RenderParams::default();
        (dyed.shade.hue, dyed.shade.saturation, dyed.shade.value) = (30.0, 1.2, 0.9);
        dyed.shade.amount = 0.6;
        let views = [
            ("render.png", coif::render::RenderParams::default()),
            (
                "render_yaw25.png",
                coif::render::RenderParams {
                    yaw_deg: 25.0,
                    pitch_deg: -5.0,
                    ..Default::default()
                },
            ),
            ("render_dyed.png", dyed),
        ];
        for (file, p) in &views {
            let r = coif::render::render(&engine, &rm, p)?;
            coif::render::write(&out.join(file), &r, p, false)?;
        }
        lines.push(format!(
            "  renders             {}  ({:.2} s; render.png, render_yaw25.png, render_dyed.png)",
            out.display(),
            t.elapsed().as_secs_f64()
        ));
        bar.inc(1);
    }
    bar.finish_and_clear();
    println!(
        "  synthetic case      {}  (image, mask, strokes, ground truth)",
        case_dir.display()
    );
    println!(
        "  its orientation     {}  ({:.2} s; mean error {:.2} deg over {} hair px >= 5 px inside the mask)",
        synth_out.display(),
        r.seconds,
        err.mean_deg,
        err.count
    );
    println!(
        "  astronaut photo     {}  ({:.2} s)",
        astro_out.display(),
        r2.seconds
    );
    for l in lines {
        println!("{l}");
    }
    Ok(())
}

#[derive(Args)]
struct AnalyzeArgs {
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
}

/// strokes.json, or strokes drawn elsewhere: an .svg, or a labelme .json (it has "shapes").
fn load_strokes(path: &Path, size: (u32, u32)) -> anyhow::Result<coif::io::annot::Strokes> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let imported = if ext == "svg" {
        Some(coif::io::import::strokes_from_svg(path)?)
    } else {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let labelme = serde_json::from_str::<serde_json::Value>(&text)
            .ok()
            .is_some_and(|v| v.get("shapes").is_some() && v.get("strokes").is_none());
        if labelme {
            Some(coif::io::import::strokes_from_labelme(path)?)
        } else {
            None
        }
    };
    match imported {
        Some(s) => {
            s.validate(Some(size))
                .map_err(|m| Error::bad_file(path, m))?;
            Ok(s)
        }
        None => Ok(coif::io::annot::Strokes::load(path, Some(size))?),
    }
}

fn write_analysis(
    out: &Path,
    image: &Path,
    rgb: &image::RgbImage,
    an: &coif::analyze::Analysis,
    backend: &str,
) -> anyhow::Result<()> {
    use coif::io::vis;
    coif::io::ensure_dir(out)?;
    let (w, h) = (an.width, an.height);
    let shape = [h as usize, w as usize];
    let mask_img = image::GrayImage::from_fn(w, h, |x, y| {
        image::Luma([if an.mask[(y * w + x) as usize] != 0 {
            255
        } else {
            0
        }])
    });
    coif::io::write_png(&out.join("mask.png"), &mask_img)?;
    coif::io::npy::write_f32(&out.join("orientation.npy"), &shape, &an.orient.theta)?;
    coif::io::npy::write_f32(&out.join("confidence.npy"), &shape, &an.orient.confidence)?;
    coif::io::npy::write_f32(
        &out.join("direction.npy"),
        &[h as usize, w as usize, 2],
        &an.direction,
    )?;
    let mut curves: Vec<serde_json::Value> = an
        .resolved
        .curves
        .iter()
        .map(|c| serde_json::json!({"points": c.points, "source": "traced"}))
        .collect();
    curves.extend(
        an.strokes
            .iter()
            .map(|s| serde_json::json!({"points": s, "source": "stroke"})),
    );
    let doc = serde_json::json!({"version": 1, "curves": curves});
    coif::io::write_atomic(
        &out.join("curves.json"),
        serde_json::to_string(&doc)?.as_bytes(),
    )?;
    let back = vis::dimmed(rgb, 0.55);
    let before: Vec<&[[f32; 2]]> = an.traced.iter().map(|c| c.points.as_slice()).collect();
    let after: Vec<&[[f32; 2]]> = an
        .resolved
        .curves
        .iter()
        .map(|c| c.points.as_slice())
        .collect();
    coif::io::write_png(
        &out.join("curves_before.png"),
        &vis::directed_curves(&back, &before, 1.5),
    )?;
    let mut after_img = vis::directed_curves(&back, &after, 1.5);
    for s in &an.strokes {
        vis::draw_polyline(&mut after_img, s, 4.0, |_| image::Rgb([255, 255, 255]));
    }
    let sdraw: Vec<&[[f32; 2]]> = an.strokes.iter().map(|s| s.as_slice()).collect();
    let after_img = vis::directed_curves(&after_img, &sdraw, 2.0);
    coif::io::write_png(&out.join("curves_after.png"), &after_img)?;
    coif::io::write_png(
        &out.join("direction.png"),
        &vis::direction_field(&back, &an.direction),
    )?;
    coif::io::write_png(
        &out.join("orientation.png"),
        &vis::orientation(w, h, &an.orient.theta, &an.orient.confidence),
    )?;
    let meta = serde_json::json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        "image": image.display().to_string(),
        "backend": backend,
        "mask": if an.mask_computed { "segmented from the strokes" } else { "given" },
        "curves": an.traced.len(),
        "unreachable_curves": an.resolved.unreachable.len(),
        "warnings": an.warnings,
        "seconds": an.timings.iter().map(|(k, v)| (k.to_string(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
        "direction": "unit growth direction, H x W x 2, x right, y down, NaN off hair",
    });
    coif::io::write_atomic(
        &out.join("analyze.json"),
        serde_json::to_string_pretty(&meta)?.as_bytes(),
    )?;
    Ok(())
}

fn run_analyze(
    engine: &Engine,
    image: &Path,
    strokes: &Path,
    mask: Option<&Path>,
    params: &coif::analyze::AnalyzeParams,
) -> anyhow::Result<(image::RgbImage, coif::analyze::Analysis)> {
    let (rgb, m) = load_image_and_mask(image, mask, params.orient.kernel.ksize)?;
    let s = load_strokes(strokes, rgb.dimensions())?;
    let an = coif::analyze::analyze(engine, &rgb, &s, m, params)
        .with_context(|| format!("analysis of {} with {}", image.display(), strokes.display()))?;
    for w in &an.warnings {
        log::warn!("{w}");
        eprintln!("coif: warning: {w}");
    }
    Ok((rgb, an))
}

fn cmd_analyze(a: AnalyzeArgs) -> anyhow::Result<()> {
    let mut params = coif::analyze::AnalyzeParams {
        orient: a.opts.params(),
        ..Default::default()
    };
    params.orient.validate()?;
    params.resolve.radius = a.radius;
    params.resolve.stroke_weight = a.stroke_weight;
    let positive = |v: f32| v.is_finite() && v > 0.0;
    if !positive(a.radius) || !positive(a.stroke_weight) {
        return Err(Error::Invalid("--radius and --stroke-weight must be positive".into()).into());
    }
    let engine = Engine::new(a.backend.backend)?;
    let t = Instant::now();
    let (rgb, an) = run_analyze(&engine, &a.image, &a.strokes, a.mask.as_deref(), &params)?;
    write_analysis(&a.out, &a.image, &rgb, &an, &engine.describe())?;
    println!(
        "analyze: mask {}, {} curve pieces ({} unreachable from strokes) -> {} ({:.2} s on {})",
        if an.mask_computed {
            "segmented"
        } else {
            "given"
        },
        an.traced.len(),
        an.resolved.unreachable.len(),
        a.out.display(),
        t.elapsed().as_secs_f64(),
        engine.describe()
    );
    Ok(())
}

fn cmd_model(a: ModelArgs) -> anyhow::Result<()> {
    let mut p = coif::model::ModelParams {
        seed: a.seed,
        roots: a.roots,
        ..Default::default()
    };
    p.volume.cells = a.cells;
    p.refine.max_iterations = a.refine;
    let engine = Engine::new(a.backend.backend)?;
    let t = Instant::now();
    let (rgb, an) = run_analyze(&engine, &a.image, &a.strokes, a.mask.as_deref(), &p.analyze)?;
    let landmarks = match &a.landmarks {
        Some(l) => Some(coif::io::annot::Landmarks::load(l, Some(rgb.dimensions()))?),
        None => None,
    };
    write_analysis(&a.out, &a.image, &rgb, &an, &engine.describe())?;
    let m = coif::model::model_from_analysis(&engine, &rgb, an, landmarks.as_ref(), &p)
        .with_context(|| format!("3D model of {}", a.image.display()))?;
    write_model(&a.out, &a.image, &rgb, &m, &p, &engine)?;
    println!(
        "model: {} strands ({} grown from {} roots on hair, {} added by refinement), {} H cells, \
         field {} cycles to {:.1e} -> {} ({:.2} s on {})",
        m.strands.len(),
        m.grown_strands,
        m.roots_kept,
        m.strands.len() - m.grown_strands,
        m.h_cells,
        m.solve.cycles,
        m.solve.rel_residual,
        a.out.display(),
        t.elapsed().as_secs_f64(),
        engine.describe()
    );
    for (k, v) in &m.timings {
        println!("  {k:<18} {:>8.1} ms", v * 1e3);
    }
    Ok(())
}

/// `model.json`, `strands.hair` and `preview.png` of a model (the analysis is written by
/// the caller).
fn write_model(
    out: &Path,
    image: &Path,
    rgb: &image::RgbImage,
    m: &coif::model::Model,
    p: &coif::model::ModelParams,
    engine: &Engine,
) -> anyhow::Result<()> {
    coif::io::strands::write(&out.join("strands.hair"), &m.strands)?;
    // The photo travels with the model, so `coif render` needs nothing else.
    coif::io::write_png(&out.join("photo.png"), rgb)?;
    let figures = coif::model::figures(m);
    let meta = serde_json::json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        "image": image.display().to_string(),
        "width": m.analysis.width,
        "height": m.analysis.height,
        "units": "model space in metres, y up, the face looks toward +z",
        "image_from_model": m.camera.image_from_model(),
        "image_from_model_doc": "rows map homogeneous model points (x, y, z, 1) to image x (px, right), image y (px, down) and depth (px, toward the camera)",
        "camera": m.camera,
        "head": { "params": m.head.params(), "fit": m.fit },
        "grid": m.grid,
        "h_cells": m.h_cells,
        "constraints": { "curves": m.constraints_curve, "scalp": m.constraints_scalp },
        "field_solve": m.solve,
        "roots": { "drawn": m.roots_drawn, "on_hair": m.roots_kept },
        "strands": { "grown": m.grown_strands, "final": m.strands.len(), "vertices": m.strands.points.len() },
        "refinement": m.refine,
        "figures": figures,
        "params": p,
        "backend": engine.describe(),
        "seconds": m.timings.iter().map(|(k, v)| (k.to_string(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
    });
    coif::io::write_atomic(
        &out.join("model.json"),
        serde_json::to_string_pretty(&meta)?.as_bytes(),
    )?;
    // Preview: strands projected over the dimmed photo, coloured by their projected growth
    // direction (the hue ring of the analysis pictures); a subset keeps it legible.
    let mut pic = coif::io::vis::dimmed(rgb, 0.35);
    // Far strands first, so nearer ones cover them (painter's order on mean depth).
    let view = &m.strands_image;
    let off = view.offsets();
    let strand = |i: usize| &view.points[off[i]..off[i + 1]];
    let every = (view.len() / 6000).max(1);
    let mut order: Vec<(f32, usize)> = (0..view.len())
        .step_by(every)
        .map(|i| {
            let s = strand(i);
            (s.iter().map(|q| q[2]).sum::<f32>() / s.len() as f32, i)
        })
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    for s in order.iter().map(|&(_, i)| strand(i)) {
        let pts: Vec<[f32; 2]> = s.iter().map(|q| [q[0], q[1]]).collect();
        coif::io::vis::draw_polyline(&mut pic, &pts, 1.0, |k| {
            coif::io::vis::direction_colour(pts[k + 1][0] - pts[k][0], pts[k + 1][1] - pts[k][1])
        });
    }
    coif::io::vis::hue_ring(&mut pic);
    coif::io::write_png(&out.join("preview.png"), &pic)?;
    Ok(())
}

fn cmd_render(a: RenderArgs) -> anyhow::Result<()> {
    // Refuse a missing output folder before any work.
    if let Some(parent) = a.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        if !parent.is_dir() {
            anyhow::bail!(
                "{}: the output folder {} does not exist",
                a.out.display(),
                parent.display()
            );
        }
    }
    let mut p = coif::render::RenderParams {
        yaw_deg: a.yaw,
        pitch_deg: a.pitch,
        roll_deg: a.roll,
        distance: a.distance,
        scale: a.scale,
        size: a.size,
        strands_only: a.strands_only,
        background: a.background,
        colour_spacing_px: a.colour_spacing,
        colour: a.colour,
        ..Default::default()
    };
    p.raster.strand_width = a.width;
    p.shade.hue = a.hue;
    p.shade.saturation = a.saturation;
    p.shade.value = a.value;
    p.shade.amount = a.highlight;
    p.shade.model = match a.shading {
        ShadingArg::Marschner => coif::render::shade::ShadingModel::Marschner,
        ShadingArg::KajiyaKay => coif::render::shade::ShadingModel::KajiyaKay,
    };
    if !a.light.is_empty() {
        p.shade.lights = a
            .light
            .iter()
            .map(|l| l.parse::<coif::render::shade::Light>())
            .collect::<Result<_, _>>()
            .map_err(|e| anyhow::anyhow!("--light: {e}"))?;
    }
    p.inpaint.seed = a.seed;
    p.head_texture.inpaint.seed = a.seed;
    let engine = Engine::new(a.backend.backend)?;
    let t = Instant::now();
    let m = coif::render::RenderModel::load(&a.model)?;
    let r = coif::render::render(&engine, &m, &p)
        .with_context(|| format!("rendering {}", a.model.display()))?;
    let side = coif::render::write(&a.out, &r, &p, a.sixteen)?;
    println!(
        "render: {} strands, {}x{} ({}) -> {} ({:.2} s on {}; settings in {})",
        r.report.strands,
        r.width,
        r.height,
        if p.is_original_view() {
            "original view"
        } else {
            "novel view"
        },
        a.out.display(),
        t.elapsed().as_secs_f64(),
        engine.describe(),
        side.display()
    );
    for (k, v) in &r.report.seconds {
        println!("  {k:<18} {:>8.1} ms", v * 1e3);
    }
    Ok(())
}

fn cmd_export(a: ExportArgs) -> anyhow::Result<()> {
    coif::io::strands::Format::from_path(&a.to)?;
    let src = a.model.join("strands.hair");
    let s = coif::io::strands::read(&src)?;
    coif::io::strands::write(&a.to, &s)?;
    println!(
        "export: {} strands, {} vertices: {} -> {}",
        s.counts.len(),
        s.points.len(),
        src.display(),
        a.to.display()
    );
    Ok(())
}

fn cmd_import(a: ImportArgs) -> anyhow::Result<()> {
    let s = coif::io::strands::read(&a.input)?;
    coif::io::ensure_dir(&a.out)?;
    coif::io::strands::write(&a.out.join("strands.hair"), &s)?;
    let (lo, hi) = s.bounds();
    let meta = serde_json::json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        "imported_from": a.input.display().to_string(),
        "strands": { "final": s.counts.len(), "vertices": s.points.len() },
        "bounds": [lo, hi],
        "image_from_model": serde_json::Value::Null,
    });
    coif::io::write_atomic(
        &a.out.join("model.json"),
        serde_json::to_string_pretty(&meta)?.as_bytes(),
    )?;
    println!(
        "import: {} strands, {} vertices: {} -> {}",
        s.counts.len(),
        s.points.len(),
        a.input.display(),
        a.out.display()
    );
    Ok(())
}

fn cmd_convert(a: ConvertArgs) -> anyhow::Result<()> {
    // Check the output format before reading, so a typo fails fast.
    coif::io::strands::Format::from_path(&a.output)?;
    let s = coif::io::strands::read(&a.input)?;
    coif::io::strands::write(&a.output, &s)?;
    println!(
        "convert: {} strands, {} vertices: {} -> {}",
        s.counts.len(),
        s.points.len(),
        a.input.display(),
        a.output.display()
    );
    Ok(())
}

fn cmd_info() -> anyhow::Result<()> {
    let adapters = coif::gpu::list_adapters();
    println!("coif {}", env!("CARGO_PKG_VERSION"));
    println!("CPU threads: {}", rayon::current_num_threads());
    if adapters.is_empty() {
        println!(
            "GPU adapters: none (install mesa-vulkan-drivers for lavapipe, or use --backend cpu)"
        );
    } else {
        println!("GPU adapters:");
        for i in &adapters {
            println!("  {}", coif::gpu::describe(i));
        }
    }
    let auto = if coif::gpu::hardware_gpu_present() {
        "gpu (a hardware adapter is present)"
    } else {
        "cpu (no hardware adapter; lavapipe is used only with --backend gpu)"
    };
    println!("--backend auto chooses: {auto}");
    if !adapters.is_empty() {
        match coif::gpu::GpuContext::new() {
            Ok(g) => {
                println!("--backend gpu opens: {}", coif::gpu::describe(&g.info));
                println!(
                    "  max storage binding {} B, max buffer {} B, max workgroups per dimension {}",
                    g.limits.max_storage_buffer_binding_size,
                    g.limits.max_buffer_size,
                    g.limits.max_compute_workgroups_per_dimension
                );
            }
            Err(e) => println!("--backend gpu fails: {e}"),
        }
    }
    Ok(())
}
