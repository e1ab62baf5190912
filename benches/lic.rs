//! Line-integral convolution (CZ06 §3.2, the `cz_lic` pass of `coif::sketch::texture`) at
//! 512² against PyPI `rlic` (`benches/peers/lic_rlic.py`, run in the same bench) on the same
//! white noise and the same field (filled from the oracle sketch of `coif synth` long), the
//! same kernel (box, 2·4 + 1 taps; ours: RK2 steps of 1 px, 4 each way), 1 and 8 iterations,
//! with the time ratio ours/rlic and the correlation of the two outputs over the hair. Then
//! the whole `synthesise` (8 rounds) on the same field; with lavapipe, the largest difference
//! of its outputs from the cpu backend's (parity at 512²).
//!
//! The peer runs in a virtualenv the bench creates on first use (`python3 -m venv`, then
//! `pip install numpy rlic`) under `$CARGO_TARGET_DIR/peer-venv` (or `target/peer-venv`;
//! COIF_BENCH_VENV overrides); without network or pip the bench says so and times ours alone.
//!
//! Run: `cargo bench --bench lic`. COIF_BENCH_SIZE (512), COIF_BENCH_REPS (5),
//! COIF_BENCH_GPU=1 adds lavapipe.

use coif::gpu::engine::{BackendChoice, Engine};
use coif::sketch::fill::{fill, FillParams};
use coif::sketch::oracle::oracle_sketch;
use coif::sketch::prim::paint;
use coif::sketch::texture::{self, TextureParams};
use coif::sketch::RhoPrior;
use coif::stages::cz_noise;
use coif::synth::{synth, Style, SynthParams};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(d)
}

/// The venv's python with rlic, creating the venv if needed; Err says why not.
fn peer_python() -> Result<PathBuf, String> {
    let dir = match std::env::var("COIF_BENCH_VENV") {
        Ok(d) => PathBuf::from(d),
        Err(_) => std::env::var("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"))
            .join("peer-venv"),
    };
    let py = dir.join("bin/python");
    let has_rlic = |py: &Path| {
        Command::new(py)
            .args(["-c", "import rlic, numpy"])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if has_rlic(&py) {
        return Ok(py);
    }
    if !py.exists() {
        let o = Command::new("python3")
            .args(["-m", "venv"])
            .arg(&dir)
            .output()
            .map_err(|e| format!("cannot run python3 -m venv: {e}"))?;
        if !o.status.success() {
            return Err(format!(
                "python3 -m venv {} failed: {}",
                dir.display(),
                String::from_utf8_lossy(&o.stderr).trim()
            ));
        }
    }
    let o = Command::new(dir.join("bin/pip"))
        .args(["install", "-q", "numpy", "rlic"])
        .output()
        .map_err(|e| format!("cannot run pip: {e}"))?;
    if !o.status.success() || !has_rlic(&py) {
        return Err(format!(
            "pip install numpy rlic into {} failed: {}",
            dir.display(),
            String::from_utf8_lossy(&o.stderr).trim()
        ));
    }
    Ok(py)
}

/// rlic's output and median milliseconds.
fn peer(
    py: &Path,
    noise: &[f32],
    uv: &[Vec<f32>; 2],
    size: u32,
    klen: u32,
    iters: u32,
    reps: u32,
) -> Result<(Vec<f32>, f64, String), String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let shape = [size as usize, size as usize];
    let p = |n: &str| dir.path().join(n);
    for (name, data) in [("noise.npy", noise), ("u.npy", &uv[0]), ("v.npy", &uv[1])] {
        coif::io::npy::write_f32(&p(name), &shape, data).map_err(|e| e.to_string())?;
    }
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/peers/lic_rlic.py");
    let o = Command::new(py)
        .arg(script)
        .args([p("noise.npy"), p("u.npy"), p("v.npy"), p("out.npy")])
        .args([klen.to_string(), iters.to_string(), reps.to_string()])
        .output()
        .map_err(|e| e.to_string())?;
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).into_owned());
    }
    let line = String::from_utf8_lossy(&o.stdout)
        .lines()
        .last()
        .unwrap_or("")
        .to_string();
    let v: serde_json::Value = serde_json::from_str(&line).map_err(|e| e.to_string())?;
    let (_, out) = coif::io::npy::read_f32(&p("out.npy")).map_err(|e| e.to_string())?;
    Ok((
        out,
        v["median_ms"].as_f64().unwrap_or(f64::NAN),
        v["peer"].as_str().unwrap_or("rlic").to_string(),
    ))
}

