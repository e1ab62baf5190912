//! Depth rasterisation (lavapipe against the CPU mirror, and against an analytic sphere), the
//! initial hair shape, the hair volume H on a synthetic portrait, and the curve constraints.
//!
//! Parity tolerance: identical coverage (the coverage test is integer arithmetic on both
//! sides) and depth within 1e-4 of the scene's depth range on every covered pixel (the
//! interpolation is f32 and the GPU may fuse multiply-adds). The output buffers start at the
//! pass's "empty" words, which act as the sentinels: a pixel the pass should have written but
//! did not shows up as a coverage mismatch or as a hole in the analytic sphere test.

use coif::base::rng::Rng;
use coif::gpu::engine::{BackendChoice, Engine, Recording};
use coif::model::volume::{
    hair_shape_mesh, hair_volume, lift_curves, pack_meshes, rasterize_depth, record_depth_raster,
    DepthMaps, HairShapeParams, HairVolume, HeadInput, Mesh, VolumeParams,
};
use coif::stages::depth_raster::{decode_depth, BACK_EMPTY, FRONT_EMPTY};
use coif::synth::{synth, Style, SynthCase, SynthParams};

fn gpu() -> Engine {
    Engine::new(BackendChoice::Gpu).unwrap_or_else(|e| {
        panic!("{e}\nthe GPU tests need a Vulkan adapter: apt-get install mesa-vulkan-drivers")
    })
}

fn raw_raster(e: &Engine, w: u32, h: u32, meshes: &[&Mesh]) -> (Vec<u32>, Vec<u32>) {
    let (verts, tris) = pack_meshes(meshes).unwrap();
    let mut rec = Recording::default();
    let (f, b) = record_depth_raster(&mut rec, w, h, &verts, &tris);
    rec.download(f);
    rec.download(b);
    let dl = e.run(rec).unwrap();
    (dl.get::<u32>(f), dl.get::<u32>(b))
}

/// Random triangles over and around a w x h image, and separately the awkward ones: a
/// triangle much larger than the image (the bounding-box clamp), one entirely outside, a
/// degenerate one.
fn random_mesh(w: u32, h: u32, n: usize, seed: u64) -> (Mesh, Mesh) {
    let mut rng = Rng::new(seed);
    let (wf, hf) = (w as f32, h as f32);
    let mut m = Mesh::default();
    for t in 0..n {
        let size = if t % 7 == 0 { 0.8 } else { 0.2 };
        let c = [rng.range_f32(-5.0, wf + 5.0), rng.range_f32(-5.0, hf + 5.0)];
        for _ in 0..3 {
            m.verts.push([
                c[0] + size * wf.max(8.0) * rng.range_f32(-1.0, 1.0),
                c[1] + size * hf.max(8.0) * rng.range_f32(-1.0, 1.0),
                rng.range_f32(-50.0, 80.0),
            ]);
        }
        let b = 3 * t as u32;
        m.tris.push([b, b + 1, b + 2]);
    }
    let extra = [
        [
            [-900.0, -700.0, 3.0],
            [wf + 900.0, -10.0, -7.0],
            [10.0, hf + 1000.0, 20.0],
        ],
        [
            [wf + 10.0, 1.0, 0.0],
            [wf + 30.0, 5.0, 0.0],
            [wf + 12.0, 20.0, 0.0],
        ],
        [[0.0, 0.0, 1.0], [wf, hf, 2.0], [0.5 * wf, 0.5 * hf, 3.0]],
    ];
    let mut e = Mesh::default();
    for tri in extra {
        let b = e.verts.len() as u32;
        e.verts.extend(tri);
        e.tris.push([b, b + 1, b + 2]);
    }
    (m, e)
}

