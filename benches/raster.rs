//! The strand rasteriser (C13 §4) at full size: 30k strands x 50 vertices at 1024², 1-px
//! quads, per-vertex colours and alphas, 4x MSAA with alpha-to-coverage: `render` on the CPU
//! backend and on lavapipe, next to Skia (skia-python, anti-aliased path strokes, one colour
//! per strand; `benches/peers/raster_skia.py`) drawing the same strands in the same run.
//! Prints times and ratios. On lavapipe also the strands drawn by the render pipeline (the GPU
//! path before the compute passes of `wgsl/render/strand_vis.wgsl`), for the before/after.
//!
//! Then growth rows: the cpu backend at 2048² and with 2x the strands, with peak memory.
//!
//! Run: `CARGO_TARGET_DIR=/work/target cargo bench --bench raster`
//! (COIF_BENCH_REPS sets the rounds, default 9: after a warm-up, rounds of one cpu render
//! and one skia draw, then rounds of one lavapipe render and one skia draw, so that the
//! ratios, medians over rounds, compare neighbours in time (9 rather than 3: on the 2-core
//! development VM the host slows one core or both for a second or more at a time, which
//! moves our two threads' time and not skia's one; the median of 9 rounds holds through
//! more of that); needs `pip install skia-python numpy` for the peer; RASTER_BENCH_PNG=dir writes our
//! two images there; RASTER_BENCH_RAW=file writes the cpu image as raw f32 RGBA, for
//! bit-exact before/after checks; RASTER_BENCH_CPU_ONLY=1 runs the cpu backend alone, for
//! profiling it; RASTER_BENCH_GPU_ONLY=1 times lavapipe alone (its
//! image to RASTER_BENCH_RAW); COIF_NO_AVX2=1 runs the baseline x86-64 build of the tile loop.)

use coif::base::colour::to_rgba8;
use coif::base::rng::Rng;
use coif::render::raster::{render, render_gpu_pipeline, Frame, RasterParams, ScreenStrands};
use coif::{BackendChoice, Engine};
use std::io::Write;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

const SIZE: u32 = 1024;
const STRANDS: usize = 30_000;
const VERTS: usize = 50;

/// Share of pixels whose 8-bit sRGB channels all lie within 2 levels of the other image's.
fn within_2(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    let (a, b) = (to_rgba8(a), to_rgba8(b));
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(x, y)| x.iter().zip(y.iter()).all(|(u, v)| u.abs_diff(*v) <= 2))
        .count() as f64
        / (a.len() / 4) as f64
}

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Hair-like strands: roots on the upper half of a sphere (the scalp, front and back), each
/// growing out along the normal, then bending under "gravity" with a little curl, kept
/// outside the skull; brown with per-strand variation, lighter and more transparent at the
/// tips. Screen px, depth px (larger = nearer).
fn hair(seed: u64, size: u32, strands: usize) -> ScreenStrands {
    let mut rng = Rng::new(seed);
    let c = [size as f32 * 0.5, size as f32 * 0.4, 0.0];
    let r = size as f32 * 0.2;
    let step = 7.5f32 * size as f32 / SIZE as f32;
    let mut s = ScreenStrands::default();
    for _ in 0..strands {
        // Uniform direction on the sphere, kept on the upper part (y up = -screen y).
        let (mut u, mut len2) = ([0.0f32; 3], 0.0f32);
        while !(0.01..=1.0).contains(&len2) || u[1] > 0.3 * len2.sqrt() {
            u = [
                rng.range_f32(-1.0, 1.0),
                rng.range_f32(-1.0, 1.0),
                rng.range_f32(-1.0, 1.0),
            ];
            len2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
        }
        let l = len2.sqrt();
        let n = u.map(|v| v / l);
        let mut p: [f32; 3] = std::array::from_fn(|k| c[k] + r * n[k]);
        let mut d = n;
        let curl = rng.range_f32(-0.06, 0.06);
        let shade = rng.range_f32(0.7, 1.3);
        let alpha = rng.range_f32(0.6, 1.0);
        for k in 0..VERTS {
            let f = k as f32 / (VERTS - 1) as f32;
            s.points.push(p);
            s.colors.push([
                (0.16 + 0.25 * f) * shade,
                (0.08 + 0.14 * f) * shade,
                (0.035 + 0.06 * f) * shade,
                alpha * (1.0 - 0.45 * f),
            ]);
            // Bend toward screen-down, curl around the view axis, keep outside the skull.
            let g = 0.12;
            d = [
                d[0] + curl * d[1] + 0.05 * rng.normal_f32(),
                d[1] + g - curl * d[0] + 0.05 * rng.normal_f32(),
                d[2] * 0.97 + 0.05 * rng.normal_f32(),
            ];
            let dl = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            d = d.map(|v| v / dl);
            p = std::array::from_fn(|k| p[k] + step * d[k]);
            let q: [f32; 3] = std::array::from_fn(|k| p[k] - c[k]);
            let ql = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            if ql < r * 1.02 {
                p = std::array::from_fn(|k| c[k] + q[k] * (r * 1.02 / ql));
            }
        }
        s.counts.push(VERTS as u32);
    }
    s
}

