//! The strand rasteriser: lavapipe against the CPU mirror on small scenes, coverage and
//! anti-aliasing rules checked pixel by pixel on both paths, bad input, determinism, limits.
//! Both render passes include `shared/raster_common.wgsl` (mirror: `stages::raster_common`).
//! Run with `--release` (shaders on lavapipe).

use coif::base::colour::to_rgba8;
use coif::base::rng::Rng;
use coif::gpu::GpuContext;
use coif::hair::head::{Head, WeakPerspective};
use coif::render::raster::*;
use glam::{Vec2, Vec3};
use std::sync::OnceLock;

fn ctx() -> &'static GpuContext {
    static CTX: OnceLock<GpuContext> = OnceLock::new();
    CTX.get_or_init(|| GpuContext::new().expect("a wgpu adapter (lavapipe) is needed"))
}

/// Share of pixels whose 8-bit sRGB channels (and alpha) all differ by at most `tol`, and
/// the largest channel difference seen.
fn srgb8_agreement(a: &[[f32; 4]], b: &[[f32; 4]], tol: u8) -> (f64, u8) {
    assert_eq!(a.len(), b.len(), "images differ in size");
    let (a8, b8) = (to_rgba8(a), to_rgba8(b));
    let mut ok = 0usize;
    let mut worst = 0u8;
    for (p, q) in a8.chunks_exact(4).zip(b8.chunks_exact(4)) {
        let d = p.iter().zip(q).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
        worst = worst.max(d);
        ok += (d <= tol) as usize;
    }
    (ok as f64 / a.len().max(1) as f64, worst)
}

/// The acceptance figure: Ok(share) when >= `min_share` of pixels are within `tol` levels.
fn agree(
    what: &str,
    a: &[[f32; 4]],
    b: &[[f32; 4]],
    tol: u8,
    min_share: f64,
) -> Result<f64, String> {
    let (share, worst) = srgb8_agreement(a, b, tol);
    println!(
        "{what}: {:.3}% of pixels within {tol}/255 (worst channel difference {worst})",
        100.0 * share
    );
    if share >= min_share {
        Ok(share)
    } else {
        Err(format!(
            "{what}: only {:.3}% of pixels within {tol}/255, need {:.1}%",
            100.0 * share,
            100.0 * min_share
        ))
    }
}

#[test]
fn image_agreement_helper_can_fail() {
    let a = vec![[0.5f32, 0.5, 0.5, 1.0]; 100];
    let mut b = a.clone();
    assert_eq!(srgb8_agreement(&a, &b, 0), (1.0, 0));
    // Two pixels off by far more than 2/255: 98% agree, below a 99% bar.
    b[3] = [0.6, 0.5, 0.5, 1.0];
    b[70] = [0.5, 0.5, 0.5, 0.9];
    let (share, worst) = srgb8_agreement(&a, &b, 2);
    assert_eq!(share, 0.98);
    assert!(worst > 2);
    assert!(
        agree("pair", &a, &b, 2, 0.99).is_err(),
        "a 98% agreement passed a 99% bar"
    );
    assert!(agree("pair", &a, &b, 2, 0.98).is_ok());
    // One level of difference is within tolerance 2.
    let c: Vec<[f32; 4]> = a.iter().map(|p| [p[0] * 1.004, p[1], p[2], 1.0]).collect();
    assert_eq!(srgb8_agreement(&a, &c, 2).0, 1.0);
}

// ---------------------------------------------------------------------------------------------
// Shaders: host/WGSL struct layouts of the render stages (`shader_validation` checks that
// every file validates and is registered).
// ---------------------------------------------------------------------------------------------

fn parse(name: &str, src: &str) -> naga::Module {
    let src = &coif::gpu::wgsl::compose(name, src).unwrap();
    let m =
        naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&m)
    .unwrap_or_else(|e| panic!("validation: {:?}", e.into_inner()));
    m
}

fn struct_layout(m: &naga::Module, name: &str) -> (Vec<u32>, u32) {
    let (_, ty) = m
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name}"));
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{name} is not a struct")
    };
    (members.iter().map(|m| m.offset).collect(), *span)
}

#[test]
fn shaders_validate_and_structs_match_the_host() {
    use coif::stages::{mesh_raster, strand_raster};
    use std::mem::{offset_of, size_of};
    let strand = parse("strand_raster", strand_raster::STAGE.wgsl);
    let mesh = parse("mesh_raster", mesh_raster::STAGE.wgsl);
    let seg = [
        offset_of!(SegRec, p0),
        offset_of!(SegRec, p1),
        offset_of!(SegRec, z0),
        offset_of!(SegRec, z1),
        offset_of!(SegRec, strand),
        offset_of!(SegRec, local),
        offset_of!(SegRec, c0),
        offset_of!(SegRec, c1),
        offset_of!(SegRec, o),
    ];
    let (off, span) = struct_layout(&strand, "Seg");
    assert_eq!(off, seg.map(|o| o as u32).to_vec());
    assert_eq!(span as usize, size_of::<SegRec>());
    let (off, span) = struct_layout(&mesh, "Tri");
    let tri = [
        offset_of!(TriRec, a),
        offset_of!(TriRec, b),
        offset_of!(TriRec, c),
        offset_of!(TriRec, v),
    ];
    assert_eq!(off, tri.map(|o| o as u32).to_vec());
    assert_eq!(span as usize, size_of::<TriRec>());
    // Config: encase writes field k holding the bits k+1; each WGSL member must find its own.
    let f = f32::from_bits;
    let cfg = Config {
        width: 1,
        height: 2,
        samples: 3,
        half_width: f(4),
        ndc_scale_x: f(5),
        ndc_scale_y: f(6),
        photo: 7,
        photo_half_width: f(8),
        hue_deg: f(9),
        saturation: f(10),
        value: f(11),
        _pad: 12,
    };
    let mut ub = encase::UniformBuffer::new(Vec::<u8>::new());
    ub.write(&cfg).unwrap();
    let bytes = ub.into_inner();
    for m in [&strand, &mesh] {
        let (off, span) = struct_layout(m, "Config");
        assert_eq!(span as usize, bytes.len());
        for (k, o) in off.iter().enumerate() {
            let o = *o as usize;
            assert_eq!(
                u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()),
                k as u32 + 1
            );
        }
    }
}

