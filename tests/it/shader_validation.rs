//! Every WGSL file under `wgsl/` (subfolders included) parses and validates with naga after
//! its `#include`s are expanded, every shader is used by exactly one registered stage
//! (compute or render), every shared piece is included somewhere, and every uniform struct
//! has the same size and member offsets on both sides. No GPU needed.

use coif::gpu::wgsl::{compose, include_path, SHARED};
use coif::stages;
use std::path::{Path, PathBuf};

fn wgsl_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("wgsl")
}

/// Every `.wgsl` file under `wgsl/`, subfolders included, as paths relative to `wgsl/`
/// with `/` separators.
fn wgsl_files() -> Vec<String> {
    fn walk(dir: &Path, root: &Path, out: &mut Vec<String>) {
        for e in std::fs::read_dir(dir).expect("wgsl/ is readable") {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, root, out);
            } else if p.extension().is_some_and(|e| e == "wgsl") {
                let rel = p.strip_prefix(root).unwrap();
                let parts: Vec<_> = rel.iter().map(|c| c.to_string_lossy()).collect();
                out.push(parts.join("/"));
            }
        }
    }
    let root = wgsl_root();
    let mut v = Vec::new();
    walk(&root, &root, &mut v);
    v.sort();
    v
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(wgsl_root().join(rel)).unwrap()
}

/// Shared pieces are include-only: they may use bindings the including shader declares.
fn is_shared(rel: &str) -> bool {
    rel.starts_with("shared/")
}

/// `(file under wgsl/, name, source)` of every registry entry, compute and render.
fn registered() -> Vec<(String, &'static str, &'static str)> {
    let compute = stages::ALL
        .iter()
        .map(|s| (format!("{}.wgsl", s.name), s.name, s.wgsl));
    let render = stages::RENDER
        .iter()
        .map(|s| (format!("render/{}.wgsl", s.name), s.name, s.wgsl));
    compute.chain(render).collect()
}

/// What a shader may use beyond the defaults: 64-bit atomic min/max for the render stages
/// that declare them (the host runs those only on devices that have them).
fn capabilities(name: &str) -> naga::valid::Capabilities {
    use naga::valid::Capabilities as C;
    let wide = stages::RENDER.iter().any(|s| {
        s.int64_atomics && (name == s.name || name == format!("wgsl/render/{}.wgsl", s.name))
    });
    if wide {
        C::default() | C::SHADER_INT64 | C::SHADER_INT64_ATOMIC_MIN_MAX
    } else {
        C::default()
    }
}

/// Composes (expands the includes), parses and validates.
fn parse(name: &str, src: &str) -> Result<naga::Module, String> {
    let src = compose(name, src).map_err(|e| e.to_string())?;
    let module = naga::front::wgsl::parse_str(&src)
        .map_err(|e| format!("{name}: parse error:\n{}", e.emit_to_string(&src)))?;
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), capabilities(name))
        .validate(&module)
        .map_err(|e| format!("{name}: validation error: {:?}", e.into_inner()))?;
    Ok(module)
}

/// Every shader outside `wgsl/shared/` validates after composition. The shared pieces are
/// validated as part of every shader that includes them (they are not self-contained), and
/// [`every_shared_piece_is_embedded_and_included`] makes sure each one is included.
#[test]
fn every_wgsl_file_validates() {
    let files: Vec<String> = wgsl_files().into_iter().filter(|f| !is_shared(f)).collect();
    assert!(!files.is_empty(), "no shader found under wgsl/");
    assert!(
        files.iter().any(|f| f.contains('/')),
        "no shader found in a subfolder of wgsl/ (wgsl/render/ has four)"
    );
    let failures: Vec<String> = files
        .iter()
        .filter_map(|f| parse(&format!("wgsl/{f}"), &read(f)).err())
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} shaders fail:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
}