/// CPU seconds this process has used (user + system, from /proc; 0 where unavailable).
/// The machine is shared, so wall time alone can mislead.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the parenthesised command name; utime and stime are the 12th and 13th.
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|v| v.parse().ok())
        .collect();
    f.iter().sum::<f64>() / 100.0
}

/// The process's resident-set high-water mark and current size, in MiB (VmHWM, VmRSS).
fn rss_mib() -> (f64, f64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map_or(f64::NAN, |kib| kib / 1024.0)
    };
    (field("VmHWM:"), field("VmRSS:"))
}

/// Resets the high-water mark to the current RSS (Linux: "5" to /proc/self/clear_refs).
fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// One cpu-backend render of `strands` at `size`²: (median seconds of `reps`, peak RSS MiB
/// during the renders, RSS before them MiB).
fn cpu_row(strands: &ScreenStrands, size: u32, p: &RasterParams, reps: usize) -> (f64, f64, f64) {
    let frame = Frame {
        width: size,
        height: size,
        depth_range: (-2.0 * size as f32, 2.0 * size as f32),
        background: None,
    };
    let cpu = Engine::cpu();
    let before = rss_mib().1;
    reset_peak();
    let times = (0..reps)
        .map(|_| {
            let t = Instant::now();
            let img = render(&cpu, &frame, None, Some(strands), p).unwrap();
            let s = t.elapsed().as_secs_f64();
            drop(img);
            s
        })
        .collect();
    (median(times), rss_mib().0, before)
}

fn write_raw<T: bytemuck::Pod>(path: &Path, data: &[T]) {
    std::fs::File::create(path)
        .unwrap()
        .write_all(bytemuck::cast_slice(data))
        .unwrap();
}

fn drawn_share(img: &[[f32; 4]]) -> f64 {
    img.iter().filter(|p| p[3] > 0.0).count() as f64 / img.len() as f64
}

fn save(img: &[[f32; 4]], name: &str) {
    if let Some(dir) = std::env::var_os("RASTER_BENCH_PNG") {
        let path = Path::new(&dir).join(name);
        image::RgbaImage::from_raw(SIZE, SIZE, to_rgba8(img))
            .unwrap()
            .save(&path)
            .unwrap();
        println!("  wrote {}", path.display());
    }
}

/// The skia peer (`benches/peers/raster_skia.py serve`), kept running between rounds.
struct Skia {
    child: std::process::Child,
    out: std::io::BufReader<std::process::ChildStdout>,
}

impl Skia {
    /// Starts the peer on the strands in `dir` and waits until its paths are built; None
    /// (with the reason printed) where python3 or skia-python is missing.
    fn start(dir: &Path, width: f32) -> Option<Skia> {
        use std::io::BufRead;
        use std::process::Stdio;
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/raster_skia.py");
        let child = Command::new("python3")
            .arg(&script)
            .arg(dir)
            .arg(SIZE.to_string())
            .arg(SIZE.to_string())
            .arg(width.to_string())
            .arg("serve")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn();
        let mut child = match child {
            Ok(c) => c,
            Err(e) => {
                println!("  cannot run python3 for the skia peer: {e}");
                return None;
            }
        };
        let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
        let mut ready = String::new();
        if out.read_line(&mut ready).unwrap_or(0) == 0 || !ready.contains("\"ready\"") {
            let mut err = String::new();
            use std::io::Read;
            let _ = child.stderr.take().unwrap().read_to_string(&mut err);
            println!("  skia peer failed (pip install skia-python numpy): {err}");
            return None;
        }
        Some(Skia { child, out })
    }