/// GPU against CPU: identical coverage, depth within 1e-4 of the depth range.
fn check_parity(name: &str, g: &Engine, w: u32, h: u32, meshes: &[&Mesh]) -> usize {
    let (gf, gb) = raw_raster(g, w, h, meshes);
    let (cf, cb) = raw_raster(&Engine::cpu(), w, h, meshes);
    let zs = meshes.iter().flat_map(|m| m.verts.iter().map(|v| v[2]));
    let (lo, hi) = zs.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), z| {
        (a.min(z), b.max(z))
    });
    let tol = 1e-4 * (hi - lo).max(1.0);
    let (mut covered, mut max_diff) = (0usize, 0.0f32);
    for i in 0..(w * h) as usize {
        assert_eq!(
            gf[i] == FRONT_EMPTY,
            cf[i] == FRONT_EMPTY,
            "{name}: front coverage differs at pixel {i}"
        );
        assert_eq!(
            gb[i] == BACK_EMPTY,
            cb[i] == BACK_EMPTY,
            "{name}: back coverage differs at pixel {i}"
        );
        assert_eq!(cf[i] == FRONT_EMPTY, cb[i] == BACK_EMPTY, "{name}: {i}");
        if cf[i] == FRONT_EMPTY {
            continue;
        }
        covered += 1;
        for (a, b) in [(gf[i], cf[i]), (gb[i], cb[i])] {
            let d = (decode_depth(a) - decode_depth(b)).abs();
            assert!(
                d <= tol,
                "{name}: pixel {i}: gpu {} cpu {} differ by {d} > {tol}",
                decode_depth(a),
                decode_depth(b)
            );
            max_diff = max_diff.max(d);
        }
    }
    println!(
        "depth_raster parity {name} {w}x{h}: {covered} covered pixels, identical coverage, \
         max depth diff {max_diff:.3e} (tolerance {tol:.3e} = 1e-4 of the depth range)"
    );
    covered
}

#[test]
fn depth_raster_matches_cpu() {
    let g = gpu();
    for (k, &(w, h)) in [(1u32, 1u32), (63, 65), (200, 120)].iter().enumerate() {
        let (m, extra) = random_mesh(w, h, 300, 11 + k as u64);
        let covered = check_parity("random triangles", &g, w, h, &[&m]);
        assert!(covered > 0 && (w * h == 1 || covered < (w * h) as usize));
        check_parity(
            "random + oversized/outside/degenerate",
            &g,
            w,
            h,
            &[&m, &extra],
        );
    }
    // A sphere and an ellipsoid: shared edges through pixel centres are common here.
    let sphere = Mesh::ellipsoid([48.5, 40.0, 7.0], [30.0, 30.0, 30.0], 24, 48);
    let ell = Mesh::ellipsoid([30.0, 50.0, -20.0], [20.0, 35.0, 12.5], 16, 32);
    let covered = check_parity("sphere + ellipsoid", &g, 97, 83, &[&sphere, &ell]);
    assert!(covered > 2800, "{covered}");
}

#[test]
fn depth_raster_of_sphere_matches_analytic_depth() {
    let (w, h) = (96u32, 90u32);
    let (c, r) = ([47.3f32, 44.8f32, 12.0f32], 38.0f32);
    let (n_lat, n_lon) = (48u32, 96u32);
    let sphere = Mesh::ellipsoid(c, [r; 3], n_lat, n_lon);
    let g = gpu();
    let maps = rasterize_depth(&g, w, h, &[&sphere]).unwrap();
    // The faces lie inside the sphere by at most the sagitta of the larger angular step;
    // depth is measured where the surface is at most 64° from facing the camera.
    // Within r <= 0.9 R a radial error e shows as at most e / sqrt(1 - 0.81) along the view
    // ray, and the 1/32 px snap of x, y moves depth by at most slope 0.9 / sqrt(0.19) per px.
    let step = std::f32::consts::PI / n_lat as f32;
    let sagitta = r * (1.0 - step.cos());
    let slope = 1.0 / (1.0 - 0.81f32).sqrt();
    let tol = sagitta * slope + slope / 32.0;
    let r_in = r * (step / 2.0).cos() * (std::f32::consts::PI / n_lon as f32).cos() - 0.1;
    let mut max_err = 0.0f32;
    for j in 0..h {
        for i in 0..w {
            let p = (j * w + i) as usize;
            let (dx, dy) = (i as f32 + 0.5 - c[0], j as f32 + 0.5 - c[1]);
            let rr = (dx * dx + dy * dy).sqrt();
            if rr > r + 0.1 {
                assert!(
                    !maps.covered(p),
                    "pixel ({i}, {j}) outside the sphere is covered"
                );
                continue;
            }
            if rr < r_in {
                assert!(
                    maps.covered(p),
                    "pixel ({i}, {j}) inside the sphere is empty"
                );
            }
            if rr < 0.9 * r {
                let dz = (r * r - rr * rr).sqrt();
                let ef = (maps.front[p] - (c[2] + dz)).abs();
                let eb = (maps.back[p] - (c[2] - dz)).abs();
                assert!(
                    ef <= tol && eb <= tol,
                    "({i}, {j}): errors {ef} {eb} > {tol}"
                );
                assert!(
                    maps.front[p] <= c[2] + dz + slope / 32.0,
                    "faces lie inside the sphere"
                );
                max_err = max_err.max(ef).max(eb);
            }
        }
    }
    println!(
        "sphere r={r} ({n_lat}x{n_lon}) on lavapipe: max |depth - analytic| {max_err:.4} px \
         within 0.9 r (bound {tol:.4})"
    );
}