#[test]
fn lavapipe_format_features() {
    // Why Rgba16Float: it is multisampled and resolvable on every WebGPU device; report what
    // the adapter would offer for Rgba32Float (needs an adapter-specific feature).
    let inst = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapters = pollster::block_on(inst.enumerate_adapters(wgpu::Backends::all()));
    let a = adapters
        .iter()
        .find(|a| a.get_info().name == ctx().info.name)
        .expect("the context's adapter is listed");
    let f16 = a.get_texture_format_features(wgpu::TextureFormat::Rgba16Float);
    let f32f = a.get_texture_format_features(wgpu::TextureFormat::Rgba32Float);
    println!(
        "{}: Rgba16Float {:?}; Rgba32Float {:?}; device has TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES: {}",
        a.get_info().name,
        f16.flags,
        f32f.flags,
        ctx()
            .device
            .features()
            .contains(wgpu::Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES)
    );
    use wgpu::TextureFormatFeatureFlags as F;
    assert!(f16
        .flags
        .contains(F::MULTISAMPLE_X4 | F::MULTISAMPLE_RESOLVE));
}

// ---------------------------------------------------------------------------------------------
// Scenes
// ---------------------------------------------------------------------------------------------

fn frame(w: u32, h: u32) -> Frame {
    Frame {
        width: w,
        height: h,
        depth_range: (-100.0, 100.0),
        background: None,
    }
}

fn strands(lines: &[(&[[f32; 3]], [f32; 4])]) -> ScreenStrands {
    let mut s = ScreenStrands::default();
    for (pts, c) in lines {
        s.points.extend_from_slice(pts);
        s.colors.extend(std::iter::repeat_n(*c, pts.len()));
        s.counts.push(pts.len() as u32);
    }
    s
}

/// The paths [`both`] renders with, in its order: the GPU path (compute strand passes at 4x
/// MSAA), the CPU mirror, and the GPU with the strands by the render pipeline.
const PATHS: [&str; 3] = ["gpu", "cpu", "gpu pipeline"];

fn both(f: &Frame, m: Option<&ScreenMesh>, s: Option<&ScreenStrands>) -> [Vec<[f32; 4]>; 3] {
    both_with(f, m, s, &RasterParams::default())
}

fn both_with(
    f: &Frame,
    m: Option<&ScreenMesh>,
    s: Option<&ScreenStrands>,
    p: &RasterParams,
) -> [Vec<[f32; 4]>; 3] {
    [
        render_gpu(ctx(), f, m, s, p).expect("gpu render"),
        render_cpu(f, m, s, p).expect("cpu render"),
        render_gpu_pipeline(ctx(), f, m, s, p).expect("gpu pipeline render"),
    ]
}

/// Pixels whose four channels are the same f32s in both images.
fn float_identical(a: &[[f32; 4]], b: &[[f32; 4]]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(p, q)| {
            p.iter()
                .zip(q.iter())
                .all(|(x, y)| x.to_bits() == y.to_bits())
        })
        .count()
}

fn alpha_at(img: &[[f32; 4]], w: u32, x: u32, y: u32) -> f32 {
    img[(y * w + x) as usize][3]
}

const WHITE: [f32; 4] = [1.0, 1.0, 1.0, 1.0];

#[test]
fn horizontal_strand_coverage() {
    let (w, h) = (32, 24);
    // (y, alpha) -> expected coverage of rows 9, 10, 11 in the strand's interior columns.
    let cases: [(f32, f32, [f32; 3]); 5] = [
        (10.5, 1.0, [0.0, 1.0, 0.0]),
        (10.0, 1.0, [0.5, 0.5, 0.0]),
        (10.5, 0.5, [0.0, 0.5, 0.0]),
        // Edges through sample rows: top edge at 9.875 includes sample 3 of row 9, bottom
        // edge at 10.875 excludes sample 3 of row 10 (top-left rule).
        (10.375, 1.0, [0.25, 0.75, 0.0]),
        // Edges at 10.125 (included) and 11.125 (excluded).
        (10.625, 1.0, [0.0, 1.0, 0.0]),
    ];
    for (y, alpha, want) in cases {
        let s = strands(&[(&[[4.0, y, 0.0], [28.0, y, 0.0]], [1.0, 1.0, 1.0, alpha])]);
        for (path, img) in PATHS.iter().zip(both(&frame(w, h), None, Some(&s))) {
            for x in 5..27 {
                for (row, want) in [9, 10, 11].iter().zip(want) {
                    let a = alpha_at(&img, w, x, *row);
                    assert_eq!(a, want, "{path}: y {y} alpha {alpha}: pixel ({x}, {row})");
                }
            }
            // Ends are extended by half a width: x from 3.5 to 28.5.
            assert_eq!(alpha_at(&img, w, 2, 10), 0.0, "{path}");
            assert!(alpha_at(&img, w, 3, 10) > 0.0 && alpha_at(&img, w, 28, 10) > 0.0);
            assert_eq!(alpha_at(&img, w, 29, 10), 0.0, "{path}");
            for (k, px) in img.iter().enumerate() {
                if px[3] > 0.0 {
                    assert_eq!(&px[..3], &[1.0, 1.0, 1.0], "{path}: pixel {k} colour");
                }
            }
        }
    }
}

#[test]
fn vertical_strand_obeys_the_left_edge_rule() {
    // Edges at x = 10.125 (left, included: sample 2 at x .125) and 11.125 (right, excluded).
    let s = strands(&[(&[[10.625, 3.0, 0.0], [10.625, 20.0, 0.0]], WHITE)]);
    for img in both(&frame(24, 24), None, Some(&s)) {
        for y in 4..19 {
            assert_eq!(alpha_at(&img, 24, 9, y), 0.0);
            assert_eq!(alpha_at(&img, 24, 10, y), 1.0);
            assert_eq!(alpha_at(&img, 24, 11, y), 0.0);
        }
    }
}

