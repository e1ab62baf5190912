//! Synthetic portraits with 3D ground truth: determinism, the GT strands (rooted on the
//! scalp, outside the head, smooth), the image-space GT against the projection, the files,
//! the 3D comparison itself, and the modelling pipeline judged against the GT.
//! Run with `--release --nocapture` to see the figures.

use coif::hair::head::Head;
use coif::hair::strands::StrandSet;
use coif::synth::synth3d::{compare_to_gt, synth3d_with, Synth3dCase, Synth3dOptions};
use coif::synth::{mask_interior, Style, SynthParams};
use glam::Vec3;

fn case(style: Style, seed: u64, size: u32, strands: usize) -> Synth3dCase {
    synth3d_with(
        &SynthParams {
            style,
            seed,
            width: size,
            height: size,
        },
        &Synth3dOptions {
            strands,
            ..Default::default()
        },
    )
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn point_bits(s: &StrandSet) -> Vec<u32> {
    s.points.iter().flatten().map(|x| x.to_bits()).collect()
}

#[test]
fn deterministic_per_seed() {
    for style in [Style::Long, Style::Whorl] {
        let a = case(style, 7, 160, 1500);
        let b = case(style, 7, 160, 1500);
        assert_eq!(a.case.image.as_raw(), b.case.image.as_raw(), "{style}");
        assert_eq!(a.case.mask.as_raw(), b.case.mask.as_raw(), "{style}");
        assert_eq!(bits(&a.case.gt_dir), bits(&b.case.gt_dir), "{style}");
        assert_eq!(bits(&a.case.gt_theta), bits(&b.case.gt_theta), "{style}");
        assert_eq!(a.case.strokes, b.case.strokes, "{style}");
        assert_eq!(a.case.landmarks, b.case.landmarks, "{style}");
        assert_eq!(a.gt.counts, b.gt.counts, "{style}");
        assert_eq!(point_bits(&a.gt), point_bits(&b.gt), "{style}");
        assert_eq!(a.camera, b.camera, "{style}");
        let c = case(style, 8, 160, 1500);
        assert_ne!(a.case.image.as_raw(), c.case.image.as_raw(), "{style}");
        assert_ne!(point_bits(&a.gt), point_bits(&c.gt), "{style}");
    }
}

/// Turning angles (degrees) between consecutive segments of every strand.
fn turns(s: &StrandSet) -> Vec<f32> {
    let mut out = Vec::new();
    for st in s.strands() {
        for t in st.windows(3) {
            let u = Vec3::from_array(t[1]) - Vec3::from_array(t[0]);
            let v = Vec3::from_array(t[2]) - Vec3::from_array(t[1]);
            out.push(u.angle_between(v).to_degrees());
        }
    }
    out
}

#[test]
fn gt_strands_rooted_outside_the_head_and_smooth() {
    let head = Head::default();
    for style in Style::ALL {
        for seed in 1..=2 {
            let c = case(style, seed, 256, 4000);
            let name = format!("{style} seed {seed}");
            c.gt.validate().unwrap();
            assert_eq!(
                c.gt.colors.as_ref().map(|v| v.len()),
                Some(c.gt.points.len())
            );
            assert!(c.gt.len() >= 3900, "{name}: {} strands", c.gt.len());
            let (mut root_max, mut min_sdf, mut seg_err) = (0.0f32, f32::INFINITY, 0.0f32);
            let mut lens = Vec::new();
            for st in c.gt.strands() {
                let r = Vec3::from_array(st[0]);
                root_max = root_max.max(head.sdf(r).abs());
                assert!(!head.in_face(r), "{name}: root {r} in the face");
                for q in st {
                    min_sdf = min_sdf.min(head.sdf(Vec3::from_array(*q)));
                }
                for s in st.windows(2) {
                    let l = Vec3::from_array(s[1]).distance(Vec3::from_array(s[0]));
                    seg_err = seg_err.max((l - 0.002).abs());
                }
                lens.push(0.002 * (st.len() - 1) as f32);
            }
            let t = turns(&c.gt);
            let tmax = t.iter().fold(0.0f32, |a, &b| a.max(b));
            lens.sort_by(f32::total_cmp);
            println!(
                "{name}: {} strands, {} vertices, roots ≤ {:.1e} m from the scalp, min sdf \
                 {:.2} mm, step error ≤ {:.1e} m, turning max {tmax:.2}°, length median {:.0} mm \
                 (p10 {:.0}, p90 {:.0})",
                c.gt.len(),
                c.gt.points.len(),
                root_max,
                1e3 * min_sdf,
                seg_err,
                1e3 * lens[lens.len() / 2],
                1e3 * lens[lens.len() / 10],
                1e3 * lens[lens.len() * 9 / 10]
            );
            assert!(root_max < 1e-4, "{name}: root {root_max} m off the scalp");
            assert!(
                min_sdf >= -1e-5,
                "{name}: vertex {min_sdf} m inside the head"
            );
            assert!(seg_err < 1e-4, "{name}: steps not 2 mm ({seg_err})");
            assert!(tmax <= 15.0, "{name}: turning {tmax}°");
            // Strands are mostly grown to length, not cut at once.
            assert!(lens[lens.len() / 2] > 0.012, "{name}: strands too short");
        }
    }
}

#[test]
fn image_ground_truth_matches_the_projection() {
    for style in Style::ALL {
        for seed in 1..=2 {
            let c = case(style, seed, 256, 4000);
            let name = format!("{style} seed {seed}");
            let (w, h) = (c.case.width as usize, c.case.height as usize);
            let m = c.case.mask.as_raw();
            let tol = 0.002 * c.camera.s;
            // Visible GT vertices reproject onto the mask; visible segments' projected
            // tangents agree with gt_dir where they pass.
            let (mut vis, mut on) = (0usize, 0usize);
            let (mut judged, mut agree) = (0usize, 0usize);
            let (mut judged_f, mut agree_f) = (0usize, 0usize);
            let front_tol = 0.001 * c.camera.s;
            for st in c.gt.strands() {
                let p: Vec<Vec3> = st
                    .iter()
                    .map(|q| c.camera.project(Vec3::from_array(*q)))
                    .collect();
                let pix = |q: Vec3| {
                    (q.x >= 0.0 && q.y >= 0.0 && (q.x as usize) < w && (q.y as usize) < h)
                        .then(|| q.y as usize * w + q.x as usize)
                };
                for q in &p {
                    if let Some(k) = pix(*q) {
                        if q.z >= c.body_depth[k] - tol {
                            vis += 1;
                            on += (m[k] == 255) as usize;
                        }
                    }
                }
                for s in p.windows(2) {
                    let mid = (s[0] + s[1]) * 0.5;
                    let d = (s[1] - s[0]).truncate();
                    let Some(k) = pix(mid) else { continue };
                    if mid.z < c.body_depth[k] - tol || d.length() < 0.5 {
                        continue;
                    }
                    let d = d.normalize();
                    judged += 1;
                    let g = [c.case.gt_dir[2 * k], c.case.gt_dir[2 * k + 1]];
                    let ok = d.x * g[0] + d.y * g[1] > 30f32.to_radians().cos();
                    agree += ok as usize;
                    // Segments on the front layer (within 1 mm of the visible hair surface).
                    if mid.z >= c.hair_depth[k] - front_tol {
                        judged_f += 1;
                        agree_f += ok as usize;
                    }
                }
            }
            let on_share = on as f64 / vis.max(1) as f64;
            let agree_share = agree as f64 / judged.max(1) as f64;
            let front_share = agree_f as f64 / judged_f.max(1) as f64;
            // Consistency of the image arrays themselves.
            let mut hair = 0;
            for (k, &mk) in m.iter().enumerate() {
                let (dx, dy, t) = (
                    c.case.gt_dir[2 * k],
                    c.case.gt_dir[2 * k + 1],
                    c.case.gt_theta[k],
                );
                if mk == 255 {
                    hair += 1;
                    assert!((dx.hypot(dy) - 1.0).abs() < 1e-4, "{name}: gt_dir not unit");
                    let e = coif::synth::orientation_error_deg(dy.atan2(dx), t);
                    assert!(e < 1e-2, "{name}: gt_theta off gt_dir by {e}°");
                } else {
                    assert_eq!(mk, 0);
                    assert!(
                        dx.is_nan() && dy.is_nan() && t.is_nan(),
                        "{name}: GT off hair"
                    );
                }
            }
            let frac = hair as f64 / (w * h) as f64;
            println!(
                "{name}: hair {:.1}% of the image, {vis} visible GT vertices, {:.3}% on the mask, \
                 segment tangents within 30° of gt_dir: {:.1}% of {judged_f} on the front \
                 layer ({:.1}% of all {judged} not hidden by the head)",
                100.0 * frac,
                100.0 * on_share,
                100.0 * front_share,
                100.0 * agree_share
            );
            assert!(
                on_share >= 0.999,
                "{name}: {on_share} of visible vertices on the mask"
            );
            // Strands crossing on the front layer disagree in places, so this is a share.
            assert!(front_share >= 0.95, "{name}: agreement {front_share}");
            let (lo, hi) = match style {
                Style::Long => (0.15, 0.40),
                _ => (0.025, 0.12),
            };
            assert!((lo..=hi).contains(&frac), "{name}: hair {frac}");
            // The face is never hair; landmarks lie in the image.
            c.case
                .landmarks
                .validate(Some((c.case.width, c.case.height)))
                .unwrap();
            for n in coif::io::annot::REQUIRED_LANDMARKS {
                let p = c.case.landmarks.get(n).unwrap();
                assert!(
                    !c.case.is_hair(p[0] as u32, p[1] as u32),
                    "{name}: {n} on hair"
                );
            }
            let (le, re) = (
                c.case.landmarks.get("left_eye").unwrap(),
                c.case.landmarks.get("right_eye").unwrap(),
            );
            assert!(le[0] < re[0], "{name}: eyes swapped");
            // Strokes: 4-6, on hair, along gt_dir.
            let strokes = &c.case.strokes.strokes;
            assert!(
                (4..=6).contains(&strokes.len()),
                "{name}: {} strokes",
                strokes.len()
            );
            c.case
                .strokes
                .validate(Some((c.case.width, c.case.height)))
                .unwrap();
            let inner = mask_interior(&c.case.mask, 2.0);
            for (si, s) in strokes.iter().enumerate() {
                let len: f32 = s
                    .points
                    .windows(2)
                    .map(|q| (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]))
                    .sum();
                assert!(
                    (20.0..=100.0).contains(&len),
                    "{name} stroke {si}: {len} px"
                );
                for q in &s.points {
                    assert!(
                        inner[q[1] as usize * w + q[0] as usize],
                        "{name} stroke {si}"
                    );
                }
                for q in s.points.windows(2) {
                    let seg = (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]);
                    let mid = [(q[0][0] + q[1][0]) / 2.0, (q[0][1] + q[1][1]) / 2.0];
                    let k = mid[1] as usize * w + mid[0] as usize;
                    let cosang = ((q[1][0] - q[0][0]) * c.case.gt_dir[2 * k]
                        + (q[1][1] - q[0][1]) * c.case.gt_dir[2 * k + 1])
                        / seg;
                    assert!(cosang > 20f32.to_radians().cos(), "{name} stroke {si}");
                }
            }
        }
    }
}

