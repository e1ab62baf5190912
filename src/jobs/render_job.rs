//! `coif render`'s job: one picture of a model, or every frame of a moving one.

use super::{record_all, stage, timings, RenderJob, Report};
use crate::gpu::engine::Engine;
use crate::hair::scene::Scene;
use crate::{render, sim};
use anyhow::Context;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub(super) fn run_render(engine: &Engine, j: &RenderJob) -> anyhow::Result<Report> {
    use crate::io::outpath::{self, Format};
    let p = &j.params;
    // The output is checked before any work: its type, its folder, and not the model's
    // files. Without an extension it is the frames folder of a moving scene.
    let inputs = Scene::inputs(&j.model);
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let frames = j.out.extension().is_none();
    if frames {
        outpath::require_folder(&j.out)?;
        outpath::refuse_inputs(&j.out, &inputs)?;
    } else if outpath::check(&j.out, &[Format::Png, Format::Jpeg], &inputs)? == Format::Jpeg {
        render::jpeg_fits(&j.out, p, j.sixteen)?;
    }
    let t = Instant::now();
    let scene = stage("load").run(|| Scene::load(&j.model))?;
    if frames {
        if scene.animation.is_none() {
            // A still scene is one picture, whose type the extension names.
            outpath::check(&j.out, &[Format::Png, Format::Jpeg], &inputs)?;
        }
        return render_frames(engine, &scene, j);
    }
    let r = render::render(engine, &scene, p)
        .with_context(|| format!("rendering {}", j.model.display()))?;
    let mut warnings = Vec::new();
    if !p.is_original_view() && scene.photo.is_some() && default_head_fit(&j.model) {
        warnings.push(format!(
            "{}: the head was placed by the default fit (the model was made without \
             --landmarks): this view turns a frontal head as wide as the hair mask, and a \
             face the photo shows tilted or turned will not follow it; `coif model \
             --landmarks` fits the head to the face",
            j.model.display()
        ));
    }
    record_all(&r.report.seconds);
    let side = stage("write").run(|| render::write(&j.out, &r, p, j.sixteen))?;
    Ok(Report {
        summary: format!(
            "render: {} strands, {}x{} ({}) -> {} ({:.2} s on {}; settings in {})",
            r.report.strands,
            r.width,
            r.height,
            if p.is_original_view() {
                "original view"
            } else {
                "novel view"
            },
            j.out.display(),
            t.elapsed().as_secs_f64(),
            engine.describe(),
            side.display()
        ),
        details: timings(&r.report.seconds),
        warnings,
    })
}

/// Whether the model folder's `model.json` says its head was placed by the default fit (no
/// landmarks). Unreadable or older files say nothing: no warning then.
fn default_head_fit(dir: &Path) -> bool {
    std::fs::read_to_string(dir.join("model.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| {
            v.pointer("/head/fit/method")?
                .as_str()
                .map(|m| m == "default")
        })
        .unwrap_or(false)
}

/// Every frame of an animated scene into the folder `j.out` (`NNNN.png`). A tracked video
/// draws each frame's strands into that frame's photo with its camera. A simulation takes the
/// frame's strands back to the head's rest pose and draws them from a view turned by the
/// head's yaw, pitch and roll, so head and hair move together over the inpainted
/// background; the head's translation is not drawn (the background would have to move).
pub(super) fn render_frames(
    engine: &Engine,
    scene: &Scene,
    j: &RenderJob,
) -> anyhow::Result<Report> {
    let a = scene.animation.as_ref().expect("checked by the caller");
    let t = Instant::now();
    // All frames or none: written into a temporary folder put in place at the end.
    let txn = crate::io::txn::Txn::begin(&j.out)?;
    let bar = indicatif::ProgressBar::new(a.frames.len() as u64).with_style(
        indicatif::ProgressStyle::with_template("render {bar:30} {pos}/{len} frames {eta}")
            .expect("static template"),
    );
    // What the simulated frames' views share, made once (the inpainted photo, the head).
    let mut shared = None;
    for (k, pose) in a.head.iter().enumerate() {
        crate::interrupt::check()?;
        let mut p = j.params.clone();
        // A tracked video: each frame over its own photo, seen by its own camera.
        // A tracked video's frame shows its strands where they lie; a simulated frame's
        // strands have moved from where the photo saw them (the scene's own strands).
        let (s, moved) = match scene.footage_frame(k)? {
            Some(s) => (s, false),
            None => {
                let m = sim::track::pose_transform(pose);
                let mut s = scene.clone();
                s.strands = scene.frame(k)?;
                for q in &mut s.strands.points {
                    *q = sim::track::apply_inv(&m, *q);
                }
                p.yaw_deg += pose[0];
                p.pitch_deg += pose[1];
                p.roll_deg += pose[2];
                (s, true)
            }
        };
        let r = if moved {
            let rest = scene.rest.as_ref().unwrap_or(&scene.strands);
            render::render_moved_with(engine, &s, rest, &p, &mut shared)
        } else {
            render::render(engine, &s, &p)
        }
        .with_context(|| format!("rendering frame {k} of {}", j.model.display()))?;
        record_all(&r.report.seconds);
        stage("write")
            .run(|| render::write(&txn.dir().join(format!("{k:04}.png")), &r, &p, j.sixteen))?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    txn.commit()?;
    Ok(Report {
        summary: format!(
            "render: {} frames -> {} ({:.2} s on {})",
            a.frames.len(),
            j.out.display(),
            t.elapsed().as_secs_f64(),
            engine.describe()
        ),
        ..Default::default()
    })
}