#[test]
fn sample_positions_and_mask_bits_follow_the_vulkan_standard_pattern() {
    // A 0.1 px square around one sample position covers that sample only. With alpha 0.25
    // (keep 1 of 4) the kept sample is r = (x + 2y + strand) mod 4, so the pixel shows only
    // when the tiny square sits on sample r: this ties mask bit i to position i.
    let (w, h) = (16, 16);
    let (px, py) = (10u32, 10u32);
    for (k, pos) in SAMPLE_POSITIONS_4.iter().enumerate() {
        let (cx, cy) = (px as f32 + pos[0], py as f32 + pos[1]);
        let seg = [[cx - 0.05, cy, 0.0], [cx + 0.05, cy, 0.0]];
        for strand in 0..4u32 {
            for alpha in [1.0f32, 0.25] {
                // Empty strands first, so the drawn one has index `strand`.
                let mut counts = vec![0; strand as usize];
                counts.push(2);
                let s = ScreenStrands {
                    points: seg.to_vec(),
                    counts,
                    colors: vec![[1.0, 1.0, 1.0, alpha]; 2],
                    photo: None,
                };
                let p = RasterParams {
                    samples: 4,
                    strand_width: 0.1,
                };
                let imgs = both_with(&frame(w, h), None, Some(&s), &p);
                for (path, img) in PATHS.iter().zip(imgs) {
                    let kept = alpha == 1.0 || (px + 2 * py + strand) % 4 == k as u32;
                    let want = if kept { 0.25 } else { 0.0 };
                    assert_eq!(
                        alpha_at(&img, w, px, py),
                        want,
                        "{path}: sample {k} strand {strand} alpha {alpha}"
                    );
                    let total: f32 = img.iter().map(|p| p[3]).sum();
                    assert_eq!(total, want, "{path}: coverage elsewhere");
                }
            }
        }
    }
}

#[test]
fn edges_and_corners_through_sample_positions_agree_exactly() {
    // End points on the 1/8 px grid, axis-aligned and diagonal, widths 1 and 0.75: quad
    // edges and corners fall exactly on sample positions, where only the fill rule decides
    // (the CPU mirror tests a strand's quad as one polygon, the GPU as two triangles).
    let (w, h) = (40u32, 40u32);
    let mut rng = Rng::new(99);
    let mut s = ScreenStrands::default();
    for i in 0..120 {
        let g = |r: &mut Rng| (8 + r.below(24 * 8)) as f32 / 8.0;
        let (x, y) = (g(&mut rng), g(&mut rng));
        let l = (1 + rng.below(40)) as f32 / 8.0;
        let (dx, dy) = match i % 4 {
            0 => (l, 0.0),
            1 => (0.0, l),
            2 => (l, l),
            _ => (l, -l),
        };
        s.points.push([x, y, i as f32 * 0.1]);
        s.points.push([x + dx, y + dy, i as f32 * 0.1]);
        let c = [rng.next_f32(), rng.next_f32(), rng.next_f32(), 1.0];
        s.colors.extend([c, c]);
        s.counts.push(2);
    }
    for width in [1.0f32, 0.75] {
        let p = RasterParams {
            samples: 4,
            strand_width: width,
        };
        let [gpu, cpu, pipe] = both_with(&frame(w, h), None, Some(&s), &p);
        agree("sample-aligned, gpu pipeline", &pipe, &cpu, 0, 1.0).unwrap();
        let same = float_identical(&gpu, &cpu);
        println!(
            "width {width}: {same} of {} pixels float-identical",
            gpu.len()
        );
        agree("sample-aligned", &gpu, &cpu, 0, 1.0).unwrap();
    }
}

