//! Every command as a job: the inputs and settings of one run of a pipeline, and one
//! [`run`] that reads the inputs, runs the pipeline and writes its files. The command line
//! only turns arguments into jobs; a batch run or the demo is a list of them.

use crate::analyze::orient::OrientParams;
use crate::analyze::{self, AnalyzeParams};
use crate::edit;
use crate::error::Error;
use crate::eval::metrics::orientation_error;
use crate::gpu::engine::Engine;
use crate::hair::scene::Scene;
use crate::io::{assets, ensure_dir, images, npy, strands, write_atomic};
use crate::model::{self, ModelParams};
use crate::render::RenderParams;
use crate::sim::{self, SimParams};
use crate::synth::{self, synth3d, SynthParams};
use crate::timings::{record_all, stage};
use anyhow::Context;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod cartoon;
mod command;
pub mod memory;
mod render_job;
mod sketch;
mod sketch_edit;
mod staged;
mod video;

use cartoon::run_cartoon;
pub use cartoon::CartoonJob;
use render_job::{render_frames, run_render};
use sketch::{run_sketch, run_sketch_convert, run_synth_hair};
pub use sketch::{HairRegion, SketchConvertJob, SketchJob, SynthHairJob};
use sketch_edit::run_sketch_edit;
pub use sketch_edit::{EditStep, SketchEditJob};
use video::{run_synth_video, run_transfer, run_video};
pub use video::{ClipSource, SynthVideoJob, TransferJob, VideoJob};

/// One run of a pipeline.
// A run holds a handful of jobs: their size does not matter, and boxes would only add
// noise wherever a job is built.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Job {
    Synth(SynthJob),
    SynthVideo(SynthVideoJob),
    Unpack(UnpackJob),
    Orient(OrientJob),
    Analyze(AnalyzeJob),
    Model(ModelJob),
    Render(RenderJob),
    Simulate(SimulateJob),
    Edit(EditJob),
    Export(ExportJob),
    Import(ImportJob),
    Convert(ConvertJob),
    Video(VideoJob),
    Transfer(TransferJob),
    Sketch(SketchJob),
    SketchConvert(SketchConvertJob),
    SynthHair(SynthHairJob),
    Cartoon(CartoonJob),
    SketchEdit(SketchEditJob),
}

/// A synthetic portrait with its ground truth (`coif synth`).
#[derive(Clone, Debug)]
pub struct SynthJob {
    pub out: PathBuf,
    pub params: SynthParams,
    /// 3D ground truth: strands grown on the parametric head, drawn through a known camera.
    pub gt3d: bool,
    /// Texture variation of the 2D portrait's hair (the default: the usual look).
    pub texture: synth::Texture,
}

/// The embedded astronaut photo and its strokes, written to a folder.
#[derive(Clone, Debug)]
pub struct UnpackJob {
    pub out: PathBuf,
}

/// Orientation and confidence maps (`coif orient`).
#[derive(Clone, Debug)]
pub struct OrientJob {
    pub image: PathBuf,
    pub mask: Option<PathBuf>,
    pub out: PathBuf,
    pub params: OrientParams,
    /// A `coif synth` folder whose `gt_theta.npy` and `mask.png` score the result.
    pub truth: Option<PathBuf>,
}

/// Directed hair (`coif analyze`).
#[derive(Clone, Debug)]
pub struct AnalyzeJob {
    pub image: PathBuf,
    pub strokes: PathBuf,
    pub mask: Option<PathBuf>,
    pub out: PathBuf,
    pub params: AnalyzeParams,
    /// A hair mask drawn by hand to score the result's mask against (`mask_agreement.json`).
    pub reference_mask: Option<PathBuf>,
}

/// Single-view 3D strands (`coif model`).
#[derive(Clone, Debug)]
pub struct ModelJob {
    pub image: PathBuf,
    pub strokes: PathBuf,
    pub mask: Option<PathBuf>,
    pub landmarks: Option<PathBuf>,
    /// A hair mask drawn by hand to score the mask against (`mask_agreement.json`).
    pub reference_mask: Option<PathBuf>,
    pub out: PathBuf,
    pub params: ModelParams,
}

