//! Comb and cut (issue 14, C13 appendix A): figures on strands grown on the parametric head
//! and drawn through its camera, the passes (`edit_comb`, `edit_cut`, with the stroke
//! geometry of `shared/edit_stroke.wgsl`) on lavapipe against their CPU mirrors, and the
//! command line's refusals.

use coif::edit::{self, DEFAULT_RADIUS};
use coif::gpu::engine::Engine;
use coif::hair::scene::Scene;
use coif::io::annot::{Stroke, StrokeKind, Strokes};
use coif::synth::synth3d::{synth3d_with, Synth3dOptions};
use coif::synth::{Style, SynthParams};
use glam::Vec3;

/// A scene of the 3D ground-truth synth (long style, frontal camera), `size` px square.
fn scene(n: usize, size: u32) -> Scene {
    scene_yaw(n, size, 0.0)
}

/// [`scene`] with the camera yaw drawn in ± `yaw` degrees.
fn scene_yaw(n: usize, size: u32, yaw: f32) -> Scene {
    let c = synth3d_with(
        &SynthParams {
            style: Style::Long,
            seed: 1,
            width: size,
            height: size,
        },
        &Synth3dOptions {
            strands: n,
            max_yaw_deg: yaw,
        },
    );
    println!("camera yaw {:.1}°", c.yaw_deg);
    Scene {
        dir: std::path::PathBuf::from("synth"),
        strands: c.gt,
        camera: Some(c.camera),
        head: Some(c.head),
        photo: Some(c.case.image.clone()),
        mask: None,
        width: size,
        height: size,
        animation: None,
        rest: None,
    }
}

fn proj(s: &Scene, p: [f32; 3]) -> [f64; 2] {
    let q = s.camera.unwrap().project(Vec3::from_array(p));
    [q.x as f64, q.y as f64]
}

/// Projected bounds of the strands: (x0, y0, x1, y1).
fn bounds(s: &Scene) -> [f64; 4] {
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for p in &s.strands.points {
        let q = proj(s, *p);
        b = [
            b[0].min(q[0]),
            b[1].min(q[1]),
            b[2].max(q[0]),
            b[3].max(q[1]),
        ];
    }
    b
}

/// A horizontal stroke of `kind` across the hair at height `fy` of its projected bounds.
fn across(s: &Scene, kind: StrokeKind, fy: f64) -> Strokes {
    let b = bounds(s);
    let y = (b[1] + fy * (b[3] - b[1])) as f32;
    let (x0, x1) = (b[0].max(1.0) as f32, b[2].min(s.width as f64 - 1.0) as f32);
    let pts = (0..=8)
        .map(|i| [x0 + (x1 - x0) * i as f32 / 8.0, y])
        .collect();
    Strokes::new(vec![Stroke::new(kind, pts)])
}

/// Nearest point of the stroke polyline (f64): distance and the stroke direction there.
fn nearest(st: &Strokes, p: [f64; 2]) -> (f64, [f64; 2]) {
    let mut best = (f64::MAX, [1.0, 0.0]);
    for s in &st.strokes {
        let q: Vec<[f64; 2]> = s
            .points
            .iter()
            .map(|p| [p[0] as f64, p[1] as f64])
            .collect();
        for w in q.windows(2) {
            let ab = [w[1][0] - w[0][0], w[1][1] - w[0][1]];
            let l2 = ab[0] * ab[0] + ab[1] * ab[1];
            let u = (((p[0] - w[0][0]) * ab[0] + (p[1] - w[0][1]) * ab[1]) / l2).clamp(0.0, 1.0);
            let d = ((p[0] - w[0][0] - u * ab[0]).powi(2) + (p[1] - w[0][1] - u * ab[1]).powi(2))
                .sqrt();
            if d < best.0 {
                let l = l2.sqrt();
                best = (d, [ab[0] / l, ab[1] / l]);
            }
        }
    }
    best
}

fn lavapipe() -> Engine {
    Engine::new(coif::gpu::engine::BackendChoice::Gpu).expect("a Vulkan adapter (lavapipe)")
}