#[test]
fn every_shared_piece_is_embedded_and_included() {
    let files = wgsl_files();
    let shared: Vec<&String> = files.iter().filter(|f| is_shared(f)).collect();
    let mut problems = Vec::new();
    for f in &shared {
        match SHARED.iter().find(|(p, _)| p == f) {
            None => problems.push(format!("wgsl/{f} is not in coif::gpu::wgsl::SHARED")),
            Some((_, text)) if *text != read(f) => {
                problems.push(format!("wgsl/{f}: SHARED embeds a stale copy"))
            }
            Some(_) => {}
        }
        let included = files
            .iter()
            .any(|g| read(g).lines().any(|l| include_path(l) == Some(f.as_str())));
        if !included {
            problems.push(format!(
                "wgsl/{f} is included by no shader, so nothing validates it"
            ));
        }
    }
    for (p, _) in SHARED {
        if !shared.iter().any(|f| f == p) {
            problems.push(format!("SHARED lists {p}, which is not a file under wgsl/"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn every_wgsl_file_is_registered_exactly_once_and_back() {
    let files = wgsl_files();
    let reg = registered();
    let mut problems = Vec::new();
    for f in files.iter().filter(|f| !is_shared(f)) {
        let n = reg.iter().filter(|(p, ..)| p == f).count();
        if n != 1 {
            problems.push(format!(
                "wgsl/{f} is used by {n} registry entries (stages::ALL, stages::RENDER), not 1"
            ));
        }
    }
    for (path, name, wgsl) in &reg {
        if !files.contains(path) {
            problems.push(format!("stage {name} has no wgsl/{path}"));
        } else if read(path) != *wgsl {
            problems.push(format!("stage {name} embeds a stale copy of wgsl/{path}"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn every_render_stage_has_its_entry_points() {
    for s in stages::RENDER {
        let m = parse(s.name, s.wgsl).unwrap();
        for (vs, fs) in s.entry_points {
            for (ep, stage) in [
                (vs, naga::ShaderStage::Vertex),
                (fs, naga::ShaderStage::Fragment),
            ] {
                assert!(
                    m.entry_points
                        .iter()
                        .any(|e| e.name == *ep && e.stage == stage),
                    "render stage {} has no {stage:?} entry point {ep}",
                    s.name
                );
            }
        }
        for ep in s.compute {
            assert!(
                m.entry_points
                    .iter()
                    .any(|e| e.name == *ep && e.stage == naga::ShaderStage::Compute),
                "render stage {} has no compute entry point {ep}",
                s.name
            );
        }
    }
}

#[test]
fn every_stage_declares_the_bindings_its_shader_has() {
    for s in stages::ALL {
        let m = parse(s.name, s.wgsl).unwrap();
        let mut bindings: Vec<(u32, String)> = m
            .global_variables
            .iter()
            .filter_map(|(_, g)| {
                g.binding
                    .as_ref()
                    .map(|b| (b.binding, format!("{:?}", g.space)))
            })
            .collect();
        bindings.sort();
        assert_eq!(bindings.len(), s.bindings.len(), "stage {}", s.name);
        for ((i, space), decl) in bindings.iter().zip(s.bindings) {
            let want = match decl {
                coif::gpu::engine::Bind::Uniform => "Uniform",
                coif::gpu::engine::Bind::Read => "Storage { access: StorageAccess(LOAD) }",
                coif::gpu::engine::Bind::ReadWrite => {
                    "Storage { access: StorageAccess(LOAD | STORE) }"
                }
            };
            assert_eq!(space, want, "stage {} binding {i}", s.name);
        }
        assert!(
            m.entry_points.iter().any(|e| e.name == "main"),
            "stage {} has no `main` entry point",
            s.name
        );
    }
}

/// Writes a value whose k-th field holds the bits k+1 and checks that naga puts member k of
/// the WGSL struct `Config` at the byte that holds k+1, with the same total size.
fn check_layout(stage: &str, wgsl: &str, bytes: Vec<u8>, n_fields: usize) {
    let m = parse(stage, wgsl).unwrap();
    let (_, ty) = m
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("Config"))
        .unwrap_or_else(|| panic!("{stage}: no struct Config"));
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{stage}: Config is not a struct")
    };
    assert_eq!(*span as usize, bytes.len(), "{stage}: Config size differs");
    assert_eq!(
        members.len(),
        n_fields,
        "{stage}: Config member count differs"
    );
    for (k, mem) in members.iter().enumerate() {
        let o = mem.offset as usize;
        let got = u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
        assert_eq!(
            got,
            k as u32 + 1,
            "{stage}: member {:?} at offset {o} does not hold Rust field {k}",
            mem.name
        );
    }
}

fn encase_bytes<T: encase::ShaderType + encase::internal::WriteInto>(v: &T) -> Vec<u8> {
    let mut b = encase::UniformBuffer::new(Vec::<u8>::new());
    b.write(v).unwrap();
    b.into_inner()
}

#[test]
fn uniform_structs_match_wgsl() {
    use stages::{gabor, orient_resolve, sep_blur};
    let f = |k: u32| f32::from_bits(k);
    check_layout(
        "sep_blur",
        sep_blur::STAGE.wgsl,
        encase_bytes(&sep_blur::Config {
            width: 1,
            height: 2,
            radius: 3,
            axis: 4,
            subtract: 5,
            _pad0: 6,
            _pad1: 7,
            _pad2: 8,
        }),
        8,
    );
    check_layout(
        "gabor",
        gabor::STAGE.wgsl,
        encase_bytes(&gabor::Config {
            width: 1,
            height: 2,
            half: 3,
            n_orient: 4,
            min_response: f(5),
            min_contrast: f(6),
            final_pass: 7,
            _pad2: 8,
        }),
        8,
    );
    check_layout(
        "dir_diffuse",
        stages::dir_diffuse::STAGE.wgsl,
        encase_bytes(&stages::dir_diffuse::Config {
            width: 1,
            height: 2,
            lambda: f(3),
            use_orient: 4,
        }),
        4,
    );
    check_layout(
        "orient_resolve",
        orient_resolve::STAGE.wgsl,
        encase_bytes(&orient_resolve::Config {
            width: 1,
            height: 2,
            _pad0: 3,
            _pad1: 4,
        }),
        4,
    );
    check_layout(
        "orient_moments",
        stages::orient_moments::STAGE.wgsl,
        encase_bytes(&stages::orient_moments::Config {
            width: 1,
            height: 2,
            radius: 3,
            seg_len: 4,
            robust: 5,
            delta: f(6),
            power: f(7),
            _pad1: 8,
        }),
        8,
    );
    check_layout(
        "orient_fit",
        stages::orient_fit::STAGE.wgsl,
        encase_bytes(&stages::orient_fit::Config {
            width: 1,
            height: 2,
            radius: 3,
            seg_len: 4,
            ridge: f(5),
            _pad0: 6,
            _pad1: 7,
            _pad2: 8,
        }),
        8,
    );
    check_layout(
        "strand_shade",
        stages::strand_shade::STAGE.wgsl,
        encase_bytes(&stages::strand_shade::Config {
            n_vertices: 1,
            row_stride: 2,
            n_lights: 3,
            model: 4,
            amount: f(5),
            diffuse: f(6),
            recolour: 7,
            hue_deg: f(8),
            sat_scale: f(9),
            val_scale: f(10),
            alpha_r: f(11),
            beta_r: f(12),
            view_x: f(13),
            view_y: f(14),
            view_z: f(15),
            _pad0: 16,
        }),
        16,
    );
    // flow_down and flow_up: the same four sizes.
    for st in [&stages::flow_down::STAGE, &stages::flow_up::STAGE] {
        check_layout(
            st.name,
            st.wgsl,
            encase_bytes(&stages::flow_down::Config {
                src_w: 1,
                src_h: 2,
                dst_w: 3,
                dst_h: 4,
            }),
            4,
        );
    }
    check_layout(
        "flow_warp",
        stages::flow_warp::STAGE.wgsl,
        encase_bytes(&stages::flow_warp::Config {
            width: 1,
            height: 2,
            _pad0: 3,
            _pad1: 4,
        }),
        4,
    );
    check_layout(
        "flow_solve",
        stages::flow_solve::STAGE.wgsl,
        encase_bytes(&stages::flow_solve::Config {
            width: 1,
            height: 2,
            colour: 3,
            _pad0: 4,
            alpha: f(5),
            eps_data: f(6),
            eps_smooth: f(7),
            omega: f(8),
        }),
        8,
    );
    // One uniform shared by the four PatchMatch stages.
    let pm = encase_bytes(&stages::pm_common::Config {
        width: 1,
        height: 2,
        radius: 3,
        seed: 4,
        pass_id: 5,
        step: 6,
        search_radius: 7,
        fallback: 8,
        coarse_width: 9,
        coarse_height: 10,
        vote_k: f(11),
        layer: 12,
    });
    for st in [
        &stages::pm_init::STAGE,
        &stages::pm_cost::STAGE,
        &stages::pm_search::STAGE,
        &stages::pm_vote::STAGE,
    ] {
        check_layout(st.name, st.wgsl, pm.clone(), 12);
    }
}

#[test]
fn layout_check_fails_on_a_swapped_field() {
    // The helper above must be able to fail: feed it a struct with two fields swapped.
    let wgsl = "struct Config { a: u32, b: u32, }\n@group(0) @binding(0) var<uniform> cfg: Config;\n@compute @workgroup_size(1) fn main() { _ = cfg.a; }";
    let mut bytes = Vec::new();
    for v in [2u32, 1] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let r = std::panic::catch_unwind(|| check_layout("swapped", wgsl, bytes, 2));
    assert!(r.is_err(), "a swapped field went unnoticed");
}
