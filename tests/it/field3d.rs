//! Tests of the 3D direction field (C13 Eq. 3): WGSL/CPU parity of every stage on lavapipe,
//! multigrid against an f64 CG reference, sweep counts against plain Jacobi, bad input. The
//! field passes share `shared/field_cfg.wgsl` and `shared/field_uv_nb.wgsl`, exercised here.
//!
//! Run: `XDG_RUNTIME_DIR=/tmp CARGO_TARGET_DIR=/work/target-h cargo test --release -- --nocapture`

use coif::gpu::engine::{BufProxy, Recording};
use coif::model::field3d::*;
use coif::stages::field_cfg::Config;
use coif::stages::*;
use coif::testing::{assert_no_sentinel, compare_f32, Tolerance, SENTINEL_BITS};
use coif::{BackendChoice, Engine, Error};
use std::time::Instant;

fn gpu() -> Engine {
    std::env::set_var("XDG_RUNTIME_DIR", "/tmp");
    Engine::new(BackendChoice::Gpu).expect("lavapipe available")
}

/// Deterministic hash in [0, 1).
fn hash01(i: u64, salt: u64) -> f32 {
    let mut x = i.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ salt.wrapping_mul(0xc2b2_ae3d_27d4_eb4f);
    x ^= x >> 31;
    x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x ^= x >> 29;
    (x >> 40) as f32 / (1u64 << 24) as f32
}

fn data(n: usize, salt: u64) -> Vec<f32> {
    (0..n).map(|i| 2.0 * hash01(i as u64, salt) - 1.0).collect()
}

/// cellw: -1 outside (~30 % of cells), 0 or a penalty inside.
fn cellw(n: usize, salt: u64) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let a = hash01(i as u64, salt);
            if a < 0.3 {
                -1.0
            } else if a < 0.4 {
                10.0 * hash01(i as u64, salt + 1)
            } else {
                0.0
            }
        })
        .collect()
}

/// Link weights (to +x, +y, +z, 3 per cell) between in-H cells of `w`: mostly 1, some 0
/// (cells the level keeps apart) and some fractional, so the weighting is exercised.
fn links(d: [u32; 3], w: &[f32], salt: u64) -> Vec<f32> {
    let n = w.len();
    let stride = [1usize, d[0] as usize, (d[0] * d[1]) as usize];
    let mut l = vec![0.0f32; 3 * n];
    for i in 0..n {
        let c = [
            i % d[0] as usize,
            i / stride[1] % d[1] as usize,
            i / stride[2],
        ];
        for a in 0..3 {
            if c[a] + 1 < d[a] as usize && w[i] >= 0.0 && w[i + stride[a]] >= 0.0 {
                let h = hash01((3 * i + a) as u64, salt);
                l[3 * i + a] = if h < 0.15 {
                    0.0
                } else if h < 0.3 {
                    0.5
                } else {
                    1.0
                };
            }
        }
    }
    l
}

/// The coarse cellw consistent with `fine` (in H iff a child is).
fn coarse_cellw(d: [u32; 3], fine: &[f32]) -> ([u32; 3], Vec<f32>) {
    let cd = d.map(|x| x.div_ceil(2));
    let mut w = vec![-1.0f32; (cd[0] * cd[1] * cd[2]) as usize];
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                if fine[(x + d[0] * (y + d[1] * z)) as usize] >= 0.0 {
                    w[(x / 2 + cd[0] * (y / 2 + cd[1] * (z / 2))) as usize] = 0.5;
                }
            }
        }
    }
    (cd, w)
}

fn run_both(build: impl Fn(&mut Recording) -> Vec<BufProxy>) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let run = |e: &Engine| {
        let mut rec = Recording::default();
        let outs = build(&mut rec);
        for &o in &outs {
            rec.download(o);
        }
        let dl = e.run(rec).unwrap();
        outs.iter().map(|&o| dl.get::<f32>(o)).collect::<Vec<_>>()
    };
    (run(&gpu()), run(&Engine::cpu()))
}