/// A stroke of `kind` from near the top of the hair down to near its bottom, slanted by a
/// third of the hair's width: it starts among the roots, so strands run inside its band.
fn down(s: &Scene, kind: StrokeKind) -> Strokes {
    let b = bounds(s);
    let (w, h) = (b[2] - b[0], b[3] - b[1]);
    let cx = 0.5 * (b[0] + b[2]);
    let (p0, p1) = (
        [cx - w / 6.0, b[1] + 0.05 * h],
        [cx + w / 6.0, b[1] + 0.9 * h],
    );
    let pts = (0..=8)
        .map(|i| {
            let u = i as f64 / 8.0;
            [
                (p0[0] + u * (p1[0] - p0[0])) as f32,
                (p0[1] + u * (p1[1] - p0[1])) as f32,
            ]
        })
        .collect();
    Strokes::new(vec![Stroke::new(kind, pts)])
}

/// Combs `sc` with `strokes` and checks and prints its figures; returns (vertices that end
/// within R/4 of the stroke, those of them within 5° of the stroke direction).
fn comb_figures(name: &str, sc: &Scene, strokes: &Strokes) -> (usize, usize) {
    let r = DEFAULT_RADIUS;
    let (out, rep) = edit::comb(&Engine::cpu(), sc, strokes, r).unwrap();
    let cam = sc.camera.unwrap();
    let view_z = cam.r.row(2);
    let (off, s) = (sc.strands.offsets(), &sc.strands);
    let (mut len_err, mut depth_err) = (0.0f64, 0.0f64);
    let (mut far, mut far_same, mut roots_same) = (0, 0, 0);
    let (mut near, mut aligned) = (0usize, 0usize);
    let mut worst = 0.0f64;
    for i in 0..s.len() {
        let (p, q) = (
            &s.points[off[i]..off[i + 1]],
            &out.points[off[i]..off[i + 1]],
        );
        roots_same += (p[0] == q[0]) as usize;
        if p.iter()
            .all(|v| nearest(strokes, proj(sc, *v)).0 >= r as f64)
        {
            far += 1;
            far_same += (p == q) as usize;
        }
        for k in 0..p.len() {
            let dz = |v: [f32; 3]| (0..3).map(|c| view_z[c] as f64 * v[c] as f64).sum::<f64>();
            depth_err = depth_err.max((dz(q[k]) - dz(p[k])).abs());
            if k + 1 == p.len() {
                continue;
            }
            let l = |a: [f32; 3], b: [f32; 3]| {
                (0..3)
                    .map(|c| (b[c] as f64 - a[c] as f64).powi(2))
                    .sum::<f64>()
                    .sqrt()
            };
            let l0 = l(p[k], p[k + 1]);
            if l0 > 0.0 {
                len_err = len_err.max((l(q[k], q[k + 1]) - l0).abs() / l0);
            }
            // The outgoing segment of every vertex that ends within R/4 of the stroke.
            let (a, b) = (proj(sc, q[k]), proj(sc, q[k + 1]));
            let (d, t) = nearest(strokes, a);
            if d <= r as f64 / 4.0 {
                let e = [b[0] - a[0], b[1] - a[1]];
                let ang = (e[0] * t[1] - e[1] * t[0])
                    .atan2(e[0] * t[0] + e[1] * t[1])
                    .abs()
                    .to_degrees();
                near += 1;
                aligned += (ang <= 5.0) as usize;
                worst = worst.max(ang);
            }
        }
    }
    println!(
        "comb {name}, R {r}: {} of {} strands changed; segment length {len_err:.2e} rel, depth \
         {depth_err:.2e} m; roots same {roots_same}/{}; strands farther than R bit-identical \
         {far_same}/{far}; vertices ending within R/4 of the stroke within 5° of its direction: \
         {aligned}/{near} = {:.2}% (worst {worst:.1}°); non-root vertices inside the head {:.2}% \
         -> {:.2}%",
        rep.strands_changed,
        s.len(),
        s.len(),
        100.0 * aligned as f64 / near.max(1) as f64,
        100.0 * rep.inside_head_before.unwrap(),
        100.0 * rep.inside_head_after.unwrap()
    );
    assert!(
        rep.strands_changed > 100,
        "the stroke should reach the hair"
    );
    assert!(len_err <= 1e-5, "{len_err}");
    assert!(depth_err <= 1e-6, "{depth_err}");
    assert_eq!(roots_same, s.len());
    assert_eq!(far_same, far);
    (near, aligned)
}