/// A render of a model folder (`coif render`).
#[derive(Clone, Debug)]
pub struct RenderJob {
    pub model: PathBuf,
    pub out: PathBuf,
    pub params: RenderParams,
    /// 16-bit PNG.
    pub sixteen: bool,
}

/// A simulated sequence of a model folder (`coif simulate`).
#[derive(Clone, Debug)]
pub struct SimulateJob {
    pub model: PathBuf,
    pub out: PathBuf,
    pub params: SimParams,
}

/// A comb or a cut of a model folder's strands (`coif edit`).
#[derive(Clone, Debug)]
pub struct EditJob {
    pub model: PathBuf,
    pub out: PathBuf,
    pub tool: EditTool,
    /// Radius of influence, image px (C13: 32; a cut with 0 is clean).
    pub radius: f32,
    /// Level of the strand hierarchy the strokes act on (0: the strands).
    pub level: usize,
}

/// Which edit, with its strokes file (`strokes.json` schema, strokes of that kind).
#[derive(Clone, Debug)]
pub enum EditTool {
    Comb { strokes: PathBuf },
    Cut { strokes: PathBuf, seed: u64 },
}

/// A model folder's strands as a strand file (`coif export`).
#[derive(Clone, Debug)]
pub struct ExportJob {
    pub model: PathBuf,
    pub to: PathBuf,
}

/// A strand file into a model folder (`coif import`).
#[derive(Clone, Debug)]
pub struct ImportJob {
    pub input: PathBuf,
    pub out: PathBuf,
}

/// A strand file into another format (`coif convert`).
#[derive(Clone, Debug)]
pub struct ConvertJob {
    pub input: PathBuf,
    pub output: PathBuf,
}

/// What a job did: one summary line, indented detail lines, and warnings that did not stop
/// it.
#[derive(Clone, Debug, Default)]
pub struct Report {
    pub summary: String,
    pub details: Vec<String>,
    pub warnings: Vec<String>,
}

impl Job {
    /// Whether the job runs passes (and so wants the engine the user chose).
    pub fn needs_engine(&self) -> bool {
        matches!(
            self,
            Job::Orient(_)
                | Job::Analyze(_)
                | Job::Model(_)
                | Job::Render(_)
                | Job::Simulate(_)
                | Job::Edit(_)
                | Job::Video(_)
                | Job::Transfer(_)
                | Job::Sketch(_)
                | Job::SynthHair(_)
                | Job::Cartoon(_)
        )
    }

    /// A short label for progress bars.
    pub fn label(&self) -> String {
        let (what, path) = match self {
            Job::Synth(j) => ("synth", &j.out),
            Job::SynthVideo(j) => ("synth-video", &j.out),
            Job::Unpack(j) => ("unpack", &j.out),
            Job::Orient(j) => ("orient", &j.out),
            Job::Analyze(j) => ("analyze", &j.out),
            Job::Model(j) => ("model", &j.out),
            Job::Render(j) => ("render", &j.out),
            Job::Simulate(j) => ("simulate", &j.out),
            Job::Edit(j) => ("edit", &j.out),
            Job::Export(j) => ("export", &j.to),
            Job::Import(j) => ("import", &j.out),
            Job::Convert(j) => ("convert", &j.output),
            Job::Video(j) => ("video", &j.out),
            Job::Transfer(j) => ("transfer", &j.out),
            Job::Sketch(j) => ("sketch", &j.out),
            Job::SketchConvert(j) => ("sketch-convert", &j.out),
            Job::SynthHair(j) => ("synth-hair", &j.out),
            Job::Cartoon(j) => ("cartoon", &j.out),
            Job::SketchEdit(j) => ("sketch-edit", &j.out),
        };
        format!("{what} {}", path.display())
    }
}

/// Runs one job on `engine`; a job that writes a folder writes it all or not at all (see
/// [`staged`]).
pub fn run(engine: &Engine, job: &Job) -> anyhow::Result<Report> {
    memory::check(engine, job)?;
    staged::run(engine, job)
}