#[test]
fn write_round_trips() {
    let c = case(Style::SidePart, 3, 128, 800);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("case");
    c.write(&out).unwrap();
    for f in [
        "image.png",
        "mask.png",
        "strokes.json",
        "landmarks.json",
        "gt_theta.npy",
        "gt_dir.npy",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let img = image::open(out.join("image.png")).unwrap().to_rgb8();
    assert_eq!(img.as_raw(), c.case.image.as_raw());
    let gt = coif::io::strands::read(&out.join("gt_strands.hair")).unwrap();
    assert_eq!(gt.counts, c.gt.counts);
    assert_eq!(point_bits(&gt), point_bits(&c.gt));
    let cam: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("camera.json")).unwrap()).unwrap();
    let back: coif::hair::head::WeakPerspective =
        serde_json::from_value(cam["camera"].clone()).unwrap();
    assert!((back.s - c.camera.s).abs() < 1e-3);
    assert!((back.t - c.camera.t).length() < 1e-3);
    assert!((back.r - c.camera.r).abs_diff_eq(glam::Mat3::ZERO, 1e-6));
    let m: [[f32; 4]; 3] = serde_json::from_value(cam["image_from_model"].clone()).unwrap();
    // The matrix projects like the camera.
    for q in c.gt.points.iter().step_by(997) {
        let p = c.camera.project(Vec3::from_array(*q));
        let r: Vec<f32> = m
            .iter()
            .map(|row| row[0] * q[0] + row[1] * q[1] + row[2] * q[2] + row[3])
            .collect();
        assert!(
            (p.x - r[0]).abs() < 1e-2 && (p.y - r[1]).abs() < 1e-2 && (p.z - r[2]).abs() < 1e-2
        );
    }
}