#[test]
fn comb_keeps_lengths_depths_roots_and_aligns_with_the_stroke() {
    let sc = scene(1500, 256);
    // Down the hair from among the roots: strands run inside the band.
    let (near, aligned) = comb_figures("down the hair", &sc, &down(&sc, StrokeKind::Comb));
    assert!(near > 1000, "{near}");
    assert!(aligned as f64 >= 0.95 * near as f64, "{aligned}/{near}");
    // Across the hair: strands turn along the stroke as they enter its band and then run
    // parallel to it, so few or none end within R/4 (the share is printed, not required).
    comb_figures("across the hair", &sc, &across(&sc, StrokeKind::Comb, 0.55));
    // A turned camera: the view axis is not a model axis, so depths and lengths are kept
    // to rounding rather than exactly.
    let sc = scene_yaw(1500, 256, 40.0);
    let (near, aligned) = comb_figures(
        "down the hair, turned camera",
        &sc,
        &down(&sc, StrokeKind::Comb),
    );
    assert!(aligned as f64 >= 0.95 * near as f64, "{aligned}/{near}");
}

#[test]
fn edit_comb_parity_on_lavapipe() {
    let sc = scene_yaw(1200, 256, 40.0);
    let strokes = across(&sc, StrokeKind::Comb, 0.5);
    let (a, _) = edit::comb(&Engine::cpu(), &sc, &strokes, DEFAULT_RADIUS).unwrap();
    let mut gpu = lavapipe();
    // Small bindings, so the strands go up in several tiles.
    gpu.set_max_binding_bytes(256 * 1024);
    let (b, rep) = edit::comb(&gpu, &sc, &strokes, DEFAULT_RADIUS).unwrap();
    let worst = a
        .points
        .iter()
        .zip(&b.points)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).fold(0.0f32, f32::max))
        .fold(0.0f32, f32::max);
    let untouched_same = sc
        .strands
        .points
        .iter()
        .zip(&a.points)
        .zip(&b.points)
        .filter(|((o, p), _)| o == p)
        .all(|((o, _), q)| o == q);
    println!(
        "comb parity ({}): {} strands changed, largest difference {worst:.2e} m; vertices the mirror left alone are bit-identical on the GPU: {untouched_same}",
        rep.backend, rep.strands_changed
    );
    assert!(worst <= 1e-5, "{worst}");
    assert!(untouched_same);
}

/// First crossing (f64) of the projected strand with the stroke: the segment index and the
/// crossing point.
fn first_crossing(sc: &Scene, st: &Strokes, pts: &[[f32; 3]]) -> Option<(usize, [f64; 2])> {
    let q: Vec<[f64; 2]> = st.strokes[0]
        .points
        .iter()
        .map(|p| [p[0] as f64, p[1] as f64])
        .collect();
    for k in 0..pts.len().saturating_sub(1) {
        let (p0, p1) = (proj(sc, pts[k]), proj(sc, pts[k + 1]));
        for w in q.windows(2) {
            let (a, b) = (w[0], w[1]);
            let d = [p1[0] - p0[0], p1[1] - p0[1]];
            let e = [b[0] - a[0], b[1] - a[1]];
            let den = d[0] * e[1] - d[1] * e[0];
            if den == 0.0 {
                continue;
            }
            let f = [a[0] - p0[0], a[1] - p0[1]];
            let s = (f[0] * e[1] - f[1] * e[0]) / den;
            let u = (f[0] * d[1] - f[1] * d[0]) / den;
            if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&u) {
                return Some((k, [p0[0] + s * d[0], p0[1] + s * d[1]]));
            }
        }
    }
    None
}