/// Runs one job writing straight to its outputs.
fn run_here(engine: &Engine, job: &Job) -> anyhow::Result<Report> {
    match job {
        Job::Synth(j) => run_synth(j),
        Job::SynthVideo(j) => run_synth_video(j),
        Job::Unpack(j) => run_unpack(j),
        Job::Orient(j) => run_orient(engine, j),
        Job::Analyze(j) => run_analyze(engine, j),
        Job::Model(j) => run_model(engine, j),
        Job::Render(j) => run_render(engine, j),
        Job::Simulate(j) => run_simulate(engine, j),
        Job::Edit(j) => run_edit(engine, j),
        Job::Export(j) => run_export(j),
        Job::Import(j) => run_import(j),
        Job::Video(j) => run_video(engine, j),
        Job::Transfer(j) => run_transfer(engine, j),
        Job::Sketch(j) => run_sketch(engine, j),
        Job::SketchConvert(j) => run_sketch_convert(j),
        Job::SynthHair(j) => run_synth_hair(engine, j),
        Job::Cartoon(j) => run_cartoon(engine, j),
        Job::SketchEdit(j) => run_sketch_edit(j),
        Job::Convert(j) => run_convert(j),
    }
}

/// Runs jobs in order with a progress bar (hidden when stderr is not a terminal); stops at
/// the first failure, naming the job.
pub fn run_all(engine: &Engine, jobs: &[Job]) -> anyhow::Result<Vec<Report>> {
    let bar = indicatif::ProgressBar::new(jobs.len() as u64).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
            .expect("static template"),
    );
    let mut reports = Vec::with_capacity(jobs.len());
    for job in jobs {
        crate::interrupt::check()?;
        bar.set_message(job.label());
        // Each job's stages under its command's name (`--timings`).
        let (r, stages) = crate::timings::collect(|| run(engine, job));
        crate::timings::record_prefixed(job.command(), &stages);
        let r = r.with_context(|| job.label())?;
        reports.push(r);
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(reports)
}