/// A flat square at depth `depth`, textured with one colour, covering [x0, x1] x [y0, y1].
fn square_mesh(x0: f32, y0: f32, x1: f32, y1: f32, depth: f32, c: [f32; 4]) -> ScreenMesh {
    ScreenMesh {
        // Counter-clockwise as viewed (y down): (x0,y0) -> (x0,y1) -> (x1,y1).
        positions: vec![
            [x0, y0, depth],
            [x0, y1, depth],
            [x1, y1, depth],
            [x1, y0, depth],
        ],
        uvs: vec![[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        texture: Texture {
            width: 1,
            height: 1,
            texels: vec![c],
        },
    }
}

#[test]
fn depth_test_hides_strands_behind_the_mesh() {
    let (w, h) = (32, 32);
    let red = [1.0, 0.0, 0.0, 1.0];
    let mesh = square_mesh(8.0, 8.0, 24.0, 24.0, 0.0, red);
    let mut f = frame(w, h);
    f.background = Some(vec![[0.0, 0.0, 1.0, 1.0]; (w * h) as usize]);
    for (depth, visible) in [(-10.0f32, false), (10.0, true)] {
        let s = strands(&[(
            &[[2.0, 16.5, depth], [30.0, 16.5, depth]],
            [0.0, 1.0, 0.0, 1.0],
        )]);
        for (path, img) in PATHS.iter().zip(both(&f, Some(&mesh), Some(&s))) {
            let at = |x: u32, y: u32| img[(y * w + x) as usize];
            // Over the square: green in front, red behind; outside it the strand shows on blue.
            let want_mid = if visible { [0.0, 1.0, 0.0, 1.0] } else { red };
            assert_eq!(at(16, 16), want_mid, "{path}: depth {depth}");
            assert_eq!(at(4, 16), [0.0, 1.0, 0.0, 1.0], "{path}");
            assert_eq!(at(16, 12), red, "{path}");
            assert_eq!(at(2, 2), [0.0, 0.0, 1.0, 1.0], "{path}");
        }
    }
    // Strands write depth: a near strand drawn first still wins over a later, farther one.
    let s = strands(&[
        (&[[2.0, 4.5, 20.0], [30.0, 4.5, 20.0]], [0.0, 1.0, 0.0, 1.0]),
        (&[[16.5, 1.0, 5.0], [16.5, 30.0, 5.0]], [1.0, 1.0, 0.0, 1.0]),
    ]);
    for img in both(&f, Some(&mesh), Some(&s)) {
        assert_eq!(img[(4 * w + 16) as usize], [0.0, 1.0, 0.0, 1.0]);
        assert_eq!(img[(16 * w + 16) as usize], [1.0, 1.0, 0.0, 1.0]);
    }
}

/// Exact depth ties between strands go to the one drawn first, on both paths (the CPU path
/// draws each tile front to back and breaks ties by draw rank, see `TileBuf::rank`), and a
/// nearer strand drawn last still wins.
#[test]
fn depth_ties_between_strands_go_to_the_earlier_strand() {
    let (w, h) = (32, 32);
    let (red, green, blue) = (
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0, 1.0],
    );
    let s = strands(&[
        (&[[2.0, 10.5, 5.0], [30.0, 10.5, 5.0]], red),
        (&[[10.5, 2.0, 5.0], [10.5, 30.0, 5.0]], green),
        (&[[2.0, 20.5, 5.0], [30.0, 20.5, 5.0]], blue),
        (&[[20.5, 2.0, 9.0], [20.5, 30.0, 9.0]], [1.0, 1.0, 1.0, 1.0]),
    ]);
    for (path, img) in PATHS.iter().zip(both(&frame(w, h), None, Some(&s))) {
        let at = |x: u32, y: u32| img[(y * w + x) as usize];
        assert_eq!(at(10, 10), red, "{path}: red drawn before green");
        assert_eq!(at(10, 20), green, "{path}: green drawn before blue");
        assert_eq!(at(20, 10), [1.0; 4], "{path}: the nearer white strand");
        assert_eq!(at(20, 20), [1.0; 4], "{path}");
    }
}

#[test]
fn back_faces_are_culled() {
    let (w, h) = (16, 16);
    let mut front = square_mesh(2.0, 2.0, 14.0, 14.0, 0.0, WHITE);
    for (path, img) in PATHS.iter().zip(both(&frame(w, h), Some(&front), None)) {
        assert_eq!(alpha_at(&img, w, 8, 8), 1.0, "{path}: front face drawn");
    }
    for t in &mut front.triangles {
        t.swap(1, 2);
    }
    for (path, img) in PATHS.iter().zip(both(&frame(w, h), Some(&front), None)) {
        assert!(img.iter().all(|p| p[3] == 0.0), "{path}: back face culled");
    }
}

#[test]
fn texture_is_bilinear_with_texel_centres_at_half_integers() {
    // A 2x1 texture black|white stretched over 16 px: uv u = (x + 0.5) / 16 at pixel x, so the
    // texel coordinate is 2u - 0.5 and the value ramps from 0 at u = 1/4 to 1 at u = 3/4.
    let (w, h) = (16, 4);
    let mut mesh = square_mesh(0.0, 0.0, 16.0, 4.0, 0.0, WHITE);
    mesh.texture = Texture {
        width: 2,
        height: 1,
        texels: vec![[0.0, 0.0, 0.0, 1.0], [1.0, 1.0, 1.0, 1.0]],
    };
    for (path, img) in PATHS.iter().zip(both(&frame(w, h), Some(&mesh), None)) {
        for x in 0..w {
            let u = (x as f32 + 0.5) / 16.0;
            let want = (2.0 * u - 0.5).clamp(0.0, 1.0);
            let got = img[(w + x) as usize][0];
            assert!((got - want).abs() < 2e-3, "{path}: x {x}: {got} vs {want}");
        }
    }
}

/// A mesh texel's alpha is coverage: floor(alpha·N + 0.5) of a pixel's N samples, on both
/// paths, with depth written only where covered (a strand behind shows in the rest).
#[test]
fn texture_alpha_is_coverage_of_the_samples() {
    let (w, h) = (8, 8);
    for samples in [4u32, 1] {
        let p = RasterParams {
            samples,
            ..Default::default()
        };
        for (a, k) in [
            (0.0f32, 0u32),
            (0.1, 0),
            (0.3, 1),
            (0.5, 2),
            (0.7, 3),
            (0.9, 4),
            (1.0, 4),
        ] {
            let k = if samples == 1 { (a >= 0.5) as u32 } else { k };
            let mesh = square_mesh(0.0, 0.0, 8.0, 8.0, 0.0, [1.0, 0.0, 0.0, a]);
            // A green strand behind the whole square, filling every sample the mesh leaves.
            let behind: Vec<[f32; 3]> = (0..8).map(|y| [-1.0, y as f32 + 0.5, -20.0]).collect();
            let s = {
                let mut s = ScreenStrands::default();
                for q in &behind {
                    s.points.extend_from_slice(&[*q, [9.0, q[1], -20.0]]);
                    s.colors.extend([[0.0, 1.0, 0.0, 1.0]; 2]);
                    s.counts.push(2);
                }
                s
            };
            let f = frame(w, h);
            for (path, img) in PATHS.iter().zip(both_with(&f, Some(&mesh), Some(&s), &p)) {
                let want = k as f32 / samples as f32;
                for (i, px) in img.iter().enumerate() {
                    assert!(
                        (px[0] - want).abs() < 2e-3 && (px[1] - (1.0 - want)).abs() < 2e-3,
                        "{path}, {samples} samples, alpha {a}: pixel {i} is {px:?}, want red {want}"
                    );
                }
            }
        }
    }
}

/// Parity with a texture whose alpha cuts the head along a soft edge.
#[test]
fn gpu_matches_cpu_with_texture_alpha() {
    for (w, h, seed, samples) in [(128u32, 112u32, 5u64, 4u32), (96, 80, 9, 1)] {
        let mut rng = Rng::new(seed);
        let mut mesh = head_mesh(w, h, &mut rng);
        let tw = mesh.texture.width;
        for (i, t) in mesh.texture.texels.iter_mut().enumerate() {
            // A ramp across the texture with noise: cut, soft and kept columns.
            let x = (i as u32 % tw) as f32 / (tw - 1) as f32;
            t[3] = (1.6 * x - 0.3 + 0.2 * rng.next_f32()).clamp(0.0, 1.0);
        }
        let s = random_strands(w, h, 150, &mut rng);
        let p = RasterParams {
            samples,
            strand_width: 1.0,
        };
        let f = Frame {
            width: w,
            height: h,
            depth_range: (-200.0, 200.0),
            background: Some(gradient_background(w, h)),
        };
        let cpu = render_cpu(&f, Some(&mesh), Some(&s), &p).unwrap();
        let gpu = render_gpu(ctx(), &f, Some(&mesh), Some(&s), &p).unwrap();
        // The cut must show: some of the head's pixels are partly covered.
        let opaque = render_cpu(
            &f,
            Some(&head_mesh(w, h, &mut Rng::new(seed))),
            Some(&s),
            &p,
        )
        .unwrap();
        let changed = cpu
            .iter()
            .zip(&opaque)
            .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| (x - y).abs() > 0.05))
            .count();
        println!("{w}x{h}, {samples} samples: the alpha changes {changed} px");
        assert!(
            changed > (w * h) as usize / 20,
            "alpha cut only {changed} px"
        );
        agree("texture alpha", &gpu, &cpu, 2, 0.99).unwrap();
    }
}

// ---------------------------------------------------------------------------------------------
// Parity on a head + random strands
// ---------------------------------------------------------------------------------------------