#[test]
fn clean_cut_ends_at_the_crossing() {
    let sc = scene(1500, 256);
    let strokes = across(&sc, StrokeKind::Cut, 0.6);
    let (out, rep) = edit::cut(&Engine::cpu(), &sc, &strokes, 0.0, 7).unwrap();
    println!("{rep:?}");
    let off = sc.strands.offsets();
    let oo = out.offsets();
    let (mut crossing, mut within, mut same_k, mut untouched_same, mut untouched) = (0, 0, 0, 0, 0);
    let mut worst = 0.0f64;
    for i in 0..sc.strands.len() {
        let p = &sc.strands.points[off[i]..off[i + 1]];
        let q = &out.points[oo[i]..oo[i + 1]];
        match first_crossing(&sc, &strokes, p) {
            Some((k, x)) => {
                crossing += 1;
                same_k += (q.len() == k + 1) as usize;
                // The tip against the crossing, in units of the crossing segment.
                let tip = proj(&sc, q[q.len() - 1]);
                let (a, b) = (proj(&sc, p[k]), proj(&sc, p[k + 1]));
                let seg = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
                let d = ((tip[0] - x[0]).powi(2) + (tip[1] - x[1]).powi(2)).sqrt();
                let rel = d / seg.max(1e-12);
                worst = worst.max(rel);
                within += (rel <= 1.0 + 1e-9 && q == &p[..q.len()]) as usize;
            }
            None => {
                untouched += 1;
                untouched_same += (q == p) as usize;
            }
        }
    }
    println!(
        "clean cut: {crossing} strands cross; tip within one vertex spacing of the crossing (and a prefix) on {within}; \
         cut at the f64 first crossing on {same_k}; worst tip distance {worst:.3} spacings; \
         {untouched_same}/{untouched} strands that do not cross are bit-identical"
    );
    assert!(crossing > 200, "{crossing}");
    assert_eq!(within, crossing);
    assert_eq!(untouched_same, untouched);
}

#[test]
fn wide_cut_draws_one_third_and_edit_cut_agrees_on_both_backends() {
    let sc = scene(4000, 256);
    let strokes = across(&sc, StrokeKind::Cut, 0.5);
    let r = DEFAULT_RADIUS;
    let (out, rep) = edit::cut(&Engine::cpu(), &sc, &strokes, r, 11).unwrap();
    let mean = rep.mean_r_over_radius.unwrap();
    // Kolmogorov-Smirnov against the density 2(1 − x) of x = r/R that weights 1 − r/R give
    // on candidates spread evenly across the band (CDF 2x − x²), asymptotic p-value.
    let mut xs: Vec<f64> = out
        .strands()
        .map(|st| nearest(&strokes, proj(&sc, st[st.len() - 1])).0 / r as f64)
        .filter(|x| *x < 1.0)
        .collect();
    xs.sort_by(f64::total_cmp);
    let n = xs.len() as f64;
    let d = xs
        .iter()
        .enumerate()
        .map(|(i, &x)| {
            let f = 2.0 * x - x * x;
            (f - i as f64 / n).abs().max(((i + 1) as f64 / n - f).abs())
        })
        .fold(0.0f64, f64::max);
    let lam = (n.sqrt() + 0.12 + 0.11 / n.sqrt()) * d;
    let p: f64 = (1..100)
        .map(|k| {
            let k = k as f64;
            2.0 * (-1.0f64).powf(k - 1.0) * (-2.0 * k * k * lam * lam).exp()
        })
        .sum::<f64>()
        .clamp(0.0, 1.0);
    println!(
        "cut R {r}: {} strands drawn, mean r/R {mean:.4} (1/3 expected for candidates spread evenly across the band); KS D {d:.4}, p {p:.3}; {} cut",
        rep.drawn, rep.strands_cut
    );
    let a = edit::cut_counts(&Engine::cpu(), &sc, &strokes, r, 11).unwrap();
    let mut gpu = lavapipe();
    gpu.set_max_binding_bytes(256 * 1024);
    let b = edit::cut_counts(&gpu, &sc, &strokes, r, 11).unwrap();
    let same = a.iter().zip(&b).filter(|(x, y)| x == y).count();
    let a0 = edit::cut_counts(&Engine::cpu(), &sc, &strokes, 0.0, 11).unwrap();
    let b0 = edit::cut_counts(&gpu, &sc, &strokes, 0.0, 11).unwrap();
    let same0 = a0.iter().zip(&b0).filter(|(x, y)| x == y).count();
    println!(
        "cut parity: same vertex on {same}/{} strands at R {r}, {same0}/{} at R 0",
        a.len(),
        a0.len()
    );
    assert!(rep.drawn >= 1000, "{}", rep.drawn);
    assert!((mean - 1.0 / 3.0).abs() <= 0.02, "{mean}");
    assert!(p > 0.01, "KS p {p}");
    assert_eq!(same, a.len());
    assert_eq!(same0, a0.len());
}