#[test]
fn comparison_measures_what_it_says() {
    let c = case(Style::Whorl, 2, 128, 1500);
    let head = &c.head;
    let same = compare_to_gt(&c.gt, &c.gt, head);
    assert_eq!(same.tangent_median_deg, 0.0);
    assert_eq!(same.tangent_within_30, 1.0);
    assert_eq!(same.dist_median_mm, 0.0);
    assert_eq!(same.gt_covered_1cm, 1.0);
    assert_eq!(same.model_inside_head, 0.0);
    // Shifted 5 mm outwards along x: distances grow accordingly, tangents stay.
    let mut shifted = c.gt.clone();
    for p in &mut shifted.points {
        p[0] += 0.005;
    }
    let f = compare_to_gt(&shifted, &c.gt, head);
    println!("shifted 5 mm: {f:?}");
    assert!(f.dist_median_mm > 0.5 && f.dist_median_mm <= 5.0 + 1e-3);
    assert!(f.tangent_within_30 > 0.8);
    // Reversed strands (tip first): tangents opposite.
    let mut rev = StrandSet::new(Vec::new(), c.gt.counts.clone());
    for st in c.gt.strands() {
        rev.points.extend(st.iter().rev());
    }
    let f = compare_to_gt(&rev, &c.gt, head);
    println!("reversed: {f:?}");
    assert!(f.tangent_median_deg > 150.0, "{}", f.tangent_median_deg);
    assert_eq!(f.dist_median_mm, 0.0);
    // Only the strands rooted on the image's left (model x < 0): the right side's GT is
    // partly uncovered.
    let mut left = StrandSet::default();
    for st in c.gt.strands().filter(|st| st[0][0] < 0.0) {
        left.points.extend_from_slice(st);
        left.counts.push(st.len() as u32);
    }
    let f = compare_to_gt(&left, &c.gt, head);
    println!("left half: {f:?}");
    assert!(f.gt_covered_1cm < 0.9 && f.gt_covered_1cm > 0.4);
    // Far away: nothing near.
    let mut far = c.gt.clone();
    for p in &mut far.points {
        p[1] += 1.0;
    }
    let f = compare_to_gt(&far, &c.gt, head);
    assert_eq!(f.gt_covered_1cm, 0.0);
    assert_eq!(f.tangent_within_30, 0.0);
}