fn head_mesh(w: u32, h: u32, rng: &mut Rng) -> ScreenMesh {
    let head = Head::new(&Default::default());
    let (pos, tris) = head.mesh(24);
    let (lo, hi) = head.bounds();
    let ext = (hi - lo).max_element();
    let s = 0.9 * w.min(h) as f32 / ext;
    let centre = (lo + hi) * 0.5;
    let t = Vec2::new(w as f32 * 0.5 - s * centre.x, h as f32 * 0.5 + s * centre.y);
    let cam = WeakPerspective::frontal(s, t);
    let positions: Vec<[f32; 3]> = pos.iter().map(|p| cam.project(*p).to_array()).collect();
    // Planar uv from the image position: smooth but not trivial across the face.
    let uvs = positions
        .iter()
        .map(|p| [p[0] / w as f32, p[1] / h as f32])
        .collect();
    let (tw, th) = (12u32, 12u32);
    let texels = (0..tw * th)
        .map(|_| [rng.next_f32(), rng.next_f32(), rng.next_f32(), 1.0])
        .collect();
    ScreenMesh {
        positions,
        uvs,
        triangles: tris,
        texture: Texture {
            width: tw,
            height: th,
            texels,
        },
    }
}

fn random_strands(w: u32, h: u32, n: usize, rng: &mut Rng) -> ScreenStrands {
    let mut s = ScreenStrands::default();
    for _ in 0..n {
        let len = 6 + rng.below(14) as usize;
        let mut p = Vec3::new(
            rng.range_f32(0.0, w as f32),
            rng.range_f32(0.0, h as f32),
            rng.range_f32(-60.0, 90.0),
        );
        let mut dir = rng.range_f32(0.0, std::f32::consts::TAU);
        let base = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
        let alpha = rng.range_f32(0.05, 1.0);
        for k in 0..len {
            s.points.push(p.to_array());
            let f = k as f32 / len as f32;
            s.colors.push([
                base[0] * (1.0 - 0.5 * f),
                base[1],
                (base[2] + 0.3 * f).min(1.0),
                (alpha * (1.0 - 0.6 * f) + 0.2 * rng.next_f32()).min(1.0),
            ]);
            dir += rng.range_f32(-0.5, 0.5);
            let step = rng.range_f32(1.5, 5.0);
            p += Vec3::new(dir.cos() * step, dir.sin() * step, rng.range_f32(-3.0, 3.0));
        }
        s.counts.push(len as u32);
    }
    s
}

fn gradient_background(w: u32, h: u32) -> Vec<[f32; 4]> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
            [0.2 + 0.6 * x, 0.3 * y, 0.5 - 0.4 * x * y, 1.0]
        })
        .collect()
}

#[test]
fn gpu_matches_cpu_on_head_and_strands() {
    for (w, h, seed, samples) in [
        (128u32, 112u32, 7u64, 4u32),
        (96, 96, 11, 4),
        (160, 120, 3, 1),
    ] {
        let mut rng = Rng::new(seed);
        let mesh = head_mesh(w, h, &mut rng);
        let s = random_strands(w, h, 300, &mut rng);
        let p = RasterParams {
            samples,
            strand_width: 1.0,
        };
        let mut f = Frame {
            width: w,
            height: h,
            depth_range: (-200.0, 200.0),
            background: None,
        };
        // Coverage of mesh + strands alone, so agreement is not won on bare background.
        let alone = render_cpu(&f, Some(&mesh), Some(&s), &p).unwrap();
        let covered = alone.iter().filter(|p| p[3] > 0.0).count() as f64 / alone.len() as f64;
        let strand_px = render_cpu(&f, None, Some(&s), &p)
            .unwrap()
            .iter()
            .filter(|p| p[3] > 0.0)
            .count() as f64
            / alone.len() as f64;
        println!(
            "{w}x{h}, {samples} samples: mesh+strands cover {:.1}% of pixels, strands alone {:.1}%",
            100.0 * covered,
            100.0 * strand_px
        );
        assert!(covered >= 0.30, "scene covers only {:.1}%", 100.0 * covered);
        assert!(
            strand_px >= 0.15,
            "strands cover only {:.1}%",
            100.0 * strand_px
        );
        let gpu_alone = render_gpu(ctx(), &f, Some(&mesh), Some(&s), &p).unwrap();
        agree("no background", &gpu_alone, &alone, 2, 0.99).unwrap();
        f.background = Some(gradient_background(w, h));
        let cpu = render_cpu(&f, Some(&mesh), Some(&s), &p).unwrap();
        let gpu = render_gpu(ctx(), &f, Some(&mesh), Some(&s), &p).unwrap();
        agree("over background", &gpu, &cpu, 2, 0.99).unwrap();
        let pipe = render_gpu_pipeline(ctx(), &f, Some(&mesh), Some(&s), &p).unwrap();
        agree("over background, gpu pipeline", &pipe, &cpu, 2, 0.99).unwrap();
        for (what, img) in [("gpu", &gpu), ("gpu pipeline", &pipe)] {
            let exact = float_identical(img, &cpu);
            println!(
                "  {what}: float-identical pixels {:.3}%",
                100.0 * exact as f64 / cpu.len() as f64
            );
        }
        if std::env::var_os("RASTER_DUMP").is_some() {
            let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
            for (name, img) in [("gpu", &gpu), ("cpu", &cpu)] {
                let path = dir.join(format!("raster_{w}x{h}_{name}.png"));
                image::RgbaImage::from_raw(w, h, to_rgba8(img))
                    .unwrap()
                    .save(&path)
                    .unwrap();
                println!("  wrote {}", path.display());
            }
        }
    }
}

/// A photo with detail at the pixel scale (the case where sampling only at vertices fails).
fn noisy_photo(w: u32, h: u32, rng: &mut Rng) -> Texture {
    Texture {
        width: w,
        height: h,
        texels: (0..w * h)
            .map(|_| [rng.next_f32(), rng.next_f32(), rng.next_f32(), 1.0])
            .collect(),
    }
}

/// Photo colour for `s`: the photo's camera sees screen point p at `map(p)`.
fn with_photo(
    mut s: ScreenStrands,
    tex: Texture,
    map: impl Fn([f32; 3]) -> [f32; 2],
    hsv: Option<[f32; 3]>,
) -> ScreenStrands {
    s.photo = Some(StrandPhoto {
        points: s.points.iter().map(|&p| map(p)).collect(),
        texture: tex,
        half_width: 0.5,
        hsv,
    });
    s
}