/// The main job on the embedded inputs: a synthetic case with ground truth and the astronaut
/// photo, each through orientation, directed hair, 3D strands and three renders (the
/// original view, a novel view and a recolouring); then a comb, a cut and a short wind clip
/// of the photo's hair; then a short synthetic clip tracked and recoloured (`coif video`);
/// then the photo's hair as a CZ06 sketch, synthesised back from the sketch alone and drawn
/// as a cartoon.
pub fn demo(out: &Path) -> Vec<Job> {
    let case = out.join("synth-long");
    let astro = out.join("astronaut");
    let mut jobs = vec![
        Job::Synth(SynthJob {
            out: case.clone(),
            params: SynthParams {
                style: synth::Style::Long,
                seed: 1,
                width: 512,
                height: 512,
            },
            gt3d: false,
            texture: Default::default(),
        }),
        Job::Orient(OrientJob {
            image: case.join("image.png"),
            mask: Some(case.join("mask.png")),
            out: out.join("orient-synth-long"),
            params: OrientParams::default(),
            truth: Some(case.clone()),
        }),
        Job::Unpack(UnpackJob { out: astro.clone() }),
        Job::Orient(OrientJob {
            image: astro.join("image.png"),
            mask: None,
            out: out.join("orient-astronaut"),
            params: OrientParams::default(),
            truth: None,
        }),
    ];
    // Directed hair with the mask segmented from the strokes, for both.
    for (name, dir) in [("synth-long", &case), ("astronaut", &astro)] {
        jobs.push(Job::Analyze(AnalyzeJob {
            image: dir.join("image.png"),
            strokes: dir.join("strokes.json"),
            mask: None,
            out: out.join(format!("analyze-{name}")),
            params: AnalyzeParams::default(),
            reference_mask: None,
        }));
    }
    // 3D strands: the synthetic case with its mask and landmarks, the photo from its strokes
    // alone (mask segmented, default head fit).
    let mut dyed = RenderParams::default();
    (dyed.shade.hue, dyed.shade.saturation, dyed.shade.value) = (30.0, 1.2, 0.9);
    dyed.shade.amount = 0.6;
    let views = [
        ("render.png", RenderParams::default()),
        (
            "render_yaw25.png",
            RenderParams {
                yaw_deg: 25.0,
                pitch_deg: -5.0,
                ..Default::default()
            },
        ),
        ("render_dyed.png", dyed),
    ];
    for (name, dir, truth) in [("synth-long", &case, true), ("astronaut", &astro, false)] {
        let model = out.join(format!("model-{name}"));
        jobs.push(Job::Model(ModelJob {
            image: dir.join("image.png"),
            strokes: dir.join("strokes.json"),
            mask: truth.then(|| dir.join("mask.png")),
            landmarks: truth.then(|| dir.join("landmarks.json")),
            reference_mask: None,
            out: model.clone(),
            params: ModelParams::default(),
        }));
        for (file, p) in &views {
            jobs.push(Job::Render(RenderJob {
                model: model.clone(),
                out: model.join(file),
                params: p.clone(),
                sixteen: false,
            }));
        }
    }
    // A comb and a cut of the photo's hair, each rendered into the photo.
    for (name, tool, radius) in [
        (
            "comb",
            EditTool::Comb {
                strokes: astro.join("comb.json"),
            },
            32.0,
        ),
        (
            "cut",
            EditTool::Cut {
                strokes: astro.join("cut.json"),
                seed: 1,
            },
            32.0,
        ),
    ] {
        let dir = out.join(format!("edit-astronaut-{name}"));
        jobs.push(Job::Edit(EditJob {
            model: out.join("model-astronaut"),
            out: dir.clone(),
            tool,
            radius,
            level: 0,
        }));
        jobs.push(Job::Render(RenderJob {
            model: dir.clone(),
            out: dir.join("render.png"),
            params: RenderParams::default(),
            sixteen: false,
        }));
    }
    // A short wind clip of the photo's hair, every frame rendered into the photo.
    let wind = out.join("sim-astronaut-wind");
    jobs.push(Job::Simulate(SimulateJob {
        model: out.join("model-astronaut"),
        out: wind.clone(),
        params: SimParams {
            frames: 10,
            wind: 0.6,
            ..Default::default()
        },
    }));
    jobs.push(Job::Render(RenderJob {
        model: wind.clone(),
        out: wind.join("render"),
        params: RenderParams::default(),
        sixteen: false,
    }));
    // A short synthetic clip: the model of its first frame tracked through it, and every
    // frame recoloured over its own photo. Small (128², 12 frames, 3000 roots) so that it
    // adds about half a minute on the cpu backend.
    let clip = out.join("synth-video-long");
    let mut vp = synth::video::VideoParams::new(synth::Style::Long, 1, 128, 12);
    vp.strands = 300;
    jobs.push(Job::SynthVideo(SynthVideoJob {
        out: clip.clone(),
        params: vp,
    }));
    let tracked = out.join("video-synth-long");
    let r = clip.join("reference");
    jobs.push(Job::Video(VideoJob {
        source: ClipSource::Frames(clip.join("frames")),
        ann: crate::video::run::Annotations {
            reference: 0,
            strokes: r.join("strokes.json"),
            mask: Some(r.join("mask.png")),
            landmarks: Some(r.join("landmarks.json")),
            landmark_dir: None,
            points: None,
        },
        out: tracked.clone(),
        model: ModelParams {
            roots: 3000,
            ..Default::default()
        },
        track: Default::default(),
    }));
    jobs.push(Job::Render(RenderJob {
        model: tracked.clone(),
        out: tracked.join("render_dyed"),
        params: views[2].1.clone(),
        sixteen: false,
    }));
    // The astronaut's hair as a sketch of a few hundred bytes (CZ06), and back: an image
    // synthesised from the sketch alone, over the photo.
    let sk = out.join("sketch-astronaut");
    jobs.push(Job::Sketch(SketchJob {
        image: astro.join("image.png"),
        region: HairRegion::Strokes(astro.join("strokes.json")),
        strokes: None,
        out: sk.clone(),
        params: Default::default(),
    }));
    jobs.push(Job::SynthHair(SynthHairJob {
        sketch: sk.join("hair.czs"),
        out: sk.join("synth.png"),
        over: Some(astro.join("image.png")),
        layers: None,
        params: Default::default(),
    }));
    // Its cartoon (CZ06 Fig. 17): brush strokes coloured by growth direction, over the photo
    // and as an SVG on paper.
    let cartoon = crate::sketch::cartoon::CartoonParams {
        style: crate::sketch::cartoon::Style::Direction,
        ..Default::default()
    };
    for (file, over) in [
        ("cartoon.png", Some(astro.join("image.png"))),
        ("cartoon.svg", None),
    ] {
        jobs.push(Job::Cartoon(CartoonJob {
            sketch: sk.join("hair.czs"),
            out: sk.join(file),
            over,
            params: cartoon,
        }));
    }
    jobs
}