fn median_ms(reps: u32, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Pearson correlation of a and b over `keep`.
fn corr(a: &[f32], b: &[f32], keep: &[bool]) -> f64 {
    let idx: Vec<usize> = (0..a.len()).filter(|&k| keep[k]).collect();
    let m = |v: &[f32]| idx.iter().map(|&k| v[k] as f64).sum::<f64>() / idx.len() as f64;
    let (ma, mb) = (m(a), m(b));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for &k in &idx {
        let (x, y) = (a[k] as f64 - ma, b[k] as f64 - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    sab / (saa * sbb).sqrt()
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
}

fn main() {
    let size: u32 = env("COIF_BENCH_SIZE", 512);
    let reps: u32 = env("COIF_BENCH_REPS", 5);
    let mut engines = vec![("cpu", Engine::cpu())];
    if env("COIF_BENCH_GPU", 0) != 0 {
        match Engine::new(BackendChoice::Gpu) {
            Ok(e) => engines.push(("lavapipe", e)),
            Err(e) => eprintln!("no GPU engine: {e}"),
        }
    }
    let case = synth(&SynthParams {
        style: Style::Long,
        seed: 1,
        width: size,
        height: size,
    });
    let hair: Vec<bool> = case.mask.as_raw().iter().map(|&v| v > 127).collect();
    let painted = paint(&oracle_sketch(&case), size, size, Some(&hair));
    let prior = RhoPrior {
        weight: [0.7, 0.3],
        mean: [4.0, 9.0],
        sigma: [1.5, 3.0],
    };
    let field = fill(
        &engines[0].1,
        &painted,
        &hair,
        &prior,
        1,
        &FillParams::default(),
    )
    .expect("fill");
    let dom: Vec<bool> = (0..hair.len())
        .map(|k| hair[k] && field.theta[k].is_finite() && field.rho[k].is_finite())
        .collect();
    // rlic takes only positive textures: the pass's noise, half-width 0.5, about 1 (LIC is
    // linear; neither side reads off the hair, which is 1 to keep rlic's check quiet).
    let ncfg = cz_noise::Config::new(size, size, 1, 0.5);
    let noise: Vec<f32> = (0..hair.len())
        .map(|k| {
            if dom[k] {
                1.0 + cz_noise::noise_at(&ncfg, k as u32)
            } else {
                1.0
            }
        })
        .collect();
    let uv = [
        field.theta.iter().map(|t| t.cos()).collect::<Vec<f32>>(),
        field.theta.iter().map(|t| t.sin()).collect::<Vec<f32>>(),
    ];
    let half_len = TextureParams::default().half_len;
    let klen = 2 * half_len as u32 + 1;
    println!(
        "LIC at {size}², field from the oracle sketch of synth long ({} hair px), box kernel of \
         {klen} taps, median of {reps}",
        dom.iter().filter(|&&d| d).count()
    );
    let py = peer_python();
    if let Err(e) = &py {
        println!(
            "rlic peer unavailable: {e}\n(the bench needs python3 with venv and pip access to \
             PyPI for `rlic`; timing ours alone)"
        );
    }
    for iters in [1u32, 8] {
        let pr = py
            .as_ref()
            .ok()
            .map(|py| peer(py, &noise, &uv, size, klen, iters, reps));
        if let Some(Err(e)) = &pr {
            println!("rlic failed: {e}");
        }
        let mut first: Option<Vec<f32>> = None;
        for (bname, engine) in &engines {
            let mut out = Vec::new();
            let ms = median_ms(reps, || {
                out = texture::lic(engine, &field, &hair, &noise, half_len, iters).expect("lic");
            });
            match &first {
                None => first = Some(out.clone()),
                Some(c) => println!(
                    "{iters} iteration(s) at {size}²: max |{bname} − cpu| = {:.2e}",
                    max_diff(&out, c)
                ),
            }
            match &pr {
                Some(Ok((theirs, pms, name))) => println!(
                    "{iters} iteration(s): ours ({bname}) {ms:.1} ms, {name} {pms:.1} ms, ratio \
                     ours/rlic {:.2}; correlation of the outputs over the hair {:.3}",
                    ms / pms,
                    corr(&out, theirs, &dom)
                ),
                _ => println!("{iters} iteration(s): ours ({bname}) {ms:.1} ms"),
            }
        }
    }
    let p = TextureParams::default();
    let mut first: Option<Vec<f32>> = None;
    for (bname, engine) in &engines {
        let mut out = Vec::new();
        let ms = median_ms(reps.min(3), || {
            out = texture::synthesise(engine, &field, &hair, 1, &p).expect("synthesise");
        });
        let s = texture::texture_stats(&out, &field, &hair);
        println!(
            "synthesise ({} rounds, {size}²) on {bname}: {:.2} s; contrast ratio {:.3}, \
             along/across {:.3}",
            p.rounds,
            ms / 1e3,
            s.contrast_ratio,
            s.along_across
        );
        match &first {
            None => first = Some(out),
            Some(c) => println!(
                "synthesise at {size}²: max |{bname} − cpu| = {:.2e} (max |I_H| {:.1})",
                max_diff(&out, c),
                c.iter().fold(0.0f32, |m, v| m.max(v.abs()))
            ),
        }
    }
}