#[test]
fn photo_colour_reproduces_the_photo_at_its_own_view() {
    // Opaque strands with a zero offset, photo points = screen points: wherever the strands
    // cover all samples of a pixel, the pixel is the photo's texel, on both paths.
    let (w, h) = (96u32, 80u32);
    let mut rng = Rng::new(5);
    let tex = noisy_photo(w, h, &mut rng);
    let mut s = random_strands(w, h, 400, &mut rng);
    for c in &mut s.colors {
        *c = [0.0, 0.0, 0.0, 1.0];
    }
    let s = with_photo(s, tex.clone(), |p| [p[0], p[1]], None);
    let f = Frame {
        width: w,
        height: h,
        depth_range: (-200.0, 200.0),
        background: None,
    };
    for (path, img) in PATHS.iter().zip(both(&f, None, Some(&s))) {
        let (mut full, mut worst) = (0usize, 0.0f32);
        for (px, t) in img.iter().zip(&tex.texels) {
            if px[3] >= 1.0 {
                full += 1;
                for k in 0..3 {
                    worst = worst.max((px[k] - t[k]).abs());
                }
            }
        }
        println!(
            "{path}: {full} fully covered pixels, largest difference from the photo {worst:.2e}"
        );
        assert!(
            full > (w * h / 4) as usize,
            "{path}: only {full} covered pixels"
        );
        // f16 target (11 bits) and interpolation rounding of the photo point.
        assert!(
            worst <= 2e-3,
            "{path}: covered pixel differs from the photo by {worst}"
        );
    }
}