fn run_synth(j: &SynthJob) -> anyhow::Result<Report> {
    let p = &j.params;
    for side in [p.width, p.height] {
        if !(64..=4096).contains(&side) {
            return Err(Error::Invalid(format!("--size {side} is outside 64..=4096")).into());
        }
    }
    if j.gt3d && !j.texture.is_plain() {
        let t = &j.texture;
        return Err(
            Error::Invalid(format!("--texture {t} applies to 2D only (drop --gt3d)")).into(),
        );
    }
    if j.gt3d && !p.style.has_3d() {
        return Err(Error::Invalid(format!(
            "--style {} has no 3D ground truth (drop --gt3d)",
            p.style
        ))
        .into());
    }
    let what = if j.gt3d {
        let c = synth3d::synth3d(p);
        c.write(&j.out)?;
        format!(
            "3D ground truth: {} strands, camera yaw {:.1}°",
            c.gt.len(),
            c.yaw_deg
        )
    } else {
        synth::synth_textured(p, &j.texture).write(&j.out)?;
        format!("2D ground truth, texture {}", j.texture)
    };
    Ok(Report {
        summary: format!(
            "synth: {} seed {} ({}x{}, {what}) -> {}",
            p.style,
            p.seed,
            p.width,
            p.height,
            j.out.display()
        ),
        ..Default::default()
    })
}

fn run_unpack(j: &UnpackJob) -> anyhow::Result<Report> {
    ensure_dir(&j.out)?;
    write_atomic(&j.out.join("image.png"), assets::ASTRONAUT_PNG)?;
    write_atomic(
        &j.out.join("strokes.json"),
        assets::ASTRONAUT_STROKES.as_bytes(),
    )?;
    write_atomic(&j.out.join("comb.json"), assets::ASTRONAUT_COMB.as_bytes())?;
    write_atomic(&j.out.join("cut.json"), assets::ASTRONAUT_CUT.as_bytes())?;
    Ok(Report {
        summary: format!(
            "unpack: the astronaut photo, its strokes and comb and cut strokes -> {}",
            j.out.display()
        ),
        ..Default::default()
    })
}

fn run_orient(engine: &Engine, j: &OrientJob) -> anyhow::Result<Report> {
    j.params.validate()?;
    let r = analyze::run_orient(engine, &j.image, j.mask.as_deref(), &j.params)?;
    // Score before writing, so a bad truth folder leaves nothing behind.
    let score = match &j.truth {
        Some(dir) => {
            let _s = stage("score");
            let (shape, gt) = npy::read_f32(&dir.join("gt_theta.npy"))?;
            let mask_path = dir.join("mask.png");
            let mask = images::open(&mask_path)?.to_luma8();
            let (w, h) = (r.map.width, r.map.height);
            if shape != [h as usize, w as usize] || mask.dimensions() != (w, h) {
                return Err(Error::bad_file(
                    dir,
                    format!(
                        "ground truth is {shape:?}, mask {:?}, image {w}x{h}",
                        mask.dimensions()
                    ),
                )
                .into());
            }
            let e = orientation_error(&r.map, &gt, &mask, 5);
            Some(format!(
                "; mean error {:.2} deg over {} hair px >= 5 px inside the mask",
                e.mean_deg, e.count
            ))
        }
        None => None,
    };
    stage("write").run(|| analyze::write_orient(&j.out, &j.image, &r))?;
    Ok(Report {
        summary: format!(
            "orient: {}x{} on {} in {:.2} s{} -> {}",
            r.map.width,
            r.map.height,
            r.backend,
            r.seconds,
            score.unwrap_or_default(),
            j.out.display()
        ),
        ..Default::default()
    })
}

