//! Synthetic video with exact ground truth (`coif synth-video`): determinism, frame 0 is the
//! still case, the hair motion keeps roots and lengths and stays out of the body, the true
//! flow checked against the rendered frames, the track, and the command line.
//! Run with `--release --nocapture` to see the figures.

use coif::io::annot::Landmarks;
use coif::synth::synth3d::synth3d_with;
use coif::synth::video::{true_flow, SynthVideo, VideoFrame, VideoParams};
use coif::synth::Style;
use std::path::Path;
use std::process::{Command, Output};

fn params(style: Style, seed: u64, size: u32, frames: usize, strands: usize) -> VideoParams {
    let mut p = VideoParams::new(style, seed, size, frames);
    p.strands = strands;
    p
}

fn point_bits(f: &VideoFrame) -> Vec<u32> {
    f.strands
        .iter()
        .flatten()
        .flat_map(|q| q.to_array())
        .map(f32::to_bits)
        .collect()
}

fn flow_bits(v: &[[f32; 2]]) -> Vec<u32> {
    v.iter().flatten().map(|x| x.to_bits()).collect()
}

/// Every file under `dir`, relative path → bytes.
fn tree(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

#[test]
fn deterministic_per_seed() {
    let p = params(Style::Whorl, 3, 80, 3, 500);
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    SynthVideo::new(&p).unwrap().write(&a, false).unwrap();
    SynthVideo::new(&p).unwrap().write(&b, false).unwrap();
    let (ta, tb) = (tree(&a), tree(&b));
    assert_eq!(ta.keys().collect::<Vec<_>>(), tb.keys().collect::<Vec<_>>());
    for (k, v) in &ta {
        assert!(v == &tb[k], "{k} differs between two runs");
    }
    println!("same seed: {} files, identical bytes", ta.len());
    // In memory too: strands and flow.
    let (va, va2) = (SynthVideo::new(&p).unwrap(), SynthVideo::new(&p).unwrap());
    let (f1, f2) = (va.frame(1), va.frame(2));
    let (g1, g2) = (va2.frame(1), va2.frame(2));
    assert_eq!(point_bits(&f2), point_bits(&g2));
    assert_eq!(
        flow_bits(&true_flow(&f1, &f2)),
        flow_bits(&true_flow(&g1, &g2))
    );
    // Another seed moves differently.
    let q = params(Style::Whorl, 4, 80, 3, 500);
    let vb = SynthVideo::new(&q).unwrap();
    assert_ne!(va.motion, vb.motion);
    assert_ne!(
        va.frame(2).render.image.as_raw(),
        vb.frame(2).render.image.as_raw()
    );
}

/// Camera noise: fresh per frame, the same for the same seed, zero mean with the stated σ
/// against the clean render, and nothing but the image changes.
#[test]
fn camera_noise_is_seeded_and_has_its_sigma() {
    let mut p = params(Style::Long, 2, 96, 3, 800);
    let clean = SynthVideo::new(&p).unwrap();
    p.noise = 4.0;
    let (a, b) = (SynthVideo::new(&p).unwrap(), SynthVideo::new(&p).unwrap());
    let (c1, a1, b1, a2) = (clean.frame(1), a.frame(1), b.frame(1), a.frame(2));
    assert_eq!(a1.render.image.as_raw(), b1.render.image.as_raw());
    assert_eq!(point_bits(&a1), point_bits(&c1));
    assert_eq!(a1.render.mask.as_raw(), c1.render.mask.as_raw());
    // Residuals on pixels away from 0 and 255, where clamping does not bias them.
    let resid = |noisy: &VideoFrame, clean: &VideoFrame| -> Vec<f64> {
        noisy
            .render
            .image
            .as_raw()
            .iter()
            .zip(clean.render.image.as_raw())
            .filter(|(_, &c)| (20..=235).contains(&c))
            .map(|(&n, &c)| n as f64 - c as f64)
            .collect()
    };
    let r = resid(&a1, &c1);
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    let sd = (r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt();
    println!(
        "noise σ 4: mean {mean:.3}, σ {sd:.3} over {} channels",
        r.len()
    );
    assert!(
        mean.abs() < 0.1 && (sd - 4.0).abs() < 0.15,
        "mean {mean}, σ {sd}"
    );
    // Fresh per frame: the residuals of frames 1 and 2 are uncorrelated.
    let c2 = clean.frame(2);
    let (r1, r2) = (resid(&a1, &c1), resid(&a2, &c2));
    let same = r1.iter().zip(&r2).filter(|(x, y)| x == y).count() as f64 / r1.len() as f64;
    assert!(same < 0.2, "{:.0}% of residuals repeat", 100.0 * same);
}

#[test]
fn frame_zero_is_the_still_case() {
    for style in [Style::Long, Style::SidePart] {
        let p = params(style, 2, 96, 4, 800);
        let v = SynthVideo::new(&p).unwrap();
        let still = synth3d_with(&p.synth, &p.still_options());
        let f = v.frame(0);
        assert_eq!(
            f.render.image.as_raw(),
            still.case.image.as_raw(),
            "{style}"
        );
        assert_eq!(f.render.mask.as_raw(), still.case.mask.as_raw(), "{style}");
        assert_eq!(f.render.landmarks, still.case.landmarks, "{style}");
        assert_eq!(f.pose.camera, still.camera, "{style}");
        assert_eq!(
            f.strand_set().points,
            still.gt.points,
            "{style}: frame 0 strands"
        );
        let r = v.reference();
        assert_eq!(r.case.image.as_raw(), still.case.image.as_raw());
        assert_eq!(r.case.strokes, still.case.strokes);
        // The motion starts from rest and stays within the stated bounds.
        let later = v.frame(3);
        assert_ne!(later.render.image.as_raw(), f.render.image.as_raw());
        for i in 0..p.frames {
            let (_, yaw, pitch, _) = v.camera(i);
            assert!(yaw.abs() <= 10.0 && pitch.abs() <= 10.0, "{yaw} {pitch}");
        }
    }
}

#[test]
fn hair_motion_keeps_roots_lengths_and_clearance() {
    let (mut root_err, mut len_err, mut pen, mut moved) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for style in [Style::Long, Style::Short] {
        let p = params(style, 1, 96, 8, 1000);
        let v = SynthVideo::new(&p).unwrap();
        let rest = &v.scene.strands;
        let c = v.motion.clearance_m;
        for i in [1usize, 4, 7] {
            let (st, scale) = v.strands(i);
            assert_eq!(st.len(), rest.len());
            assert!(scale.iter().all(|l| (0.0..=1.0).contains(l)));
            for (a, b) in st.iter().zip(rest) {
                assert_eq!(a.len(), b.len());
                root_err = root_err.max(a[0].distance(b[0]));
                for k in 1..a.len() {
                    let (la, lb) = (a[k].distance(a[k - 1]), b[k].distance(b[k - 1]));
                    len_err = len_err.max((la - lb).abs() / lb);
                    // No vertex deeper in the body than at rest (or closer than the
                    // clearance when it was farther).
                    let d0 = v.scene.body_sdf(b[k]);
                    pen = pen.max(d0.min(c) - v.scene.body_sdf(a[k]));
                    moved = moved.max(a[k].distance(b[k]));
                }
            }
        }
    }
    println!(
        "hair motion over 8 frames: root error {root_err:.2e} m, segment length error \
         {len_err:.2e} (relative), deepest extra penetration {pen:.2e} m, largest vertex \
         motion {:.1} mm",
        moved * 1e3
    );
    assert!(root_err <= 1e-6, "{root_err}");
    assert!(len_err <= 1e-5, "{len_err}");
    assert!(pen <= 1e-6, "{pen}");
    assert!(moved > 1e-3, "the hair hardly moves: {moved}");
}

/// Bilinear sample of an RGB image at (x, y) in pixel-centre coordinates (centre of pixel i
/// at i + 0.5), None outside.
fn sample(img: &image::RgbImage, x: f32, y: f32) -> Option<[f32; 3]> {
    let (fx, fy) = (x - 0.5, y - 0.5);
    let (w, h) = img.dimensions();
    if fx < 0.0 || fy < 0.0 || fx > (w - 1) as f32 || fy > (h - 1) as f32 {
        return None;
    }
    let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
    let px = |x, y| img.get_pixel(x, y).0.map(|v| v as f32);
    let (a, b, c, d) = (px(x0, y0), px(x1, y0), px(x0, y1), px(x1, y1));
    Some(std::array::from_fn(|k| {
        (a[k] * (1.0 - ax) + b[k] * ax) * (1.0 - ay) + (c[k] * (1.0 - ax) + d[k] * ax) * ay
    }))
}

#[test]
fn true_flow_agrees_with_the_rendered_frames() {
    // Checks that use only the rendered frames: a flowed hair pixel lands on hair in the
    // next frame; the growth direction there matches; and the next frame sampled at the
    // flowed position looks like this one (photometric error below that of no motion).
    let mut report = Vec::new();
    for style in [Style::Long, Style::Whorl, Style::SidePart] {
        let p = params(style, 1, 128, 8, 2500);
        let v = SynthVideo::new(&p).unwrap();
        let (w, h) = (p.synth.width as usize, p.synth.height as usize);
        let mut prev = v.frame(0);
        let (mut n, mut on_hair, mut dir_ok, mut moved) = (0usize, 0usize, 0usize, 0usize);
        let (mut e_flow, mut e_zero, mut flow_len) = (0.0f64, 0.0f64, 0.0f64);
        let (mut track_hair, mut still_hair) = (0usize, 0usize);
        for i in 1..p.frames {
            let cur = v.frame(i);
            let flow = true_flow(&prev, &cur);
            for y in 0..h {
                for x in 0..w {
                    let k = y * w + x;
                    let d = flow[k];
                    if d[0].is_nan() {
                        assert!(prev.render.hits[k].is_none());
                        continue;
                    }
                    assert!(prev.render.mask.as_raw()[k] > 0, "flow off the mask");
                    n += 1;
                    flow_len += d[0].hypot(d[1]) as f64;
                    let (qx, qy) = (x as f32 + 0.5 + d[0], y as f32 + 0.5 + d[1]);
                    let (ix, iy) = (qx.floor() as i64, qy.floor() as i64);
                    if ix < 0 || iy < 0 || ix >= w as i64 || iy >= h as i64 {
                        continue;
                    }
                    let j = iy as usize * w + ix as usize;
                    if cur.render.mask.as_raw()[j] > 0 {
                        on_hair += 1;
                        let a = [prev.render.gt_dir[2 * k], prev.render.gt_dir[2 * k + 1]];
                        let b = [cur.render.gt_dir[2 * j], cur.render.gt_dir[2 * j + 1]];
                        if a[0] * b[0] + a[1] * b[1] > 20f32.to_radians().cos() {
                            dir_ok += 1;
                        }
                    }
                }
            }
            if i + 1 == p.frames {
                // Photometric check from frame 0 to the last frame (by the track, so that
                // the motion is large enough), where it is at least half a pixel.
                let f0 = v.frame(0);
                let track = true_flow(&f0, &cur);
                for (k, d) in track.iter().enumerate() {
                    if d[0].is_nan() || d[0].hypot(d[1]) < 0.5 {
                        continue;
                    }
                    let (x, y) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
                    if let (Some(a), Some(b), Some(c)) = (
                        sample(&f0.render.image, x, y),
                        sample(&cur.render.image, x + d[0], y + d[1]),
                        sample(&cur.render.image, x, y),
                    ) {
                        moved += 1;
                        let at = |x: f32, y: f32| {
                            let (ix, iy) = (x.floor() as usize, y.floor() as usize);
                            cur.render.mask.as_raw()[iy * w + ix] > 0
                        };
                        track_hair += at(x + d[0], y + d[1]) as usize;
                        still_hair += at(x, y) as usize;
                        let l1 = |u: [f32; 3], v: [f32; 3]| {
                            (0..3).map(|c| (u[c] - v[c]).abs()).sum::<f32>() as f64 / 3.0
                        };
                        e_flow += l1(a, b);
                        e_zero += l1(a, c);
                    }
                }
            }
            prev = cur;
        }
        let land = on_hair as f64 / n as f64;
        let dirs = dir_ok as f64 / on_hair as f64;
        let (ef, ez) = (e_flow / moved as f64, e_zero / moved as f64);
        let track_land = track_hair as f64 / moved as f64;
        report.push(format!(
            "{style}: {n} hair px over {} frame pairs, mean |flow| {:.2} px; {:.2}% land \
             on hair, {:.2}% of those within 20° of the growth direction; frame 0 to the last, on \
             {moved} px moving >= 0.5 px: {:.2}% land on hair with the track ({:.2}% without), \
             colour error {ef:.1} with the track, {ez:.1} without (ratio {:.2})",
            p.frames - 1,
            flow_len / n as f64,
            100.0 * land,
            100.0 * dirs,
            100.0 * track_land,
            100.0 * still_hair as f64 / moved as f64,
            ef / ez
        ));
        assert!(n > 1000, "{style}: {n}");
        assert!(land >= 0.95, "{style}: {land}");
        assert!(dirs >= 0.9, "{style}: {dirs}");
        assert!(moved > 100, "{style}: {moved}");
        assert!(track_land >= 0.95, "{style}: {track_land}");
        assert!(
            ef < ez,
            "{style}: flow does not explain the motion ({ef} vs {ez})"
        );
    }
    println!(
        "true flow against the rendered frames:\n{}",
        report.join("\n")
    );
}

#[test]
fn track_starts_at_zero() {
    let p = params(Style::Long, 5, 96, 3, 800);
    let v = SynthVideo::new(&p).unwrap();
    let f0 = v.frame(0);
    let t0 = true_flow(&f0, &f0);
    let covered = f0.render.hits.iter().filter(|h| h.is_some()).count();
    assert!(covered > 500, "{covered}");
    for (d, hit) in t0.iter().zip(&f0.render.hits) {
        match hit {
            Some(_) => assert_eq!(*d, [0.0, 0.0]),
            None => assert!(d[0].is_nan() && d[1].is_nan()),
        }
    }
    // The head moves: flow on the hair is not zero.
    let mean = true_flow(&f0, &v.frame(2))
        .iter()
        .filter(|d| !d[0].is_nan())
        .map(|d| d[0].hypot(d[1]))
        .sum::<f32>()
        / covered as f32;
    println!("track 0 -> 2: mean {mean:.2} px on {covered} hair px");
    assert!(mean > 0.1, "{mean}");
}

fn coif(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_coif"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("coif runs")
}

#[test]
fn cli_writes_every_file() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("clip");
    let o = coif(&[
        "synth-video",
        "--out",
        out.to_str().unwrap(),
        "--style",
        "short",
        "--frames",
        "3",
        "--seed",
        "2",
        "--size",
        "64",
        "--strands",
        "400",
        "--noise",
        "2",
        "--jpeg",
        "80",
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    println!("{text}");
    for i in 0..3 {
        let n = format!("{i:04}");
        let img = image::open(out.join(format!("frames/{n}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (64, 64));
        let m = image::open(out.join(format!("masks/{n}.png")))
            .unwrap()
            .to_luma8();
        assert!(m.pixels().any(|p| p[0] == 255));
        Landmarks::load(&out.join(format!("landmarks/{n}.json")), Some((64, 64))).unwrap();
        let gt = coif::io::strands::read(&out.join(format!("gt/{n}.hair"))).unwrap();
        assert_eq!(gt.len(), 400);
        let (shape, t) = coif::io::npy::read_f32(&out.join(format!("track/{n}.npy"))).unwrap();
        assert_eq!(shape, vec![64, 64, 2]);
        if i == 0 {
            assert!(t.iter().all(|x| x.is_nan() || *x == 0.0));
            assert!(!out.join("flow/0000.npy").exists());
        } else {
            let (shape, f) = coif::io::npy::read_f32(&out.join(format!("flow/{n}.npy"))).unwrap();
            assert_eq!(shape, vec![64, 64, 2]);
            assert!(f.iter().any(|x| x.is_finite()));
            if i == 1 {
                // From frame 0 the track to frame 1 is the flow to frame 1.
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&f), bits(&t));
            }
        }
    }
    let cams: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("cameras.json")).unwrap()).unwrap();
    assert_eq!(cams["frames"], 3);
    assert_eq!(cams["fps"], 24.0);
    assert_eq!(cams["style"], "short");
    assert_eq!(cams["noise_sigma"], 2.0);
    assert_eq!(cams["jpeg_quality"], 80);
    assert_eq!(cams["per_frame"].as_array().unwrap().len(), 3);
    let cam: coif::hair::head::WeakPerspective =
        serde_json::from_value(cams["per_frame"][2]["camera"].clone()).unwrap();
    assert!(cam.s > 0.0);
    for f in [
        "image.png",
        "mask.png",
        "strokes.json",
        "landmarks.json",
        "gt_strands.hair",
        "camera.json",
        "gt_dir.npy",
        "gt_theta.npy",
    ] {
        assert!(out.join("reference").join(f).is_file(), "reference/{f}");
    }
    let gif = image::codecs::gif::GifDecoder::new(std::io::Cursor::new(
        std::fs::read(out.join("preview.gif")).unwrap(),
    ))
    .unwrap();
    use image::AnimationDecoder;
    assert_eq!(gif.into_frames().count(), 3);
    assert!(!out.join("frames/0003.png").exists());
}

#[test]
fn cli_refuses_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("bad");
    let o = out.to_str().unwrap();
    for (args, needle) in [
        (["--frames", "1", "--size", "64"], "--frames 1"),
        (["--frames", "10001", "--size", "64"], "--frames 10001"),
        (["--frames", "2", "--size", "32"], "--size 32"),
        (["--strands", "0", "--size", "64"], "--strands 0"),
        (["--noise", "-1", "--size", "64"], "--noise -1"),
        (["--noise", "NaN", "--size", "64"], "--noise NaN"),
        (["--jpeg", "101", "--size", "64"], "--jpeg 101"),
    ] {
        let mut a = vec!["synth-video", "--out", o];
        a.extend(args);
        let r = coif(&a);
        let e = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(64), "{a:?}: {e}");
        assert!(e.contains(needle), "{a:?}: {e}");
        assert!(!out.exists(), "{a:?} wrote {}", out.display());
    }
    let r = coif(&["synth-video", "--out", o, "--style", "curly"]);
    assert!(!r.status.success());
}

/// The flow check's own building block: a sample at a pixel centre is that pixel.
#[test]
fn sample_hits_pixel_centres() {
    let img = image::RgbImage::from_fn(4, 3, |x, y| image::Rgb([x as u8 * 10, y as u8, 7]));
    assert_eq!(sample(&img, 2.5, 1.5), Some([20.0, 1.0, 7.0]));
    assert_eq!(sample(&img, 3.0, 1.5), Some([25.0, 1.0, 7.0]));
    assert_eq!(sample(&img, 0.2, 1.5), None);
}
