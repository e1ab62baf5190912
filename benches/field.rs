//! The 3D direction field of C13 Eq. (3) on the 80³ hair-shell test volume
//! (`field3d::test_shell`): our multigrid on the CPU backend and on lavapipe (one timed
//! run, a slow software GPU), next to pyamg smoothed-aggregation AMG + CG on the same
//! normal equations (`benches/peers/field_pyamg.py`) in the same run, to relative residual
//! 1e-5. Prints the time ratio.
//!
//! Run: `CARGO_TARGET_DIR=/work/target-h cargo bench --bench field`
//! (COIF_BENCH_REPS sets repetitions; needs `pip install pyamg scipy` for the peer.)

use coif::model::field3d::{solve, test_shell, FieldParams, NormalSystem};
use coif::{BackendChoice, Engine};
use std::io::Write;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn time_solve(engine: &Engine, n: u32, reps: usize) -> f64 {
    let tv = test_shell(n);
    let p = FieldParams::default();
    let times: Vec<f64> = (0..reps + 1)
        .map(|_| {
            let t = Instant::now();
            let (_, rep) = solve(engine, &tv.grid, &tv.h, &tv.constraints, &p).unwrap();
            assert!(rep.converged);
            t.elapsed().as_secs_f64()
        })
        .skip(1)
        .collect();
    let (_, rep) = solve(engine, &tv.grid, &tv.h, &tv.constraints, &p).unwrap();
    println!(
        "  {} {n}³: {:.3} s median of {reps}; {} cycles, {} smoothing sweeps, rel residual {:.2e}, \
         levels {:?}",
        engine.describe(),
        median(times.clone()),
        rep.cycles,
        rep.smoothing_sweeps,
        rep.rel_residual,
        rep.levels.iter().map(|l| l.dims[0]).collect::<Vec<_>>()
    );
    median(times)
}

fn write_raw<T: bytemuck::Pod>(path: &Path, data: &[T]) {
    std::fs::File::create(path)
        .unwrap()
        .write_all(bytemuck::cast_slice(data))
        .unwrap();
}

/// Writes `(L² + w_c P)` as CSR and `w_c P c` (n x 3) for the peer.
fn write_system(dir: &Path, sys: &NormalSystem) {
    let n = sys.len();
    let lrow = |i: usize| -> Vec<(usize, f64)> {
        let mut r: Vec<(usize, f64)> = sys.nb[i]
            .iter()
            .filter(|&&j| j != u32::MAX)
            .map(|&j| (j as usize, 1.0))
            .collect();
        let d = r.len() as f64;
        r.push((i, -d));
        r
    };
    let (mut indptr, mut indices, mut data) = (vec![0i64], Vec::new(), Vec::new());
    for i in 0..n {
        // Row i of L·L (L symmetric) plus the penalty on the diagonal.
        let mut acc: Vec<(usize, f64)> = Vec::new();
        for (k, lik) in lrow(i) {
            for (j, lkj) in lrow(k) {
                acc.push((j, lik * lkj));
            }
        }
        acc.push((i, sys.pen[i]));
        acc.sort_by_key(|e| e.0);
        let mut merged: Vec<(usize, f64)> = Vec::new();
        for (j, v) in acc {
            match merged.last_mut() {
                Some(last) if last.0 == j => last.1 += v,
                _ => merged.push((j, v)),
            }
        }
        for (j, v) in merged {
            if v != 0.0 {
                indices.push(j as i32);
                data.push(v);
            }
        }
        indptr.push(indices.len() as i64);
    }
    write_raw(&dir.join("indptr.i64"), &indptr);
    write_raw(&dir.join("indices.i32"), &indices);
    write_raw(&dir.join("data.f64"), &data);
    write_raw(&dir.join("b.f64"), &sys.b);
}

fn json_f64(s: &str, key: &str) -> Option<f64> {
    let at = s.find(&format!("\"{key}\":"))? + key.len() + 3;
    let rest = s[at..].trim_start();
    let end = rest.find([',', '}']).unwrap_or(rest.len());
    rest[..end].trim().parse().ok()
}

fn main() {
    let reps: usize = std::env::var("COIF_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let n = 80;
    println!("field3d (C13 Eq. 3) on the {n}³ hair shell, relative residual 1e-5:");
    let ours = time_solve(&Engine::cpu(), n, reps);
    match Engine::new(BackendChoice::Gpu) {
        Ok(g) => {
            // lavapipe runs the same recording in software: one timed run.
            let t = time_solve(&g, n, 1);
            println!("  lavapipe / cpu backend: {:.1}x", t / ours);
        }
        Err(e) => println!("  no GPU backend: {e}"),
    }
    let tv = test_shell(n);
    let sys = NormalSystem::new(&tv.grid, &tv.h, &tv.constraints, 10.0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_system(dir.path(), &sys);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/field_pyamg.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(dir.path())
        .arg("1e-5")
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let s = String::from_utf8_lossy(&o.stdout).to_string();
            println!(
                "  pyamg SA + CG (same normal equations, n = {}): {}",
                sys.len(),
                s.trim()
            );
            let peer = json_f64(&s, "total_s").expect("peer prints total_s");
            println!(
                "  time ratio ours (cpu backend) / pyamg (setup + solve): {:.2} ({:.3} s vs {:.3} s)",
                ours / peer,
                ours,
                peer
            );
        }
        Ok(o) => println!(
            "  pyamg peer failed (pip install pyamg scipy): {}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => println!("  cannot run python3: {e}"),
    }
}
