//! `coif simulate`: a scene's strands through a simulation, frame by frame, and the files a
//! simulated sequence is: the scene (the modelled strands at rest), `frames/NNNN.hair` (their
//! positions in every frame, model space, the head at that frame's pose; colours stay in the
//! scene), `sim.json` (settings and per-frame figures of the simulated guides) and
//! `preview.gif` (the strands drawn over the photo, frame by frame).

use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use crate::hair::scene::{Animation, Scene};
use crate::hair::strands::StrandSet;
use crate::io::{ensure_dir, vis, write_atomic, write_json};
use crate::sim::{Sim, SimFigures, SimParams};
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// A simulated sequence in memory.
pub struct SimRun {
    /// The simulated guides at rest (resampled strands, frame 0 before any step).
    pub rest: StrandSet,
    /// The modelled strands of every frame following their guides, model space (frame 0 is
    /// the rest state at the first pose).
    pub frames: Vec<StrandSet>,
    /// Head pose per frame (yaw, pitch, roll in degrees; translation in metres).
    pub poses: Vec<[f32; 6]>,
    pub figures: Vec<SimFigures>,
    pub seconds: f64,
    pub backend: String,
}

/// Simulates `scene` for `p.frames` frames; `progress` shows a bar on a terminal.
pub fn run(engine: &Engine, scene: &Scene, p: &SimParams, progress: bool) -> Result<SimRun> {
    let head = scene.head.as_ref().ok_or_else(|| {
        Error::bad_file(
            scene.dir.join("model.json"),
            "the model has no head to simulate against (imported strands?); run `coif model` \
             on a photo first",
        )
    })?;
    let t = Instant::now();
    let mut sim = Sim::new(&scene.strands, head, p)?;
    let bar = if progress {
        indicatif::ProgressBar::new(p.frames as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("simulate {bar:30} {pos}/{len} frames {eta}")
            .expect("static template"),
    );
    let mut frames = vec![sim.strands()];
    let mut figures = vec![sim.figures()];
    let mut poses = vec![p.track.pose(0.0)];
    for f in 1..=p.frames {
        crate::interrupt::check()?;
        sim.advance(engine, p.substeps)?;
        frames.push(sim.strands());
        figures.push(sim.figures());
        poses.push(p.track.pose(f as f32));
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(SimRun {
        rest: sim.rest.clone(),
        frames,
        poses,
        figures,
        seconds: t.elapsed().as_secs_f64(),
        backend: engine.describe(),
    })
}

/// Writes the sequence to `out` (created): the scene with its animation, the frame files,
/// `sim.json` and `preview.gif`.
pub fn write(out: &Path, scene: &Scene, r: &SimRun, p: &SimParams) -> Result<()> {
    ensure_dir(&out.join("frames"))?;
    let mut names = Vec::with_capacity(r.frames.len());
    for (k, s) in r.frames.iter().enumerate() {
        let name = format!("frames/{k:04}.hair");
        // Positions only: colours and transparency are the scene's, the same every frame.
        let points = StrandSet::new(s.points.clone(), s.counts.clone());
        crate::io::strands::write(&out.join(&name), &points)?;
        names.push(name);
    }
    let worst = |f: fn(&SimFigures) -> f64| r.figures.iter().map(f).fold(0.0, f64::max);
    let summary = json!({
        "stretch_p99_max": worst(|f| f.stretch_p99),
        "stretch_max": worst(|f| f.stretch_max),
        "length_max": worst(|f| f.length_max),
        "root_error_max_m": worst(|f| f.root_error_max),
        "min_head_distance_m": r.figures.iter().map(|f| f.min_head_distance).fold(f32::INFINITY, f32::min),
    });
    let doc = json!({
        "version": 1,
        "coif": env!("CARGO_PKG_VERSION"),
        "source": scene.dir.display().to_string(),
        "params": p,
        "dt": p.dt(),
        "strands": r.rest.len(),
        "backend": r.backend,
        "seconds": r.seconds,
        "figures": summary,
        "per_frame": r.figures,
    });
    write_json(&out.join("sim.json"), &doc)?;
    if let (Some(photo), Some(cam)) = (&scene.photo, &scene.camera) {
        let gif = preview_gif(photo, cam, &r.frames, p.fps)?;
        write_atomic(&out.join("preview.gif"), &gif)?;
    }
    let mut s = scene.clone();
    s.dir = out.to_path_buf();
    s.animation = Some(Animation {
        fps: p.fps,
        frames: names,
        head: r.poses.clone(),
        footage: None,
    });
    s.save(out, json!({ "simulation": "sim.json" }))
}

/// Every frame's strands projected over the dimmed photo (a subset, nearest last), as an
/// animated GIF at `fps`.
pub fn preview_gif(
    photo: &image::RgbImage,
    cam: &crate::hair::head::WeakPerspective,
    frames: &[StrandSet],
    fps: f32,
) -> Result<Vec<u8>> {
    let back = vis::dimmed(photo, 0.35);
    preview_gif_with(frames.len(), fps, |k| {
        Ok((back.clone(), *cam, frames[k].clone()))
    })
}

/// An animated GIF of `n` frames at `fps`: frame k's strands (a subset, nearest last,
/// coloured by direction) projected by its camera over its backdrop, all three from
/// `frame(k)`, so a long clip is never held in memory whole.
pub fn preview_gif_with(
    n: usize,
    fps: f32,
    mut frame: impl FnMut(
        usize,
    ) -> Result<(
        image::RgbImage,
        crate::hair::head::WeakPerspective,
        StrandSet,
    )>,
) -> Result<Vec<u8>> {
    use image::codecs::gif::{GifEncoder, Repeat};
    let mut bytes = Vec::new();
    {
        let mut enc = GifEncoder::new_with_speed(&mut bytes, 20);
        enc.set_repeat(Repeat::Infinite)
            .map_err(|e| Error::Invalid(format!("GIF: {e}")))?;
        let delay = image::Delay::from_numer_denom_ms(1000, fps.max(1.0).round() as u32);
        for k in 0..n {
            let (mut pic, cam, s) = frame(k)?;
            let every = (s.len() / 3000).max(1);
            let mut order: Vec<(f32, Vec<[f32; 2]>)> = s
                .strands()
                .step_by(every)
                .map(|st| {
                    let q: Vec<glam::Vec3> = st
                        .iter()
                        .map(|p| cam.project(glam::Vec3::from_array(*p)))
                        .collect();
                    let z = q.iter().map(|v| v.z).sum::<f32>() / q.len() as f32;
                    (z, q.iter().map(|v| [v.x, v.y]).collect())
                })
                .collect();
            order.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (_, pts) in &order {
                vis::draw_polyline(&mut pic, pts, 1.0, |k| {
                    vis::direction_colour(pts[k + 1][0] - pts[k][0], pts[k + 1][1] - pts[k][1])
                });
            }
            let rgba = image::DynamicImage::ImageRgb8(pic).to_rgba8();
            enc.encode_frame(image::Frame::from_parts(rgba, 0, 0, delay))
                .map_err(|e| Error::Invalid(format!("GIF: {e}")))?;
        }
    }
    Ok(bytes)
}