fn run_analyze(engine: &Engine, j: &AnalyzeJob) -> anyhow::Result<Report> {
    let p = &j.params;
    p.orient.validate()?;
    let positive = |v: f32| v.is_finite() && v > 0.0;
    if !positive(p.resolve.radius) || !positive(p.resolve.stroke_weight) {
        return Err(Error::Invalid("--radius and --stroke-weight must be positive".into()).into());
    }
    let t = Instant::now();
    let reference = Reference::load(j.reference_mask.as_deref(), &j.image)?;
    let (rgb, an) = analyze::run(engine, &j.image, &j.strokes, j.mask.as_deref(), p)?;
    record_all(&an.timings);
    stage("write").run(|| analyze::write(&j.out, &j.image, &rgb, &an, p, &engine.describe()))?;
    let scored = reference.score(&j.out, &rgb, &an, ", ")?;
    Ok(Report {
        summary: format!(
            "analyze: mask {}{scored}, {} curve pieces ({} unreachable from strokes) -> {} ({:.2} s on {})",
            if an.mask_computed {
                "segmented"
            } else {
                "given"
            },
            an.traced.len(),
            an.resolved.unreachable.len(),
            j.out.display(),
            t.elapsed().as_secs_f64(),
            engine.describe()
        ),
        details: Vec::new(),
        warnings: an.warnings.clone(),
    })
}

/// A hair mask drawn by hand that a job scores its mask against (`--reference-mask`), read
/// before the work so that a bad one fails at once.
struct Reference<'a>(Option<(&'a Path, image::GrayImage)>);

impl<'a> Reference<'a> {
    fn load(path: Option<&'a Path>, image: &Path) -> crate::Result<Self> {
        Ok(Reference(match path {
            Some(r) => Some((r, crate::io::images::load_reference_mask(r, image)?)),
            None => None,
        }))
    }

    /// Writes the agreement into `out`; returns the summary's words on it, after `lead`
    /// (or nothing without a reference).
    fn score(
        &self,
        out: &Path,
        rgb: &image::RgbImage,
        an: &analyze::Analysis,
        lead: &str,
    ) -> crate::Result<String> {
        let Some((path, m)) = &self.0 else {
            return Ok(String::new());
        };
        let a = analyze::write_agreement(out, rgb, an, m, path)?;
        Ok(format!(
            "{lead}IoU {:.4} with the reference ({} hair px missed, {} taken)",
            a.iou, a.missed, a.taken
        ))
    }
}

fn run_model(engine: &Engine, j: &ModelJob) -> anyhow::Result<Report> {
    let p = &j.params;
    let t = Instant::now();
    let reference = Reference::load(j.reference_mask.as_deref(), &j.image)?;
    let (rgb, m) = model::run(
        engine,
        &j.image,
        &j.strokes,
        j.mask.as_deref(),
        j.landmarks.as_deref(),
        p,
    )?;
    record_all(&m.timings);
    stage("write").run(|| model::write(&j.out, &j.image, &rgb, &m, p, &engine.describe()))?;
    let scored = reference.score(&j.out, &rgb, &m.analysis, "; mask ")?;
    Ok(Report {
        summary: format!(
            "model: {} strands ({} grown from {} roots on hair, {} added by refinement), {} H \
             cells, field {} cycles to {:.1e}{scored} -> {} ({:.2} s on {})",
            m.strands.len(),
            m.grown_strands,
            m.roots_kept,
            m.strands.len() - m.grown_strands,
            m.h_cells,
            m.solve.cycles,
            m.solve.rel_residual,
            j.out.display(),
            t.elapsed().as_secs_f64(),
            engine.describe()
        ),
        details: timings(&m.timings),
        warnings: m.analysis.warnings.clone(),
    })
}

fn timings<S: std::fmt::Display>(t: &[(S, f64)]) -> Vec<String> {
    t.iter()
        .map(|(k, v)| format!("{k:<18} {:>8.1} ms", v * 1e3))
        .collect()
}