fn coif(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_coif"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("coif runs")
}

#[test]
fn edit_cli_writes_a_model_and_refuses_bad_input() {
    let t = tempfile::tempdir().unwrap();
    let p = |s: &str| t.path().join(s).display().to_string();
    let mut sc = scene(150, 128);
    sc.dir = t.path().join("model");
    sc.save(&sc.dir, serde_json::json!({})).unwrap();
    across(&sc, StrokeKind::Comb, 0.5)
        .save(&t.path().join("comb.json"))
        .unwrap();
    across(&sc, StrokeKind::Cut, 0.5)
        .save(&t.path().join("cut.json"))
        .unwrap();
    // Near the roots: with R 32 some strands are drawn at their root and keep only it.
    across(&sc, StrokeKind::Cut, 0.0)
        .save(&t.path().join("top.json"))
        .unwrap();
    Strokes::new(vec![Stroke::new(
        StrokeKind::Comb,
        vec![[10.0, 10.0], [500.0, 10.0]],
    )])
    .save(&t.path().join("off.json"))
    .unwrap();
    // A degenerate stroke: `Strokes::save` refuses it, so it is written by hand.
    std::fs::write(
        t.path().join("dot.json"),
        r#"{"version":1,"strokes":[{"kind":"cut","points":[[10,10],[10,10]]}]}"#,
    )
    .unwrap();
    // The unedited model at the photo's view, which every edit must change.
    let o = coif(&[
        "render",
        "--backend",
        "cpu",
        "--model",
        &p("model"),
        "--out",
        &p("unedited.png"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let unedited = image::open(p("unedited.png")).unwrap().to_rgb8();
    for (tool, file, extra) in [
        ("--comb", "comb.json", vec![]),
        ("--cut", "cut.json", vec!["--radius", "0"]),
        ("--cut", "top.json", vec!["--radius", "32"]),
    ] {
        let out = p(&format!("out-{}", &file[..file.len() - 5]));
        let mut args = vec!["edit", "--backend", "cpu", "--model"];
        let (model, f) = (p("model"), p(file));
        args.extend([model.as_str(), tool, f.as_str(), "--out", out.as_str()]);
        args.extend(extra);
        let o = coif(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        println!("{}", String::from_utf8_lossy(&o.stdout));
        let meta: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(format!("{out}/model.json")).unwrap())
                .unwrap();
        assert_eq!(meta["edit"]["tool"], &tool[2..]);
        let back = Scene::load(std::path::Path::new(&out)).unwrap();
        let roots_only = back.strands.counts.iter().filter(|&&c| c == 1).count();
        println!("{out}: {roots_only} strands keep only their root");
        assert!(back.camera.is_some() && back.head.is_some());
        // Where the photo saw the edited strands, one to one with them.
        let rest = back
            .rest
            .as_ref()
            .expect("an edited model keeps its rest strands");
        assert_eq!(rest.counts, back.strands.counts);
        let o = coif(&[
            "render",
            "--backend",
            "cpu",
            "--model",
            &out,
            "--out",
            &format!("{out}.png"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // The edit shows at the photo's view (before, the photo came back whatever it did).
        let img = image::open(format!("{out}.png")).unwrap().to_rgb8();
        let changed = img
            .pixels()
            .zip(unedited.pixels())
            .filter(|(a, b)| (0..3).any(|k| a.0[k].abs_diff(b.0[k]) > 10))
            .count();
        println!("{out}: {changed} px differ from the unedited render by more than 10 levels");
        assert!(
            changed >= 20,
            "{tool} {file}: the edit does not show ({changed} px)"
        );
    }
    // A rest file that does not match the strands, and a bad `rest` key: clear errors.
    let edited = t.path().join("out-comb");
    let rest = coif::io::strands::read(&edited.join("rest.hair")).unwrap();
    let short = coif::hair::strands::StrandSet::new(
        rest.points[..rest.counts[0] as usize].to_vec(),
        vec![rest.counts[0]],
    );
    coif::io::strands::write(&edited.join("rest.hair"), &short).unwrap();
    let e = Scene::load(&edited).unwrap_err().to_string();
    assert!(e.contains("rest.hair") && e.contains("one to one"), "{e}");
    let meta_path = edited.join("model.json");
    let text = std::fs::read_to_string(&meta_path).unwrap();
    std::fs::write(&meta_path, text.replace("\"rest.hair\"", "\"../x.hair\"")).unwrap();
    let e = Scene::load(&edited).unwrap_err().to_string();
    assert!(e.contains("model.json") && e.contains("rest"), "{e}");
    let cases: &[(&[&str], &str)] = &[
        (&["--comb", "cut.json"], "cut.json"),
        (&["--cut", "comb.json"], "comb.json"),
        (&["--comb", "off.json"], "off.json"),
        (&["--comb", "missing.json"], "missing.json"),
        (&["--cut", "dot.json"], "dot.json"),
    ];
    for (extra, needle) in cases {
        let (model, out) = (p("model"), p("bad"));
        let file = p(extra[1]);
        let o = coif(&[
            "edit",
            "--backend",
            "cpu",
            "--model",
            &model,
            extra[0],
            &file,
            "--out",
            &out,
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        println!("{extra:?}: exit {:?}: {}", o.status.code(), err.trim());
        assert!(!o.status.success());
        assert!(err.contains(needle), "{extra:?}: {err}");
        assert!(!t.path().join("bad").exists(), "{extra:?} wrote output");
    }
    for radius in ["nan", "-1"] {
        let o = coif(&[
            "edit",
            "--backend",
            "cpu",
            "--model",
            &p("model"),
            "--comb",
            &p("comb.json"),
            "--radius",
            radius,
            "--out",
            &p("bad"),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        println!(
            "--radius {radius}: exit {:?}: {}",
            o.status.code(),
            err.trim()
        );
        assert_eq!(o.status.code(), Some(64), "{err}");
        assert!(err.contains("--radius"), "{err}");
        assert!(!t.path().join("bad").exists());
    }
    // A missing model folder, and a model without a camera (imported strands).
    let o = coif(&[
        "edit",
        "--backend",
        "cpu",
        "--model",
        &p("nope"),
        "--comb",
        &p("comb.json"),
        "--out",
        &p("bad"),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("missing model: exit {:?}: {}", o.status.code(), err.trim());
    assert!(!o.status.success() && err.contains("nope"), "{err}");
    let o = coif(&["import", &p("model/strands.hair"), "--out", &p("bare")]);
    assert!(o.status.success());
    let o = coif(&[
        "edit",
        "--backend",
        "cpu",
        "--model",
        &p("bare"),
        "--comb",
        &p("comb.json"),
        "--out",
        &p("bad"),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("no camera: exit {:?}: {}", o.status.code(), err.trim());
    assert_eq!(o.status.code(), Some(65), "{err}");
    assert!(
        err.contains("model.json") && err.contains("no camera"),
        "{err}"
    );
    assert!(!t.path().join("bad").exists());
}

/// The strand hierarchy: centres plus residuals give back every strand at every level, and a
/// comb at level 2 moves the members with their residuals unchanged.
#[test]
fn hierarchy_rebuilds_strands_and_a_level_2_comb_keeps_residuals() {
    use coif::edit::hierarchy::{Hierarchy, HierarchyParams};
    let sc = scene(3000, 256);
    let t = std::time::Instant::now();
    let h = Hierarchy::build(&sc.strands, &HierarchyParams::default()).unwrap();
    let sizes: Vec<usize> = h.levels.iter().map(|l| l.centres.len()).collect();
    println!(
        "hierarchy of {} strands: clusters per level {sizes:?} ({:.2} s)",
        sc.strands.len(),
        t.elapsed().as_secs_f64()
    );
    assert!(h.levels.len() >= 2, "{sizes:?}");
    for level in 1..=h.levels.len() {
        let same = h
            .rebuild(level, h.centres(level).unwrap(), &sc.strands)
            .unwrap();
        assert_eq!(same.counts, sc.strands.counts);
        let worst = same
            .points
            .iter()
            .zip(&sc.strands.points)
            .map(|(a, b)| (Vec3::from_array(*a) - Vec3::from_array(*b)).length())
            .fold(0.0f32, f32::max);
        println!("  level {level}: rebuilt within {worst:.2e} m");
        assert!(worst <= 1e-5, "level {level}: {worst} m");
    }
    // Comb the level-2 centres, then rebuild.
    let centres = h.centres(2).unwrap().clone();
    let csc = Scene {
        strands: centres.clone(),
        ..sc.clone()
    };
    let (combed, rep) = edit::comb(
        &Engine::cpu(),
        &csc,
        &down(&sc, StrokeKind::Comb),
        DEFAULT_RADIUS,
    )
    .unwrap();
    assert!(
        rep.strands_changed > 0,
        "the comb should move some level-2 centres"
    );
    let (out, levels) = h.rebuild_levels(2, &combed, &sc.strands).unwrap();
    assert_eq!(out.counts, sc.strands.counts);
    assert!(
        out.strands()
            .zip(sc.strands.strands())
            .all(|(a, b)| a[0] == b[0]),
        "roots moved"
    );
    // The level-1 centres are the members of level 2: re-derive their residuals.
    let lv = &h.levels[1];
    let rest: Vec<&[[f32; 3]]> = centres.strands().collect();
    let now: Vec<&[[f32; 3]]> = combed.strands().collect();
    let mut worst = 0.0f32;
    for (i, member) in levels[0].iter().enumerate() {
        let c = lv.parent[i] as usize;
        let r = &lv.residuals[i];
        let again = Hierarchy::offsets_on(r, rest[c], now[c], member);
        for (a, b) in again.iter().zip(&r.offset).skip(1) {
            worst = worst.max((Vec3::from_array(*a) - Vec3::from_array(*b)).length());
        }
    }
    let moved = out
        .points
        .iter()
        .zip(&sc.strands.points)
        .filter(|(a, b)| a != b)
        .count();
    println!(
        "comb at level 2: {} of {} centres changed, {moved} strand vertices moved; level-1 \
         residuals re-derived within {worst:.2e} m",
        rep.strands_changed,
        centres.len()
    );
    assert!(moved > 0);
    assert!(worst <= 1e-5, "{worst} m");
}

/// `coif edit --level L`: the strokes act on cluster centres and the strands follow; a
/// level the hierarchy does not have is refused, writing nothing.
#[test]
fn edit_cli_at_a_hierarchy_level() {
    let t = tempfile::tempdir().unwrap();
    let p = |s: &str| t.path().join(s).display().to_string();
    let mut sc = scene(1200, 256);
    sc.dir = t.path().join("model");
    sc.save(&sc.dir, serde_json::json!({})).unwrap();
    across(&sc, StrokeKind::Comb, 0.5)
        .save(&t.path().join("comb.json"))
        .unwrap();
    let run = |level: &str, out: &str| {
        let (model, comb, out) = (p("model"), p("comb.json"), p(out));
        coif(&[
            "edit",
            "--backend",
            "cpu",
            "--model",
            &model,
            "--comb",
            &comb,
            "--level",
            level,
            "--out",
            &out,
        ])
    };
    let o = run("1", "l1");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    println!("{out}");
    assert!(out.contains("hierarchy        level 1"), "{out}");
    let back = Scene::load(&t.path().join("l1")).unwrap();
    assert_eq!(back.strands.counts, sc.strands.counts);
    assert_ne!(back.strands.points, sc.strands.points);
    let o = run("9", "l9");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(64), "{err}");
    assert!(err.contains("--level 9"), "{err}");
    assert!(!t.path().join("l9").exists());
}