const SIZES: &[[u32; 3]] = &[[13, 11, 9], [24, 24, 24]];
/// f32 stencil sums in a different order (GPU may fuse multiply-adds).
const TOL: Tolerance = Tolerance::new(1e-5, 1e-4);

fn cfg(d: [u32; 3], cd: [u32; 3], colour: u32, mode: u32, sigma: f32, count: u32) -> Config {
    Config {
        nx: d[0],
        ny: d[1],
        nz: d[2],
        colour,
        sigma,
        mode,
        cnx: cd[0],
        cny: cd[1],
        cnz: cd[2],
        count,
    }
}

#[test]
fn smooth_matches_cpu() {
    for &d in SIZES {
        let n = (d[0] * d[1] * d[2]) as usize;
        let w = cellw(n, 1);
        let lk = links(d, &w, 21);
        let f = data(6 * n, 2);
        let uv = data(6 * n, 3);
        for (colour, mode) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (g, c) = run_both(|rec| {
                let c = cfg(d, [0; 3], colour, mode, 0.25, 0);
                let u = rec.uniform("cfg", &c);
                let (wb, fb) = (rec.upload("w", &w), rec.upload("f", &f));
                let (ub, lb) = (rec.upload("uv", &uv), rec.upload("links", &lk));
                rec.dispatch(
                    &field_smooth::STAGE,
                    field_smooth::workgroups(&c),
                    &[u, wb, fb, ub, lb],
                    &[],
                );
                vec![ub]
            });
            let name = format!("field_smooth {d:?} colour {colour} mode {mode}");
            let st = compare_f32(&name, &g[0], &c[0], TOL).unwrap();
            // The pass must have changed exactly the in-H cells of its colour.
            let changed = (0..n).filter(|&i| c[0][6 * i..6 * i + 6] != uv[6 * i..6 * i + 6]);
            let expect = (0..n).filter(|&i| {
                let (x, y, z) = (
                    i as u32 % d[0],
                    i as u32 / d[0] % d[1],
                    i as u32 / (d[0] * d[1]),
                );
                w[i] >= 0.0 && (x + y + z) % 2 == colour
            });
            assert_eq!(changed.count(), expect.count(), "{name}");
            println!("{name}: {st}");
        }
    }
}

#[test]
fn resid_matches_cpu() {
    for &d in SIZES {
        let n = (d[0] * d[1] * d[2]) as usize;
        let w = cellw(n, 4);
        let lk = links(d, &w, 22);
        let f = data(6 * n, 5);
        let uv = data(6 * n, 6);
        let (g, c) = run_both(|rec| {
            let c = cfg(d, [0; 3], 0, 0, 0.0625, 0);
            let u = rec.uniform("cfg", &c);
            let (wb, fb, ub) = (
                rec.upload("w", &w),
                rec.upload("f", &f),
                rec.upload("uv", &uv),
            );
            let r = rec.alloc("r", 24 * n as u64, SENTINEL_BITS);
            let lb = rec.upload("links", &lk);
            rec.dispatch(
                &field_resid::STAGE,
                field_resid::workgroups(&c),
                &[u, wb, fb, ub, r, lb],
                &[],
            );
            vec![r]
        });
        let name = format!("field_resid {d:?}");
        assert_no_sentinel(&name, &g[0]).unwrap();
        let st = compare_f32(&name, &g[0], &c[0], TOL).unwrap();
        println!("{name}: {st}");
    }
}