/// The modelling pipeline on the 3D cases (cpu, 256², fewer roots), judged in 2D by
/// `coif::model::figures` and in 3D against the GT.
#[test]
fn model_against_3d_ground_truth() {
    use coif::analyze::analyze;
    use coif::model::{figures, model_from_analysis, ModelParams};
    let engine = coif::Engine::cpu();
    let p = ModelParams {
        roots: 12_000,
        ..Default::default()
    };
    for style in [Style::Long, Style::SidePart, Style::Whorl] {
        for seed in 1..=2 {
            let c = case(style, seed, 256, 6000);
            let name = format!("{style} seed {seed}");
            let t = std::time::Instant::now();
            let mask: Vec<u8> = c.case.mask.pixels().map(|m| (m.0[0] > 127) as u8).collect();
            let an = analyze(
                &engine,
                &c.case.image,
                &c.case.strokes,
                Some(mask),
                &p.analyze,
            )
            .unwrap();
            let m = model_from_analysis(&engine, &c.case.image, an, Some(&c.case.landmarks), &p)
                .unwrap();
            let f = figures(&m);
            let g = compare_to_gt(&m.strands, &c.gt, &c.head);
            let cam_err = (m.camera.s - c.camera.s).abs() / c.camera.s;
            println!(
                "{name}: model {} strands, IoU {:.3}, direction {:.1}%, turning p99 {:.1}° | \
                 vs GT: tangent median {:.1}°, ≤30° {:.1}%, distance median {:.1} mm p90 {:.1} \
                 mm, GT covered (1 cm) {:.1}%, inside head {:.2}% | camera scale error {:.2}% \
                 ({:.1} s)",
                f.strands,
                f.coverage_iou,
                100.0 * f.direction_agreement,
                f.turn_p99_deg,
                g.tangent_median_deg,
                100.0 * g.tangent_within_30,
                g.dist_median_mm,
                g.dist_p90_mm,
                100.0 * g.gt_covered_1cm,
                100.0 * g.model_inside_head,
                100.0 * cam_err,
                t.elapsed().as_secs_f64()
            );
            // The landmarks are exact projections of the head's: the fit recovers the camera.
            assert!(cam_err < 0.01, "{name}: camera scale off by {cam_err}");
            // A reconstruction in the right place growing the right way: the long and
            // side-part models follow the true 3D tangents (median ≤ 30°). The whorl is a
            // known failure, printed but not bounded: its fringe (hair from a crown behind the
            // hairline falling onto the forehead) cannot be grown from roots along the field,
            // and the model grows much of the cap the wrong way (tangent median ~60-80° at
            // 256², see the issue 4 note).
            if style != Style::Whorl {
                assert!(g.tangent_median_deg <= 30.0, "{name}: {g:?}");
            }
            assert!(g.dist_median_mm <= 10.0, "{name}: {g:?}");
            assert!(g.gt_covered_1cm >= 0.3, "{name}: {g:?}");
            assert!(g.model_inside_head <= 0.05, "{name}: {g:?}");
        }
    }
}

#[test]
fn small_and_odd_sizes_work() {
    for (w, h) in [(64, 64), (300, 200), (192, 288)] {
        for style in Style::ALL {
            let c = synth3d_with(
                &SynthParams {
                    style,
                    seed: 3,
                    width: w,
                    height: h,
                },
                &Synth3dOptions {
                    strands: 1500,
                    ..Default::default()
                },
            );
            assert_eq!(c.case.image.dimensions(), (w, h));
            let hair = c.case.mask.pixels().filter(|p| p[0] == 255).count();
            assert!(
                hair as f64 > 0.02 * (w * h) as f64,
                "{style} {w}x{h}: {hair} px"
            );
            c.case.strokes.validate(Some((w, h))).unwrap();
            c.case.landmarks.validate(Some((w, h))).unwrap();
            // At 64² a short cap is a band a few pixels thick: no room for a stroke.
            if w.min(h) >= 192 {
                assert!(
                    !c.case.strokes.strokes.is_empty(),
                    "{style} {w}x{h}: no stroke"
                );
            }
        }
    }
}