fn run_simulate(engine: &Engine, j: &SimulateJob) -> anyhow::Result<Report> {
    let scene = stage("load").run(|| Scene::load(&j.model))?;
    memory::check_simulate(engine, &scene, j.params.frames)?;
    let r = stage("simulate")
        .run(|| sim::run::run(engine, &scene, &j.params, true))
        .with_context(|| format!("simulating {}", j.model.display()))?;
    stage("write").run(|| sim::run::write(&j.out, &scene, &r, &j.params))?;
    let worst = |f: fn(&sim::SimFigures) -> f64| r.figures.iter().map(f).fold(0.0, f64::max);
    Ok(Report {
        summary: format!(
            "simulate: {} strands x {} vertices, {} frames of {} steps -> {} ({:.2} s on {})",
            r.rest.len(),
            j.params.n_verts,
            j.params.frames,
            j.params.substeps,
            j.out.display(),
            r.seconds,
            r.backend
        ),
        details: vec![
            format!("stretch p99      {:.3} %", 100.0 * worst(|f| f.stretch_p99)),
            format!(
                "strand length    {:.3} % at most",
                100.0 * worst(|f| f.length_max)
            ),
            format!(
                "roots            {:.1e} m from the head's motion at most",
                worst(|f| f.root_error_max)
            ),
            format!(
                "head distance    {:.2} mm at least",
                1e3 * r
                    .figures
                    .iter()
                    .map(|f| f.min_head_distance)
                    .fold(f32::INFINITY, f32::min)
            ),
        ],
        warnings: Vec::new(),
    })
}

fn run_edit(engine: &Engine, j: &EditJob) -> anyhow::Result<Report> {
    use crate::io::annot::StrokeKind;
    let full = stage("load").run(|| Scene::load(&j.model))?;
    // At a level above the strands, the strokes act on the cluster centres and the strands
    // are rebuilt from them with their residuals.
    let hierarchy = if j.level > 0 {
        let _s = stage("hierarchy");
        let h = edit::hierarchy::Hierarchy::build(
            &full.strands,
            &edit::hierarchy::HierarchyParams::default(),
        )?;
        let centres = h.centres(j.level)?.clone();
        Some((h, centres))
    } else {
        None
    };
    let scene = match &hierarchy {
        Some((_, centres)) => Scene {
            strands: centres.clone(),
            rest: None,
            ..full.clone()
        },
        None => full.clone(),
    };
    let mut warnings = Vec::new();
    // Everything is read, checked and computed before the first file is written.
    let (strands, meta, summary, details) = match &j.tool {
        EditTool::Comb { strokes } => {
            let _s = stage("comb");
            let s = edit::load_strokes(&scene, strokes, StrokeKind::Comb)?;
            warnings.extend(edit::unused_brush(&s, StrokeKind::Comb, strokes, j.radius));
            let (out, r) = edit::comb(engine, &scene, &s, j.radius)?;
            let details = vec![
                format!("strands changed  {} of {}", r.strands_changed, r.strands),
                format!("vertices moved   {}", r.vertices_moved),
                format!(
                    "segment length   {:.1e} relative at most",
                    r.length_error_max
                ),
                format!("depth            {:.1e} m at most", r.depth_error_max),
            ];
            let summary = format!(
                "edit: comb {} stroke(s), R {} px -> {} ({:.2} s on {})",
                r.strokes,
                r.radius,
                j.out.display(),
                r.seconds,
                r.backend
            );
            let meta = json!({"tool": "comb", "strokes": strokes, "report": r});
            (out, meta, summary, details)
        }
        EditTool::Cut { strokes, seed } => {
            let _s = stage("cut");
            let s = edit::load_strokes(&scene, strokes, StrokeKind::Cut)?;
            warnings.extend(edit::unused_brush(&s, StrokeKind::Cut, strokes, j.radius));
            let (out, r) = edit::cut(engine, &scene, &s, j.radius, *seed)?;
            let mut details = vec![
                format!("strands cut      {} of {}", r.strands_cut, r.strands),
                format!(
                    "vertices         {} -> {}",
                    r.vertices_before, r.vertices_after
                ),
            ];
            if let Some(m) = r.mean_r_over_radius {
                details.push(format!("mean r/R         {m:.3} over {} draws", r.drawn));
            }
            let summary = format!(
                "edit: cut {} stroke(s), R {} px -> {} ({:.2} s on {})",
                r.strokes,
                r.radius,
                j.out.display(),
                r.seconds,
                r.backend
            );
            let meta = json!({"tool": "cut", "strokes": strokes, "seed": seed, "report": r});
            (out, meta, summary, details)
        }
    };
    if scene.animation.is_some() {
        warnings.push(
            "the model's animation is not carried over: the edit changes its rest strands"
                .to_string(),
        );
    }
    let (strands, details) = match &hierarchy {
        Some((h, centres)) => {
            let rebuilt = stage("hierarchy").run(|| h.rebuild(j.level, &strands, &full.strands))?;
            let mut d = details;
            d.push(format!(
                "hierarchy        level {} of {} ({} centres); {} strands rebuilt",
                j.level,
                h.levels.len(),
                centres.len(),
                rebuilt.len()
            ));
            (rebuilt, d)
        }
        None => (strands, details),
    };
    // Where the photo saw the edited strands: each keeps its rest strand's first vertices
    // (a comb moves vertices, a cut drops tail ones). Rendered without it, the photo (hair
    // and all) came back at the photo's view whatever the edit did.
    let rest = rest_after_edit(full.rest.as_ref().unwrap_or(&full.strands), &strands);
    let edited = Scene {
        dir: j.out.clone(),
        strands,
        animation: None,
        rest: Some(rest),
        ..full
    };
    stage("write").run(|| edited.save(&j.out, json!({ "edit": meta, "level": j.level })))?;
    Ok(Report {
        summary,
        details,
        warnings,
    })
}