#[test]
fn restrict_and_prolong_match_cpu() {
    for &d in SIZES {
        let n = (d[0] * d[1] * d[2]) as usize;
        let w = cellw(n, 7);
        let (cd, wc) = coarse_cellw(d, &w);
        let nc = wc.len();
        let r = data(6 * n, 8);
        let uvc = data(6 * nc, 9);
        let uv = data(6 * n, 10);
        let (g, c) = run_both(|rec| {
            let c = cfg(d, cd, 0, 0, 1.0, 0);
            let u = rec.uniform("cfg", &c);
            let (wb, wcb) = (rec.upload("w", &w), rec.upload("wc", &wc));
            let rb = rec.upload("r", &r);
            let fc = rec.alloc("fc", 24 * nc as u64, SENTINEL_BITS);
            let zc = rec.alloc("zc", 24 * nc as u64, SENTINEL_BITS);
            rec.dispatch(
                &field_restrict::STAGE,
                field_restrict::workgroups(&c),
                &[u, wb, wcb, rb, fc, zc],
                &[],
            );
            let (uvcb, uvb) = (rec.upload("uvc", &uvc), rec.upload("uv", &uv));
            rec.dispatch(
                &field_prolong::STAGE,
                field_prolong::workgroups(&c),
                &[u, wb, wcb, uvcb, uvb],
                &[],
            );
            vec![fc, zc, uvb]
        });
        for (k, name) in ["restrict f", "restrict uv", "prolong"].iter().enumerate() {
            let name = format!("field {name} {d:?}");
            if k < 2 {
                assert_no_sentinel(&name, &g[k]).unwrap();
            }
            let st = compare_f32(&name, &g[k], &c[k], TOL).unwrap();
            println!("{name}: {st}");
        }
        assert!(
            c[1].iter().all(|&x| x == 0.0),
            "coarse unknowns start at zero"
        );
    }
}

#[test]
fn coarse_direct_matches_cpu() {
    for &d in SIZES {
        let n = (d[0] * d[1] * d[2]) as usize;
        let w = cellw(n, 11);
        let lk = links(d, &w, 23);
        let cells: Vec<u32> = (0..n as u32)
            .filter(|&i| w[i as usize] >= 0.0)
            .take(300)
            .collect();
        let m = cells.len();
        let inv = data(m * m, 12);
        let f = data(6 * n, 13);
        let uv = data(6 * n, 14);
        let (g, c) = run_both(|rec| {
            let c = cfg(d, [0; 3], 0, 0, 0.25, m as u32);
            let u = rec.uniform("cfg", &c);
            let (cb, lb, fb) = (
                rec.upload("cells", &cells),
                rec.upload("links", &lk),
                rec.upload("f", &f),
            );
            let gb = rec.alloc("g", 12 * m as u64, SENTINEL_BITS);
            rec.dispatch(
                &field_coarse_rhs::STAGE,
                field_coarse_rhs::workgroups(&c),
                &[u, cb, fb, gb, lb],
                &[],
            );
            let (ib, ub) = (rec.upload("inv", &inv), rec.upload("uv", &uv));
            rec.dispatch(
                &field_dense::STAGE,
                field_dense::workgroups(&c),
                &[u, cb, ib, gb, ub],
                &[],
            );
            vec![gb, ub]
        });
        let name = format!("field_coarse_rhs {d:?}");
        assert_no_sentinel(&name, &g[0]).unwrap();
        println!("{name}: {}", compare_f32(&name, &g[0], &c[0], TOL).unwrap());
        // Sums of 300 products of magnitude ~1: absolute tolerance.
        let name = format!("field_dense {d:?}");
        println!(
            "{name}: {}",
            compare_f32(&name, &g[1], &c[1], Tolerance::new(1e-3, 1e-4)).unwrap()
        );
    }
}

/// Share of H cells with |reference| > 0.1 whose direction is within 1° of the reference.
fn angle_share(v: &[f32], reference: &[f64]) -> (f64, usize, f64) {
    let (mut ok, mut tot, mut worst) = (0usize, 0usize, 0.0f64);
    for i in 0..reference.len() / 3 {
        let a = &reference[3 * i..3 * i + 3];
        let na = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        if na <= 0.1 {
            continue;
        }
        let b: Vec<f64> = v[3 * i..3 * i + 3].iter().map(|&x| x as f64).collect();
        let nb = b.iter().map(|x| x * x).sum::<f64>().sqrt();
        let cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (na * nb).max(1e-300);
        let ang = cos.clamp(-1.0, 1.0).acos().to_degrees();
        tot += 1;
        worst = worst.max(ang);
        if ang <= 1.0 {
            ok += 1;
        }
    }
    (ok as f64 / tot.max(1) as f64, tot, worst)
}