    /// One draw; its seconds.
    fn draw(&mut self) -> f64 {
        use std::io::BufRead;
        let stdin = self.child.stdin.as_mut().unwrap();
        writeln!(stdin, "draw").unwrap();
        stdin.flush().unwrap();
        let mut line = String::new();
        self.out.read_line(&mut line).unwrap();
        line.trim()
            .parse()
            .expect("the peer prints a draw's seconds")
    }

    /// Stops the peer; its closing JSON line.
    fn finish(mut self) -> String {
        use std::io::Read;
        drop(self.child.stdin.take());
        let mut rest = String::new();
        let _ = self.out.read_to_string(&mut rest);
        let _ = self.child.wait();
        rest
    }
}

fn main() {
    let reps: usize = std::env::var("COIF_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(9);
    if let Some(row) = std::env::var("RASTER_BENCH_ROW")
        .ok()
        .and_then(|r| r.parse().ok())
    {
        return growth_child(row, &RasterParams::default(), reps);
    }
    let strands = hair(2013, SIZE, STRANDS);
    let frame = Frame {
        width: SIZE,
        height: SIZE,
        depth_range: (-2.0 * SIZE as f32, 2.0 * SIZE as f32),
        background: None,
    };
    let p = RasterParams::default();
    println!(
        "strand raster: {STRANDS} strands x {VERTS} vertices at {SIZE}², width {} px, {} samples:",
        p.strand_width, p.samples
    );
    // RASTER_BENCH_GPU_ONLY=1: lavapipe alone, one warm-up and `reps` timed runs (for
    // profiling it).
    if std::env::var_os("RASTER_BENCH_GPU_ONLY").is_some() {
        let g = Engine::new(BackendChoice::Gpu).expect("a GPU backend");
        let img = render(&g, &frame, None, Some(&strands), &p).unwrap();
        if let Some(path) = std::env::var_os("RASTER_BENCH_RAW") {
            write_raw(Path::new(&path), &img);
        }
        let times: Vec<f64> = (0..reps)
            .map(|_| {
                let t = Instant::now();
                let _ = render(&g, &frame, None, Some(&strands), &p).unwrap();
                t.elapsed().as_secs_f64()
            })
            .collect();
        println!(
            "  {}: {:.3} s median of {reps}",
            g.describe(),
            median(times)
        );
        return;
    }
    // The peer first: its paths are built before anything is timed (two cores), then it
    // draws one frame whenever a round asks.
    let dir = tempfile::tempdir().unwrap();
    write_raw(&dir.path().join("points.f32"), &strands.points);
    write_raw(&dir.path().join("counts.u32"), &strands.counts);
    write_raw(&dir.path().join("colors.f32"), &strands.colors);
    // RASTER_BENCH_CPU_ONLY=1: the cpu backend alone (for profiling it).
    let cpu_only = std::env::var_os("RASTER_BENCH_CPU_ONLY").is_some();
    let mut skia = if cpu_only {
        None
    } else {
        Skia::start(dir.path(), p.strand_width)
    };
    let cpu = Engine::cpu();
    let gpu = if cpu_only {
        None
    } else {
        match Engine::new(BackendChoice::Gpu) {
            Ok(g) => Some(g),
            Err(e) => {
                println!("  no GPU backend: {e}");
                None
            }
        }
    };
    // Warm-ups (allocation, shader compilation, caches), then `reps` rounds of one cpu
    // render and one skia draw, then `reps` rounds of one lavapipe render and one skia draw:
    // the machine's speed drifts over a run (by 1.4x between runs here), so each round's
    // ratio compares neighbours in time, and the medians are taken over rounds. (The cpu
    // backend keeps its own phase: right after a lavapipe render, whose buffers the
    // allocator has just returned, its first allocations fault in fresh pages.)
    let rss_before = rss_mib().1;
    reset_peak();
    let mut img = render(&cpu, &frame, None, Some(&strands), &p).unwrap();
    let cpu_peak_warm = rss_mib().0;
    if let Some(sk) = skia.as_mut() {
        sk.draw();
    }
    let (mut t_cpu, mut t_gpu, mut cpu_s) = (vec![], vec![], 0.0);
    let (mut skia_cpu, mut skia_gpu) = (vec![], vec![]);
    for _ in 0..reps {
        let (t, c) = (Instant::now(), cpu_seconds());
        img = render(&cpu, &frame, None, Some(&strands), &p).unwrap();
        t_cpu.push(t.elapsed().as_secs_f64());
        cpu_s += (cpu_seconds() - c) / reps as f64;
        if let Some(sk) = skia.as_mut() {
            skia_cpu.push(sk.draw());
        }
    }
    let mut gimg = gpu
        .as_ref()
        .map(|g| render(g, &frame, None, Some(&strands), &p).unwrap());
    if let Some(g) = &gpu {
        for _ in 0..reps {
            let t = Instant::now();
            gimg = Some(render(g, &frame, None, Some(&strands), &p).unwrap());
            // The render's buffers are freed at the device's next poll: counted here, not
            // left to slow the skia draw that follows.
            let ctx = g.gpu().expect("a gpu engine");
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .expect("device poll");
            t_gpu.push(t.elapsed().as_secs_f64());
            if let Some(sk) = skia.as_mut() {
                skia_gpu.push(sk.draw());
            }
        }
    }
    let ours = median(t_cpu.clone());
    println!(
        "  {}: {ours:.3} s median of {reps} ({cpu_s:.2} CPU-s per render); {:.1}% of pixels drawn",
        cpu.describe(),
        100.0 * drawn_share(&img)
    );
    println!(
        "  peak RSS of the first cpu render: {cpu_peak_warm:.0} MiB ({rss_before:.0} MiB before it)"
    );
    save(&img, "raster_cpu.png");
    if let Some(path) = std::env::var_os("RASTER_BENCH_RAW") {
        // The cpu backend's image as raw f32 RGBA (for bit-exact before/after checks).
        write_raw(Path::new(&path), &img);
    }
    let mut pipeline = None;
    if let (Some(g), Some(gimg)) = (&gpu, &gimg) {
        let tg = median(t_gpu.clone());
        println!(
            "  {}: {tg:.3} s median of {reps}; lavapipe / cpu backend: {:.2}x; peak RSS {:.0} MiB \
             (lavapipe's own memory is the process's)",
            g.describe(),
            tg / ours,
            rss_mib().0
        );
        // The rounds reuse the buffers and targets the render before them kept
        // (`coif::gpu::pool`), as a video's frames or a batch's portraits of one size do;
        // a render without them (the pool emptied first) is the first one of a size.
        let ctx = g.gpu().expect("a gpu engine");
        let kept = ctx.pooled_bytes() as f64 / (1u64 << 20) as f64;
        ctx.release_pool();
        let t = Instant::now();
        render(g, &frame, None, Some(&strands), &p).unwrap();
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("device poll");
        println!(
            "  lavapipe on fresh buffers (the pool emptied first): {:.3} s; kept between \
             renders: {kept:.0} MiB",
            t.elapsed().as_secs_f64()
        );
        // The render pipeline's strands (one warm-up, one timed run: the before of the
        // compute passes, not a figure of the issue).
        let _ = render_gpu_pipeline(ctx, &frame, None, Some(&strands), &p).unwrap();
        let t = Instant::now();
        let pimg = render_gpu_pipeline(ctx, &frame, None, Some(&strands), &p).unwrap();
        let tp = t.elapsed().as_secs_f64();
        pipeline = Some(tp);
        let agree_p = within_2(&pimg, &img);
        println!(
            "  lavapipe, strands by the render pipeline instead: {tp:.3} s ({:.3}% of pixels \
             within 2/255 of the cpu image); compute / pipeline {:.2}",
            100.0 * agree_p,
            tg / tp
        );
        let agree = within_2(gimg, &img);
        println!("  gpu vs cpu: {:.3}% of pixels within 2/255", 100.0 * agree);
        // What every call pays regardless of content (pipelines, targets, read-back).
        let tiny = Frame {
            width: 8,
            height: 8,
            depth_range: frame.depth_range,
            background: None,
        };
        let one = ScreenStrands {
            points: vec![[1.0, 1.0, 0.0], [6.0, 6.0, 0.0]],
            counts: vec![2],
            colors: vec![[1.0; 4]; 2],
            photo: None,
        };
        let t = Instant::now();
        render(g, &tiny, None, Some(&one), &p).unwrap();
        println!(
            "  lavapipe fixed cost per call (8x8 frame, one segment): {:.3} s",
            t.elapsed().as_secs_f64()
        );
        save(gimg, "raster_gpu.png");
    }
    if let Some(sk) = skia.take() {
        let info = sk.finish();
        let draw = median([skia_cpu.as_slice(), &skia_gpu].concat());
        println!(
            "  skia (AA path strokes, one colour per strand): {draw:.3} s median of {} draws; {}",
            skia_cpu.len() + skia_gpu.len(),
            info.trim()
        );
        let per_round = |ours: &[f64], skia: &[f64]| {
            median(ours.iter().zip(skia).map(|(o, s)| o / s).collect())
        };
        let (sc, sg) = (median(skia_cpu.clone()), median(skia_gpu.clone()));
        println!(
            "  ratio ours (cpu backend) / skia draw: {:.2} (median over rounds; of the medians, \
             {ours:.3} s / {sc:.3} s, {:.2}; skia's Python path building not counted)",
            per_round(&t_cpu, &skia_cpu),
            ours / sc
        );
        if !t_gpu.is_empty() {
            let tg = median(t_gpu.clone());
            println!(
                "  ratio ours (lavapipe) / skia draw: {:.2} (median over rounds; of the medians, \
                 {tg:.3} s / {sg:.3} s, {:.2})",
                per_round(&t_gpu, &skia_gpu),
                tg / sg
            );
        }
        if let Some(tp) = pipeline {
            println!(
                "  ratio ours (lavapipe, render pipeline strands) / skia draw: {:.2}",
                tp / draw
            );
        }
    }
    if cpu_only {
        return;
    }
    growth(reps);
}

/// The growth rows: (name, strands, size).
fn growth_rows() -> [(String, usize, u32); 3] {
    [
        (format!("{STRANDS} strands, {SIZE}² (base)"), STRANDS, SIZE),
        (
            format!("{STRANDS} strands, {}² (4x pixels)", 2 * SIZE),
            STRANDS,
            2 * SIZE,
        ),
        (
            format!("{} strands, {SIZE}² (2x strands)", 2 * STRANDS),
            2 * STRANDS,
            SIZE,
        ),
    ]
}

/// Child process of [`growth`]: renders row `row` and prints "seconds peak_mib before_mib".
fn growth_child(row: usize, p: &RasterParams, reps: usize) {
    let (_, strands, size) = &growth_rows()[row];
    let s = hair(2013, *size, *strands);
    let (t, peak, before) = cpu_row(&s, *size, p, reps);
    println!("{t} {peak} {before}");
}

/// Time and peak memory of the cpu backend as pixels and strands grow, each row in a fresh
/// process (memory freed by earlier renders stays resident, which would hide a row's peak).
/// Lavapipe and skia are left out here: the ratios above are the comparison, these rows
/// show the scaling.
fn growth(reps: usize) {
    println!(
        "growth, cpu backend (median of {reps}; each row in its own process; peak = its RSS \
         high-water mark; input = RSS before the renders, the strands included):"
    );
    println!(
        "  {:<34} {:>8} {:>9} {:>10} {:>10} {:>12}",
        "row", "s", "x base", "peak MiB", "input MiB", "render MiB"
    );
    let mut base_s = f64::NAN;
    for (row, (name, _, _)) in growth_rows().iter().enumerate() {
        let out = std::env::current_exe()
            .and_then(|exe| {
                Command::new(exe)
                    .env("RASTER_BENCH_ROW", row.to_string())
                    .env("COIF_BENCH_REPS", reps.to_string())
                    .output()
            })
            .expect("re-running the bench for a growth row");
        let text = String::from_utf8_lossy(&out.stdout);
        let v: Vec<f64> = text
            .lines()
            .last()
            .unwrap_or("")
            .split_whitespace()
            .filter_map(|x| x.parse().ok())
            .collect();
        let [t, peak, before] = v[..] else {
            println!(
                "  {name:<34} failed: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            continue;
        };
        if base_s.is_nan() {
            base_s = t;
        }
        println!(
            "  {name:<34} {t:>8.3} {:>8.2}x {peak:>10.0} {before:>10.0} {:>12.0}",
            t / base_s,
            peak - before
        );
    }
}