/// The rest strands of `edited` taken from `before`'s (see [`Scene::rest`]): strand i's
/// first vertices. When the edit did not only move or drop tail vertices (other strand
/// counts, a strand that grew), the edited strands stand for their own rest: their colour is
/// then the photo's where they lie, still over the inpainted photo.
fn rest_after_edit(
    before: &crate::hair::strands::StrandSet,
    edited: &crate::hair::strands::StrandSet,
) -> crate::hair::strands::StrandSet {
    let same_shape = before.counts.len() == edited.counts.len()
        && before
            .counts
            .iter()
            .zip(&edited.counts)
            .all(|(b, e)| e <= b);
    if !same_shape {
        return edited.clone();
    }
    let off = before.offsets();
    let points = edited
        .counts
        .iter()
        .enumerate()
        .flat_map(|(i, &n)| before.points[off[i]..off[i] + n as usize].iter().copied())
        .collect();
    crate::hair::strands::StrandSet::new(points, edited.counts.clone())
}

fn run_export(j: &ExportJob) -> anyhow::Result<Report> {
    let format = strands::Format::from_path(&j.to)?;
    if format == strands::Format::Usda {
        let scene = Scene::load(&j.model)?;
        if let Some(a) = &scene.animation {
            let frames = (0..a.frames.len())
                .map(|k| scene.frame(k))
                .collect::<crate::error::Result<Vec<_>>>()?;
            let head: Vec<[f32; 12]> = a
                .head
                .iter()
                .map(|p| sim::track::pack(&sim::track::pose_transform(p)))
                .collect();
            strands::write_usda_animated(
                &j.to,
                &frames,
                &head,
                a.fps,
                &strands::UsdOptions::default(),
            )?;
            return Ok(Report {
                summary: format!(
                    "export: {} frames of {} strands (time samples, head transform) -> {}",
                    frames.len(),
                    frames[0].len(),
                    j.to.display()
                ),
                ..Default::default()
            });
        }
    }
    let src = j.model.join("strands.hair");
    let s = strands::read(&src)?;
    strands::write(&j.to, &s)?;
    Ok(Report {
        summary: format!(
            "export: {} strands, {} vertices: {} -> {}",
            s.counts.len(),
            s.points.len(),
            src.display(),
            j.to.display()
        ),
        ..Default::default()
    })
}

fn run_import(j: &ImportJob) -> anyhow::Result<Report> {
    let s = strands::read(&j.input)?;
    let scene = Scene::from_strands(s, &j.out)?;
    scene.save(
        &j.out,
        json!({ "imported_from": j.input.display().to_string() }),
    )?;
    Ok(Report {
        summary: format!(
            "import: {} strands, {} vertices: {} -> {}",
            scene.strands.len(),
            scene.strands.points.len(),
            j.input.display(),
            j.out.display()
        ),
        ..Default::default()
    })
}

fn run_convert(j: &ConvertJob) -> anyhow::Result<Report> {
    // Check the output format before reading, so a typo fails fast.
    strands::Format::from_path(&j.output)?;
    let s = strands::read(&j.input)?;
    strands::write(&j.output, &s)?;
    Ok(Report {
        summary: format!(
            "convert: {} strands, {} vertices: {} -> {}",
            s.counts.len(),
            s.points.len(),
            j.input.display(),
            j.output.display()
        ),
        ..Default::default()
    })
}