#[test]
fn rasteriser_refuses_bad_meshes() {
    let e = Engine::cpu();
    let big = Mesh {
        verts: vec![[0.0, 0.0, 0.0], [3000.0, 0.0, 0.0], [0.0, 10.0, 0.0]],
        tris: vec![[0, 1, 2]],
    };
    let msg = rasterize_depth(&e, 8, 8, &[&big]).unwrap_err().to_string();
    assert!(msg.contains("subdivide"), "{msg}");
    let bad_index = Mesh {
        verts: vec![[0.0; 3]; 3],
        tris: vec![[0, 1, 3]],
    };
    assert!(rasterize_depth(&e, 8, 8, &[&bad_index]).is_err());
    let nan = Mesh {
        verts: vec![[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        tris: vec![[0, 1, 2]],
    };
    assert!(rasterize_depth(&e, 8, 8, &[&nan]).is_err());
    assert!(rasterize_depth(&e, 0, 8, &[]).is_err());
    // No mesh at all: everything empty.
    let empty = rasterize_depth(&e, 5, 3, &[]).unwrap();
    assert!((0..15).all(|i| !empty.covered(i) && empty.back[i] == f32::INFINITY));
}

// ---------------------------------------------------------------------------------------------
// Hair volume on a synthetic portrait
// ---------------------------------------------------------------------------------------------

struct Head {
    mesh: Mesh,
    centre: [f32; 3],
    radii: [f32; 3],
}

impl Head {
    /// Approximate signed distance of the ellipsoid, px, negative inside (exact sign).
    fn sdf(&self, p: [f32; 3]) -> f32 {
        let q: [f32; 3] = std::array::from_fn(|a| (p[a] - self.centre[a]) / self.radii[a]);
        let k = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        (k - 1.0) * self.radii.iter().fold(f32::INFINITY, |m, &r| m.min(r))
    }
}

/// A skull ellipsoid under the synthetic hair: the synth face ellipse (cx, cy, a, b) comes
/// back from the landmarks (eyes at cx ± 0.4a, cy - 0.1b; chin at cy + b), the skull centre
/// is (cx, cy - 0.3b) as in synth's Scene::new; the hair envelope there is about 1.6a x 1.3b.
fn synth_head(case: &SynthCase, centre_z: f32) -> Head {
    let l = |n: &str| case.landmarks.get(n).unwrap();
    let (le, re, chin) = (l("left_eye"), l("right_eye"), l("chin"));
    let a = (re[0] - le[0]) / 0.8;
    let eye_y = 0.5 * (le[1] + re[1]);
    let b = (chin[1] - eye_y) / 1.1;
    let (cx, cy) = (0.5 * (le[0] + re[0]), eye_y + 0.1 * b);
    let centre = [cx, cy - 0.3 * b, centre_z];
    let radii = [1.2 * a, 1.1 * b, 1.2 * a];
    Head {
        mesh: Mesh::ellipsoid(centre, radii, 24, 48),
        centre,
        radii,
    }
}

fn build(case: &SynthCase, head: &Head, engine: &Engine) -> coif::error::Result<HairVolume> {
    let sdf = |p: [f32; 3]| head.sdf(p);
    let input = HeadInput {
        mesh: &head.mesh,
        centre_z: head.centre[2],
        sdf: &sdf,
    };
    hair_volume(
        engine,
        case.mask.as_raw(),
        case.width,
        case.height,
        &input,
        &VolumeParams::default(),
    )
}

/// IoU of H's projection with the mask: over grid columns (mask sampled at the column centre)
/// and over pixels (a pixel is projected when its column holds H).
fn projection_iou(vol: &HairVolume) -> (f64, f64) {
    let g = &vol.grid;
    let proj: Vec<bool> = (0..g.dims[1])
        .flat_map(|j| (0..g.dims[0]).map(move |i| (i, j)))
        .map(|(i, j)| vol.front_cell(i, j).is_some())
        .collect();
    let (mut inter, mut uni) = (0usize, 0usize);
    for j in 0..g.dims[1] {
        for i in 0..g.dims[0] {
            let c = g.centre([i, j, 0]);
            let m = vol.pixel(c[0], c[1]).is_some_and(|p| vol.mask[p] != 0);
            let p = proj[(j * g.dims[0] + i) as usize];
            inter += (m && p) as usize;
            uni += (m || p) as usize;
        }
    }
    let col = inter as f64 / uni as f64;
    let (mut inter, mut uni) = (0usize, 0usize);
    for y in 0..vol.height {
        for x in 0..vol.width {
            let m = vol.mask[(y * vol.width + x) as usize] != 0;
            let c = g.cell_at([x as f32 + 0.5, y as f32 + 0.5, g.origin[2] + 0.5 * g.cell]);
            let p = c.is_some_and(|c| proj[(c[1] * g.dims[0] + c[0]) as usize]);
            inter += (m && p) as usize;
            uni += (m || p) as usize;
        }
    }
    (col, inter as f64 / uni as f64)
}

#[test]
fn hair_volume_on_synthetic_portrait() {
    let case = synth(&SynthParams::new(Style::Long, 1));
    let head = synth_head(&case, 120.0);
    let t0 = std::time::Instant::now();
    let vol = build(&case, &head, &Engine::cpu()).unwrap();
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let g = &vol.grid;
    assert_eq!(g.dims.iter().max(), Some(&80));
    assert_eq!(vol.h.len(), g.len());
    assert!(vol.count > 0 && vol.count == vol.h.iter().filter(|&&v| v == 1).count());
    // No H cell inside the head; every H cell over hair (at least `min_hair_fraction` of the
    // pixels under it) and between the maps at one of those hair pixels.
    let frac = VolumeParams::default().min_hair_fraction;
    let half = 0.5 * g.cell;
    for (idx, _) in vol.h.iter().enumerate().filter(|(_, &v)| v != 0) {
        let c = g.centre(g.coords(idx));
        assert!(
            head.sdf(c) > 0.0,
            "H cell {idx} at {c:?} is inside the head"
        );
        let (mut total, mut hair, mut between) = (0, 0, false);
        for y in
            (c[1] - half).floor().max(0.0) as u32..((c[1] + half).ceil() as u32).min(vol.height)
        {
            for x in
                (c[0] - half).floor().max(0.0) as u32..((c[0] + half).ceil() as u32).min(vol.width)
            {
                total += 1;
                let p = (y * vol.width + x) as usize;
                if vol.mask[p] != 0 {
                    hair += 1;
                    between |= c[2] - half <= vol.front[p] && c[2] + half >= vol.back[p];
                }
            }
        }
        assert!(
            hair as f32 >= frac * total as f32,
            "H cell {idx}: {hair}/{total} hair pixels"
        );
        assert!(between, "H cell {idx} at {c:?} is outside the depth maps");
    }
    // Front before back on every hair pixel, and the hair encloses the head there.
    let mut hair_px = 0;
    for i in 0..vol.mask.len() {
        if vol.mask[i] == 0 {
            continue;
        }
        hair_px += 1;
        assert!(
            vol.front[i].is_finite() && vol.back[i].is_finite(),
            "pixel {i}"
        );
        assert!(vol.front[i] >= vol.back[i], "pixel {i}");
        if vol.head.covered(i) {
            assert!(vol.front[i] >= vol.head.front[i] && vol.back[i] <= vol.head.back[i]);
        }
    }
    let (col_iou, px_iou) = projection_iou(&vol);
    println!(
        "hair volume (synth long seed 1, 512x512, {hair_px} hair px): grid {:?} cell {:.3} px, \
         |H| = {} cells, hair mesh {} tris; IoU(projection of H, mask) = {col_iou:.4} over \
         grid columns, {px_iou:.4} over pixels; {ms:.0} ms on the CPU backend",
        g.dims,
        g.cell,
        vol.count,
        vol.hair_mesh.tris.len()
    );
    assert!(col_iou >= 0.95, "column IoU {col_iou}");
    assert!(px_iou >= 0.95, "pixel IoU {px_iou}");

    // Constraints from the strokes, plus a curve leaving the mask (its tail is dropped).
    let mut curves: Vec<Vec<[f32; 2]>> = case
        .strokes
        .strokes
        .iter()
        .map(|s| s.points.clone())
        .collect();
    let start = curves[0][0];
    curves.push(
        (0..200)
            .map(|k| [start[0], start[1] + 3.0 * k as f32])
            .collect(),
    );
    assert_eq!(vol.mask[0], 0, "the image corner is background");
    let (none, none_c) = lift_curves(&[vec![[0.5, 0.5], [2.5, 1.5], [4.0, 3.0]]], &vol);
    assert!(none.is_empty() && none_c.is_empty());
    let (lines, cons) = lift_curves(&curves, &vol);
    assert!(!lines.is_empty() && !cons.is_empty());
    let n_pts: usize = lines.iter().map(|l| l.len()).sum();
    let n_in: usize = curves.iter().map(|c| c.len()).sum();
    assert!(n_pts < n_in, "points off the mask must be dropped");
    let (mut sum_d, mut max_d) = (0.0f64, 0.0f32);
    for p in lines.iter().flatten() {
        let pix = vol.pixel(p[0], p[1]).unwrap();
        assert_eq!(vol.mask[pix], 1);
        let c = g.cell_at(*p).unwrap();
        let k = vol.front_cell(c[0], c[1]).unwrap();
        assert_eq!(
            c[2], k,
            "lifted point {p:?} is not in the front-most H cell"
        );
        let zc = g.centre([c[0], c[1], k])[2];
        assert!((p[2] - zc).abs() <= 0.5 * g.cell * (1.0 + 1e-4));
        let d = (p[2] - vol.front[pix]).abs();
        (sum_d, max_d) = (sum_d + d as f64, max_d.max(d));
    }
    let mean_d = sum_d / n_pts as f64;
    assert!(mean_d <= 0.25 * g.cell as f64, "{mean_d}");
    for &(cell, t) in &cons {
        assert_eq!(vol.h[cell as usize], 1);
        let n = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        assert!((n - 1.0).abs() < 1e-4, "{t:?}");
    }
    assert!(
        cons.windows(2).all(|w| w[0].0 < w[1].0),
        "one sorted entry per cell"
    );
    println!(
        "lift_curves: {} curves ({n_in} points) -> {} polylines ({n_pts} points), {} \
         constraint cells; |z - front map| mean {mean_d:.3} px, max {max_d:.3} px",
        curves.len(),
        lines.len(),
        cons.len()
    );
}

#[test]
fn hair_volume_gpu_matches_cpu() {
    let case = synth(&SynthParams {
        width: 160,
        height: 144,
        ..SynthParams::new(Style::Long, 2)
    });
    let head = synth_head(&case, -40.0);
    let c = build(&case, &head, &Engine::cpu()).unwrap();
    let g = build(&case, &head, &gpu()).unwrap();
    assert_eq!(c.grid.dims, g.grid.dims);
    let same = c.h.iter().zip(&g.h).filter(|(a, b)| a == b).count();
    let frac = same as f64 / c.h.len() as f64;
    println!(
        "hair volume 160x144 on lavapipe vs CPU: grid {:?}, |H| {} vs {}, {:.5} of cells agree",
        c.grid.dims, g.count, c.count, frac
    );
    assert!(frac >= 0.999, "{frac}");
}

#[test]
fn hair_shape_mesh_is_closed() {
    let case = synth(&SynthParams {
        width: 128,
        height: 128,
        ..SynthParams::new(Style::Whorl, 3)
    });
    let head = synth_head(&case, 0.0);
    let maps = rasterize_depth(&Engine::cpu(), 128, 128, &[&head.mesh]).unwrap();
    let mask: Vec<bool> = case.mask.as_raw().iter().map(|&m| m > 127).collect();
    for lattice_px in [1, 2, 3] {
        let params = HairShapeParams {
            lattice_px,
            ..HairShapeParams::default()
        };
        let mesh = hair_shape_mesh(&mask, &maps, 0.0, 2.0, &params).unwrap();
        // Closed and consistently oriented: every directed edge is unique and its reverse
        // exists.
        let mut edges = std::collections::HashSet::new();
        for t in &mesh.tris {
            for e in 0..3 {
                assert!(edges.insert((t[e], t[(e + 1) % 3])), "edge used twice");
            }
        }
        assert!(edges.iter().all(|&(a, b)| edges.contains(&(b, a))));
        // Its projection covers every hair pixel.
        let own = rasterize_depth(&Engine::cpu(), 128, 128, &[&mesh]).unwrap();
        assert!((0..mask.len()).all(|i| !mask[i] || own.covered(i)));
        assert!((0..mask.len()).all(|i| !own.covered(i) || own.front[i] > own.back[i]));
    }
}

#[test]
fn bad_inputs_error_cleanly() {
    let case = synth(&SynthParams {
        width: 96,
        height: 96,
        ..SynthParams::new(Style::Short, 1)
    });
    let head = synth_head(&case, 0.0);
    let e = Engine::cpu();
    let sdf = |p: [f32; 3]| head.sdf(p);
    let input = HeadInput {
        mesh: &head.mesh,
        centre_z: 0.0,
        sdf: &sdf,
    };
    let p = VolumeParams::default();
    let mask = case.mask.as_raw();
    let err = |r: coif::error::Result<HairVolume>| r.unwrap_err().to_string();
    assert!(build(&case, &head, &e).is_ok());
    let m = err(hair_volume(&e, &mask[1..], 96, 96, &input, &p));
    assert!(m.contains("mask"), "{m}");
    let m = err(hair_volume(&e, &vec![0u8; 96 * 96], 96, 96, &input, &p));
    assert!(m.contains("empty"), "{m}");
    // A head far away from the hair.
    let away = Mesh::ellipsoid([500.0, 500.0, 0.0], [10.0; 3], 8, 16);
    let m = err(hair_volume(
        &e,
        mask,
        96,
        96,
        &HeadInput {
            mesh: &away,
            ..input
        },
        &p,
    ));
    assert!(m.contains("overlap"), "{m}");
    // A head that fills all space leaves nothing of H.
    let everywhere = |_: [f32; 3]| -1.0f32;
    let m = err(hair_volume(
        &e,
        mask,
        96,
        96,
        &HeadInput {
            sdf: &everywhere,
            ..input
        },
        &p,
    ));
    assert!(m.contains("volume is empty"), "{m}");
    let m = err(hair_volume(
        &e,
        mask,
        96,
        96,
        &HeadInput {
            centre_z: f32::NAN,
            ..input
        },
        &p,
    ));
    assert!(m.contains("not finite"), "{m}");
    let tiny = VolumeParams {
        cells: 3,
        ..VolumeParams::default()
    };
    assert!(hair_volume(&e, mask, 96, 96, &input, &tiny).is_err());
    let maps = DepthMaps {
        width: 4,
        height: 4,
        front: vec![0.0; 16],
        back: vec![0.0; 16],
    };
    let m = hair_shape_mesh(&[true; 15], &maps, 0.0, 1.0, &HairShapeParams::default())
        .unwrap_err()
        .to_string();
    assert!(m.contains("15 pixels"), "{m}");
}

#[test]
fn every_stage_validates_with_naga() {
    for stage in coif::stages::ALL {
        // Shaders name shared pieces with `#include`; naga sees them expanded.
        let src = coif::gpu::wgsl::compose(stage.name, stage.wgsl).unwrap();
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{}: {}", stage.name, e.emit_to_string(&src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}: {:?}", stage.name, e.into_inner()));
    }
}