fn check_against_cg(engine: &Engine, n: u32) -> SolveReport {
    let tv = test_shell(n);
    let t = Instant::now();
    let (v, rep) = solve(
        engine,
        &tv.grid,
        &tv.h,
        &tv.constraints,
        &FieldParams::default(),
    )
    .unwrap();
    let t_mg = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (x, it) = solve_cg_f64(&tv.grid, &tv.h, &tv.constraints, 10.0).unwrap();
    let t_cg = t.elapsed().as_secs_f64();
    let (share, count, worst) = angle_share(&v, &x);
    let sys = NormalSystem::new(&tv.grid, &tv.h, &tv.constraints, 10.0).unwrap();
    let v64: Vec<f64> = v.iter().map(|&x| x as f64).collect();
    println!(
        "{} shell {n}³ (H {} cells, {} constraints): multigrid {} cycles, {} sweeps, rel residual \
         {:.2e} (f64 check {:.2e}) in {t_mg:.2} s; CG f64 {it} iterations in {t_cg:.2} s; \
         within 1°: {:.3} % of {count} cells with |v| > 0.1, worst {worst:.3}°",
        engine.describe(),
        sys.len(),
        tv.constraints.len(),
        rep.cycles,
        rep.smoothing_sweeps,
        rep.rel_residual,
        sys.rel_residual_grid(&v64),
        100.0 * share
    );
    assert!(rep.converged, "{rep:?}");
    assert!(
        count > sys.len() / 2,
        "most of H has a field of magnitude > 0.1"
    );
    assert!(share >= 0.99, "only {:.3} % within 1°", 100.0 * share);
    // Outside H the field is exactly zero.
    for (i, &m) in tv.h.iter().enumerate() {
        if m == 0 {
            assert_eq!(&v[3 * i..3 * i + 3], &[0.0; 3]);
        }
    }
    rep
}

#[test]
fn gpu_multigrid_matches_f64_cg() {
    check_against_cg(&gpu(), 32);
}

#[test]
fn cpu_multigrid_matches_f64_cg_at_80() {
    check_against_cg(&Engine::cpu(), 80);
}

#[test]
fn multigrid_needs_far_fewer_sweeps_than_jacobi() {
    let tol = 1e-5;
    // 24³: Jacobi runs to the end.
    for (n, cap) in [(24u32, 2_000_000u64), (80, 10_000)] {
        let tv = test_shell(n);
        let p = FieldParams::default();
        let (_, rep) = solve(&Engine::cpu(), &tv.grid, &tv.h, &tv.constraints, &p).unwrap();
        let t = Instant::now();
        let j = jacobi_sweeps_to(&tv.grid, &tv.h, &tv.constraints, 10.0, tol, cap).unwrap();
        let how = if j.reached {
            "measured".to_string()
        } else {
            format!(
                "extrapolated from {} sweeps (residual {:.3e}, rate {:.8}/sweep; a lower bound)",
                j.sweeps_run, j.rel_residual, j.rate
            )
        };
        let ratio = rep.smoothing_sweeps as f64 / j.sweeps_to_tol;
        println!(
            "shell {n}³ to rel residual {tol:e}: multigrid {} smoothing sweeps (all levels; {} on \
             the fine grid, {} cycles) vs damped Jacobi (ω = {:.4}) {:.0} sweeps, {how} [{:.1} s]; \
             ratio {ratio:.2e} (need ≤ 1/20)",
            rep.smoothing_sweeps,
            rep.fine_sweeps,
            rep.cycles,
            j.omega,
            j.sweeps_to_tol,
            t.elapsed().as_secs_f64()
        );
        assert!(rep.converged);
        assert!(ratio <= 1.0 / 20.0);
    }
}