#[test]
fn gpu_matches_cpu_with_photo_colour() {
    let (w, h) = (112u32, 96u32);
    let mut rng = Rng::new(23);
    let tex = noisy_photo(w, h, &mut rng);
    let base = random_strands(w, h, 300, &mut rng);
    let mut offsets = base.clone();
    for c in &mut offsets.colors {
        // Offsets as shading leaves them: small, either sign.
        *c = [0.3 * c[0] - 0.15, 0.2 * c[1] - 0.1, 0.1 * c[2], c[3]];
    }
    // The photo's view, and a turned, scaled one (a novel view).
    let (cs, sn) = (0.3f32.cos(), 0.3f32.sin());
    let turned = move |p: [f32; 3]| {
        [
            0.9 * (cs * p[0] - sn * p[1]) + 20.0,
            0.9 * (sn * p[0] + cs * p[1]),
        ]
    };
    let cases: [(&str, ScreenStrands); 3] = [
        (
            "own view",
            with_photo(offsets.clone(), tex.clone(), |p| [p[0], p[1]], None),
        ),
        (
            "novel view",
            with_photo(offsets.clone(), tex.clone(), turned, None),
        ),
        (
            "own view, HSV",
            with_photo(offsets, tex, |p| [p[0], p[1]], Some([130.0, 0.7, 1.2])),
        ),
    ];
    for (what, s) in cases {
        let f = Frame {
            width: w,
            height: h,
            depth_range: (-200.0, 200.0),
            background: Some(gradient_background(w, h)),
        };
        let [gpu, cpu, pipe] = both(&f, None, Some(&s));
        agree(what, &gpu, &cpu, 2, 0.99).unwrap();
        agree(&format!("{what}, gpu pipeline"), &pipe, &cpu, 2, 0.99).unwrap();
        // The photo shows: the render differs from the vertex-colour render.
        let mut plain = s.clone();
        plain.photo = None;
        let v = render_cpu(&f, None, Some(&plain), &RasterParams::default()).unwrap();
        assert!(
            agree(what, &cpu, &v, 2, 0.99).is_err(),
            "{what}: photo colour had no effect"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Bad input, determinism, splitting, limits
// ---------------------------------------------------------------------------------------------

#[test]
fn bad_segments_are_skipped_identically() {
    let (w, h) = (48, 40);
    let nan = f32::NAN;
    let good: &[[f32; 3]] = &[[4.0, 4.0, 0.0], [20.0, 30.0, 5.0], [40.0, 10.0, 0.0]];
    let mut s = strands(&[
        (good, [0.8, 0.4, 0.1, 1.0]),
        // Zero-length segments inside a strand, and a repeated end point.
        (
            &[
                [10.0, 20.0, 0.0],
                [10.0, 20.0, 0.0],
                [30.0, 20.0, 0.0],
                [30.0, 20.0, 0.0],
            ],
            [0.2, 0.9, 0.3, 0.7],
        ),
        // NaN and infinite points.
        (
            &[
                [nan, 5.0, 0.0],
                [20.0, 5.0, 0.0],
                [30.0, f32::INFINITY, 0.0],
            ],
            WHITE,
        ),
        // Entirely off-screen, and off-screen both ends but crossing the frame.
        (&[[-50.0, -50.0, 0.0], [-20.0, -60.0, 0.0]], WHITE),
        (
            &[[-1e30, 35.5, 0.0], [1e30, 35.5, 0.0]],
            [0.1, 0.1, 0.9, 1.0],
        ),
        // Beyond the depth range (clipped away), and a single-point strand.
        (&[[5.0, 38.0, 500.0], [40.0, 38.0, 500.0]], WHITE),
        (&[[12.0, 12.0, 0.0]], WHITE),
    ]);
    // A NaN colour on the middle vertex of a fresh strand: both its segments go.
    s.points
        .extend_from_slice(&[[5.0, 25.0, 0.0], [25.0, 26.0, 0.0], [45.0, 27.0, 0.0]]);
    s.colors
        .extend_from_slice(&[WHITE, [nan, 0.0, 0.0, 1.0], WHITE]);
    s.counts.push(3);
    let mut mesh = square_mesh(30.0, 28.0, 44.0, 38.0, -20.0, [0.3, 0.3, 0.3, 1.0]);
    mesh.positions.push([nan, 0.0, 0.0]);
    mesh.uvs.push([0.0, 0.0]);
    mesh.triangles.push([0, 4, 1]);
    let [gpu, cpu, pipe] = both(&frame(w, h), Some(&mesh), Some(&s));
    agree("bad input", &gpu, &cpu, 0, 1.0).unwrap();
    agree("bad input, gpu pipeline", &pipe, &cpu, 0, 1.0).unwrap();
    // Only the good geometry shows: the NaN strand and the off-screen one add nothing.
    let row = |img: &[[f32; 4]], y: u32, x0: u32| {
        (x0..w).filter(|&x| alpha_at(img, w, x, y) > 0.0).count()
    };
    // (The good strand crosses row 5 near x = 4.)
    assert_eq!(row(&cpu, 5, 10), 0, "the NaN strand's segments are skipped");
    assert_eq!(
        row(&cpu, 35, 0),
        w as usize,
        "the huge segment is clipped, not lost"
    );
    assert_eq!(
        row(&cpu, 38, 0),
        0,
        "geometry beyond the depth range is clipped"
    );
    assert_eq!(
        row(&cpu, 25, 30),
        0,
        "a NaN colour drops the segments that use it"
    );
    let only_off = strands(&[(&[[-50.0, -50.0, 0.0], [-20.0, -60.0, 0.0]], WHITE)]);
    for img in both(&frame(w, h), None, Some(&only_off)) {
        assert!(img.iter().all(|p| *p == [0.0; 4]));
    }
}

#[test]
fn huge_mesh_triangles_are_clipped_not_lost() {
    // A quad reaching a million px off-screen on three sides: clipped on the host to the
    // guard band, identical on both paths, covering exactly x < 20.
    let (w, h) = (40, 24);
    let mut mesh = square_mesh(-1e6, -1e6, 20.0, 1e6, -50.0, WHITE);
    mesh.texture = Texture {
        width: 2,
        height: 2,
        texels: vec![
            [0.0, 0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 1.0],
            WHITE,
        ],
    };
    let [gpu, cpu, pipe] = both(&frame(w, h), Some(&mesh), None);
    agree("clipped mesh", &gpu, &cpu, 0, 1.0).unwrap();
    agree("clipped mesh, gpu pipeline", &pipe, &cpu, 0, 1.0).unwrap();
    for y in 0..h {
        for x in 0..w {
            assert_eq!(
                alpha_at(&cpu, w, x, y),
                if x < 20 { 1.0 } else { 0.0 },
                "({x}, {y})"
            );
        }
    }
}

/// The compute strand passes (`wgsl/render/strand_vis64.wgsl` where the device has 64-bit
/// atomics, as lavapipe does, else `strand_vis.wgsl`) draw 4x frames and agree with the CPU
/// mirror on a frame whose size is no multiple of their 8x8 pixel groups, with more segments
/// than a walk's 64-invocation workgroup and in several chunks (each walked in its own
/// order); the one-walk and two-walk passes give the same image to the bit; 1-sample frames
/// and frames too large for their i32 edge values keep the render pipeline.
#[test]
fn strand_vis_draws_4x_frames_and_matches_the_cpu_across_workgroups() {
    let (w, h) = (70, 45);
    let mut rng = Rng::new(9);
    let mesh = head_mesh(w, h, &mut rng);
    let s = random_strands(w, h, 150, &mut rng);
    let mut f = frame(w, h);
    f.depth_range = (-200.0, 200.0);
    f.background = Some(gradient_background(w, h));
    let p = RasterParams::default();
    assert_eq!(p.samples, 4);
    let compute = if ctx().has_int64_atomics() {
        "strand_vis64"
    } else {
        "strand_vis"
    };
    assert_eq!(gpu_strand_path(ctx(), &f, Some(&s), &p).unwrap(), compute);
    let one = RasterParams { samples: 1, ..p };
    assert_eq!(
        gpu_strand_path(ctx(), &f, Some(&s), &one).unwrap(),
        "strand_raster"
    );
    assert_eq!(
        gpu_strand_path(ctx(), &f, None, &p).unwrap(),
        "strand_raster"
    );
    let huge = frame(6000, 6000);
    assert_eq!(
        gpu_strand_path(ctx(), &huge, Some(&s), &p).unwrap(),
        "strand_raster"
    );
    let cpu = render_cpu(&f, Some(&mesh), Some(&s), &p).unwrap();
    let gpu = render_gpu(ctx(), &f, Some(&mesh), Some(&s), &p).unwrap();
    agree(compute, &gpu, &cpu, 2, 0.99).unwrap();
    // 37 segments a chunk (80 B each): many chunks, the same image to the bit.
    let chunked = render_gpu_chunked(ctx(), &f, Some(&mesh), Some(&s), &p, 80 * 37).unwrap();
    assert_eq!(
        float_identical(&gpu, &chunked),
        gpu.len(),
        "chunks changed the image"
    );
    // The two-walk passes (in chunks too): the same image to the bit.
    let two = render_gpu_with(
        ctx(),
        &f,
        Some(&mesh),
        Some(&s),
        &p,
        80 * 37,
        GpuStrands::TwoWalks,
    )
    .unwrap();
    assert_eq!(
        float_identical(&gpu, &two),
        gpu.len(),
        "{compute} and the two-walk passes differ"
    );
    println!(
        "strand_vis: {} of {} pixels float-identical to the cpu mirror",
        float_identical(&gpu, &cpu),
        cpu.len()
    );
}

/// The GPU path keeps its large buffers and targets for the next render of the same size
/// (`coif::gpu::pool`): a render after another scene left other keys, holders, colours and
/// segments in them gives the image it gives on fresh ones, to the bit, on every strand path
/// (one walk, two walks, chunks). A fresh context, so the pool is this test's alone.
#[test]
fn reused_buffers_carry_nothing_from_one_render_to_the_next() {
    let own = GpuContext::new().expect("a wgpu adapter (lavapipe) is needed");
    let (w, h) = (70, 45);
    let mut rng = Rng::new(21);
    let mesh = head_mesh(w, h, &mut rng);
    let a = random_strands(w, h, 150, &mut rng);
    // Another scene of the same size, without the mesh or the background.
    let b = random_strands(w, h, 150, &mut rng);
    let mut f = frame(w, h);
    f.depth_range = (-200.0, 200.0);
    f.background = Some(gradient_background(w, h));
    let bare = frame(w, h);
    let p = RasterParams::default();
    let bits = |v: &[[f32; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    let paths = [
        (u64::MAX, GpuStrands::Best),
        (80 * 37, GpuStrands::Best),
        (u64::MAX, GpuStrands::TwoWalks),
        (80 * 37, GpuStrands::TwoWalks),
    ];
    for (chunk, path) in paths {
        let fresh = GpuContext::new().expect("a wgpu adapter");
        let first = render_gpu_with(&fresh, &f, Some(&mesh), Some(&a), &p, chunk, path).unwrap();
        assert!(fresh.pooled_bytes() > 0, "nothing kept after a render");
        render_gpu_with(&own, &f, Some(&mesh), Some(&a), &p, chunk, path).unwrap();
        let kept = own.pooled_bytes();
        render_gpu_with(&own, &bare, None, Some(&b), &p, chunk, path).unwrap();
        let again = render_gpu_with(&own, &f, Some(&mesh), Some(&a), &p, chunk, path).unwrap();
        let differ = bits(&again)
            .iter()
            .zip(bits(&first))
            .filter(|(x, y)| **x != *y)
            .count();
        assert_eq!(
            differ, 0,
            "{path:?}, {chunk} B chunks: a render on kept buffers differs from a fresh one"
        );
        assert!(
            own.pooled_bytes() >= kept,
            "{path:?}: the kept buffers were not given back"
        );
    }
}

#[test]
fn gpu_renders_are_deterministic_and_chunking_is_invisible() {
    let (w, h) = (96, 80);
    let mut rng = Rng::new(5);
    let mesh = head_mesh(w, h, &mut rng);
    let s = random_strands(w, h, 200, &mut rng);
    let mut f = frame(w, h);
    f.depth_range = (-200.0, 200.0);
    let p = RasterParams::default();
    let a = render_gpu(ctx(), &f, Some(&mesh), Some(&s), &p).unwrap();
    let b = render_gpu(ctx(), &f, Some(&mesh), Some(&s), &p).unwrap();
    let bits = |v: &[[f32; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b), "two GPU renders differ");
    // 100 segments / 40 triangles per draw: many draws, same image.
    let c = render_gpu_chunked(ctx(), &f, Some(&mesh), Some(&s), &p, 64 * 100).unwrap();
    assert_eq!(bits(&a), bits(&c), "splitting into draws changed the image");
    let d = render_cpu(&f, Some(&mesh), Some(&s), &p).unwrap();
    let e = render_cpu(&f, Some(&mesh), Some(&s), &p).unwrap();
    assert_eq!(bits(&d), bits(&e), "two CPU renders differ");
}

#[test]
fn invalid_input_is_an_error_not_a_panic() {
    let s = strands(&[(&[[1.0, 1.0, 0.0], [5.0, 5.0, 0.0]], WHITE)]);
    let p = RasterParams::default();
    let limit = ctx().limits.max_texture_dimension_2d;
    let expect_invalid = |f: &Frame,
                          m: Option<&ScreenMesh>,
                          s: Option<&ScreenStrands>,
                          p: &RasterParams,
                          what: &str| {
        for r in [render_cpu(f, m, s, p), render_gpu(ctx(), f, m, s, p)] {
            match r {
                Err(coif::Error::Invalid(msg)) => println!("{what}: {msg}"),
                other => panic!(
                    "{what}: expected Error::Invalid, got {:?}",
                    other.map(|v| v.len())
                ),
            }
        }
    };
    expect_invalid(&frame(0, 10), None, Some(&s), &p, "zero width");
    expect_invalid(
        &frame(limit.max(CPU_MAX_DIM) + 1, 4),
        None,
        Some(&s),
        &p,
        "too wide",
    );
    let mut f = frame(8, 8);
    f.background = Some(vec![WHITE; 63]);
    expect_invalid(&f, None, None, &p, "short background");
    let mut f = frame(8, 8);
    f.depth_range = (10.0, -10.0);
    expect_invalid(&f, None, Some(&s), &p, "reversed depth range");
    for bad in [
        RasterParams { samples: 3, ..p },
        RasterParams {
            strand_width: 0.0,
            ..p
        },
        RasterParams {
            strand_width: f32::NAN,
            ..p
        },
    ] {
        expect_invalid(&frame(8, 8), None, Some(&s), &bad, "bad params");
    }
    let mut short = s.clone();
    short.colors.pop();
    expect_invalid(&frame(8, 8), None, Some(&short), &p, "colour count");
    let mut counts = s.clone();
    counts.counts = vec![3];
    expect_invalid(&frame(8, 8), None, Some(&counts), &p, "counts");
    let mut m = square_mesh(1.0, 1.0, 6.0, 6.0, 0.0, WHITE);
    m.triangles.push([0, 1, 9]);
    expect_invalid(&frame(8, 8), Some(&m), None, &p, "triangle index");
    let mut m = square_mesh(1.0, 1.0, 6.0, 6.0, 0.0, WHITE);
    m.texture.width = 0;
    expect_invalid(&frame(8, 8), Some(&m), None, &p, "empty texture");
    let tex = Texture {
        width: 2,
        height: 2,
        texels: vec![WHITE; 4],
    };
    let mut ph = with_photo(s.clone(), tex.clone(), |q| [q[0], q[1]], None);
    ph.photo.as_mut().unwrap().points.pop();
    expect_invalid(&frame(8, 8), None, Some(&ph), &p, "photo point count");
    let mut ph = with_photo(s.clone(), tex.clone(), |q| [q[0], q[1]], None);
    ph.photo.as_mut().unwrap().texture.texels.pop();
    expect_invalid(&frame(8, 8), None, Some(&ph), &p, "photo texel count");
    let ph = with_photo(s.clone(), tex, |q| [q[0], q[1]], Some([f32::NAN, 1.0, 1.0]));
    expect_invalid(&frame(8, 8), None, Some(&ph), &p, "photo HSV");
    // Empty but valid input renders the background.
    let mut f = frame(4, 4);
    f.background = Some(vec![[0.5, 0.25, 0.125, 1.0]; 16]);
    for img in both(&f, None, Some(&ScreenStrands::default())) {
        assert!(img.iter().all(|p| *p == [0.5, 0.25, 0.125, 1.0]));
    }
}

#[test]
fn render_picks_the_engine_backend() {
    let s = strands(&[(&[[1.0, 2.5, 0.0], [7.0, 2.5, 0.0]], WHITE)]);
    let a = render(
        &coif::Engine::cpu(),
        &frame(8, 8),
        None,
        Some(&s),
        &RasterParams::default(),
    )
    .unwrap();
    assert_eq!(
        a,
        render_cpu(&frame(8, 8), None, Some(&s), &RasterParams::default()).unwrap()
    );
    assert_eq!(alpha_at(&a, 8, 4, 2), 1.0);
}