#[test]
fn duplicate_constraints_are_averaged() {
    let tv = test_shell(16);
    let e = Engine::cpu();
    let p = FieldParams::default();
    let (c0, t0) = tv.constraints[0];
    // Two targets at one cell = one target at their mean.
    let mut dup = tv.constraints.clone();
    dup[0] = (c0, [t0[0] + 0.5, t0[1], t0[2]]);
    dup.push((c0, [t0[0] - 0.5, t0[1], t0[2]]));
    let (a, _) = solve(&e, &tv.grid, &tv.h, &tv.constraints, &p).unwrap();
    let (b, _) = solve(&e, &tv.grid, &tv.h, &dup, &p).unwrap();
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "duplicates changed the field by {worst}");
}

#[test]
fn unconstrained_component_is_zero() {
    // Two slabs separated by an empty plane; only the first has constraints.
    let grid = Grid {
        dims: [8, 8, 9],
        origin: [0.0; 3],
        cell: 1.0,
    };
    let h: Vec<u32> = (0..grid.len()).map(|i| (i / 64 != 4) as u32).collect();
    let cons = vec![(grid.index(1, 1, 1) as u32, [1.0, 0.0, 0.0])];
    let (v, rep) = solve(&Engine::cpu(), &grid, &h, &cons, &FieldParams::default()).unwrap();
    assert_eq!(rep.unconstrained_cells, 4 * 64);
    assert!(v[3 * grid.index(1, 1, 1)] > 0.9);
    assert!(v[3 * 64 * 5..].iter().all(|&x| x == 0.0));
    // One constraint: the minimiser is the constant field on its component.
    assert!((v[3 * grid.index(6, 6, 3)] - 1.0).abs() < 1e-3);
}

#[test]
fn bad_input_is_rejected() {
    let tv = test_shell(12);
    let e = Engine::cpu();
    let p = FieldParams::default();
    let invalid = |r: coif::Result<(Vec<f32>, SolveReport)>, what: &str| match r {
        Err(Error::Invalid(m)) => println!("{what}: {m}"),
        Err(other) => panic!("{what}: wrong error {other}"),
        Ok(_) => panic!("{what}: accepted"),
    };
    invalid(
        solve(&e, &tv.grid, &tv.h[1..], &tv.constraints, &p),
        "short mask",
    );
    let mut c = tv.constraints.clone();
    c.push((tv.grid.len() as u32, [1.0, 0.0, 0.0]));
    invalid(solve(&e, &tv.grid, &tv.h, &c, &p), "cell out of range");
    let outside = tv.h.iter().position(|&m| m == 0).unwrap() as u32;
    let mut c = tv.constraints.clone();
    c.push((outside, [1.0, 0.0, 0.0]));
    invalid(solve(&e, &tv.grid, &tv.h, &c, &p), "cell outside H");
    let mut c = tv.constraints.clone();
    c[3].1[1] = f32::NAN;
    invalid(solve(&e, &tv.grid, &tv.h, &c, &p), "NaN target");
    let empty = vec![0u32; tv.grid.len()];
    invalid(solve(&e, &tv.grid, &empty, &[], &p), "empty H");
    invalid(solve(&e, &tv.grid, &tv.h, &[], &p), "no constraints");
    let bad = FieldParams {
        w_c: f32::NAN,
        ..FieldParams::default()
    };
    invalid(solve(&e, &tv.grid, &tv.h, &tv.constraints, &bad), "NaN w_c");
    assert!(matches!(
        solve_cg_f64(&tv.grid, &tv.h[1..], &tv.constraints, 10.0),
        Err(Error::Invalid(_))
    ));
    assert!(matches!(
        jacobi_sweeps_to(&tv.grid, &empty, &tv.constraints, 10.0, 1e-5, 10),
        Err(Error::Invalid(_))
    ));
}

#[test]
fn shaders_validate() {
    for s in ALL {
        // Shaders name shared pieces with `#include`; naga sees them expanded.
        let src = coif::gpu::wgsl::compose(s.name, s.wgsl).unwrap();
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{}: {}", s.name, e.emit_to_string(&src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}: {e:?}", s.name));
    }
}
