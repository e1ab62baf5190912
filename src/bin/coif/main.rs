//! The `coif` command line: arguments in, jobs run, reports and errors out.

mod args;
mod cartoon_args;
mod sketch_edit_args;

use args::{Cli, Request};
use clap::Parser as _;
use coif::gpu::engine::Engine;
use coif::Error;
use std::io::Write;
use std::path::Path;

fn main() {
    // Headless Vulkan loaders print "XDG_RUNTIME_DIR is invalid" to stderr for every
    // instance; pointing it at the temp folder keeps batch logs clean. Single-threaded here.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none_or(|d| !Path::new(&d).is_dir()) {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            // --help and --version print to stdout and succeed; every other parse error is a
            // usage error, EX_USAGE as the README documents (clap's own exit code is 2).
            std::process::exit(if e.use_stderr() { 64 } else { 0 });
        }
    };
    let level = match cli.verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(level))
        .format(|buf, rec| {
            // env_logger's own layout, with the batch job a line comes from named: jobs run
            // at once (`coif batch --jobs`) would otherwise log anonymously.
            let style = buf.default_level_style(rec.level());
            let job = coif::batch::current_job()
                .map(|id| format!("{id}: "))
                .unwrap_or_default();
            writeln!(
                buf,
                "[{style}{:<5}{style:#} {}] {job}{}",
                rec.level(),
                rec.target(),
                rec.args()
            )
        })
        .init();
    // SIGINT/SIGTERM stop a run at its next stage boundary, its temporaries removed (exit
    // 130/143); without the handlers they would end it mid-write.
    if let Err(e) = coif::interrupt::install() {
        log::warn!("signal handlers not installed: {e}");
    }
    let (timings, budget) = (cli.timings, cli.max_memory);
    if let Err(e) = cli
        .cmd
        .request()
        .and_then(|req| run(req, timings.as_deref(), budget))
    {
        eprintln!("coif: error: {e:#}");
        let code = e
            .chain()
            .find_map(|c| c.downcast_ref::<Error>())
            .map_or(1, Error::exit_code);
        std::process::exit(code);
    }
}

fn run(
    req: Request,
    timings: Option<&Path>,
    budget: Option<coif::base::budget::Budget>,
) -> anyhow::Result<()> {
    if let Some(p) = timings {
        if matches!(req, Request::Info) {
            return Err(coif::Error::Invalid(
                "--timings is for the commands that run a pipeline, not `info`".into(),
            )
            .into());
        }
        coif::timings::check_path(p)?;
    }
    if let Request::Batch(mut opts) = req {
        opts.max_memory = budget;
        return batch(&opts, timings);
    }
    let Request::Jobs {
        jobs,
        backend,
        max_binding_bytes,
        banner,
    } = req
    else {
        return info();
    };
    let t0 = std::time::Instant::now();
    let (reports, stages) = coif::timings::collect(|| -> anyhow::Result<_> {
        let mut engine = {
            let _s = coif::timings::stage("engine");
            Engine::new(backend)?
        };
        if timings.is_some() {
            engine.gpu().map(|g| g.time_passes());
        }
        if let Some(b) = budget {
            engine.set_budget(b);
        }
        if let Some(b) = max_binding_bytes {
            engine.set_max_binding_bytes(b);
        }
        if let Some(b) = &banner {
            println!("{b} on {}", engine.describe());
        }
        // One job reports as it ends; several get a progress bar and report at the end.
        let reports = if jobs.len() == 1 {
            vec![coif::jobs::run(&engine, &jobs[0])?]
        } else {
            coif::jobs::run_all(&engine, &jobs)?
        };
        Ok((engine, reports))
    });
    let (engine, reports) = reports?;
    if let Some(p) = timings {
        let t = coif::timings::RunTimings {
            wall_seconds: t0.elapsed().as_secs_f64(),
            stages,
            gpu: coif::timings::GpuTime::take(&engine),
            peak_rss_bytes: coif::timings::peak_rss_bytes(),
            peak_rss_scope: coif::timings::PeakScope::Process,
        };
        // A list of jobs (`demo`) names its stages `<command>/<stage>`.
        let command = match jobs.as_slice() {
            [one] => one.command(),
            _ => "demo",
        };
        coif::timings::write(p, command, &engine, &t)?;
    }
    // Stage timings only for a single job: a list reads better as one line per job.
    let single = reports.len() == 1;
    // A closed pipe (`coif ... | head`) is not an error of the run: the files are written.
    let mut out = std::io::stdout().lock();
    for r in reports {
        for w in &r.warnings {
            eprintln!("coif: warning: {w}");
        }
        let _ = writeln!(out, "{}", r.summary);
        for d in r.details.iter().filter(|_| single) {
            let _ = writeln!(out, "  {d}");
        }
    }
    Ok(())
}

/// `coif batch`: exits with the first failing job's code after the summary is written.
fn batch(opts: &coif::batch::BatchOptions, timings: Option<&Path>) -> anyhow::Result<()> {
    use coif::batch::Status;
    let s = coif::batch::run(opts, timings)?;
    println!(
        "batch: shard {}/{}: {} jobs, {} ok, {} skipped, {} failed; summary {}",
        s.shard.index,
        s.shard.count,
        s.jobs.len(),
        s.count(Status::Ok),
        s.count(Status::Skipped),
        s.count(Status::Failed),
        s.path.display()
    );
    if let Some(sig) = s.interrupted {
        eprintln!(
            "coif: batch interrupted by {}: {} job(s) stopped, {} not run; run it again with \
             --resume to complete them",
            coif::interrupt::name(sig),
            s.count(Status::Interrupted),
            s.count(Status::NotRun)
        );
    }
    if s.exit_code != 0 {
        let _ = std::io::stdout().flush();
        std::process::exit(s.exit_code);
    }
    Ok(())
}

fn info() -> anyhow::Result<()> {
    let adapters = coif::gpu::list_adapters();
    println!("coif {}", env!("CARGO_PKG_VERSION"));
    println!("CPU threads: {}", rayon::current_num_threads());
    if adapters.is_empty() {
        println!(
            "GPU adapters: none (install mesa-vulkan-drivers for lavapipe, or use --backend cpu)"
        );
    } else {
        println!("GPU adapters:");
        for i in &adapters {
            println!("  {}", coif::gpu::describe(i));
        }
    }
    let auto = if coif::gpu::hardware_gpu_present() {
        "gpu (a hardware adapter is present)"
    } else {
        "cpu (no hardware adapter; lavapipe is used only with --backend gpu)"
    };
    println!("--backend auto chooses: {auto}");
    if !adapters.is_empty() {
        match coif::gpu::GpuContext::new() {
            Ok(g) => {
                println!("--backend gpu opens: {}", coif::gpu::describe(&g.info));
                println!(
                    "  max storage binding {} B, max buffer {} B, max workgroups per dimension {}",
                    g.limits.max_storage_buffer_binding_size,
                    g.limits.max_buffer_size,
                    g.limits.max_compute_workgroups_per_dimension
                );
                println!(
                    "  timestamp queries: {} (GPU time per pass in --timings)",
                    if g.has_timestamps() { "yes" } else { "no" }
                );
            }
            Err(e) => println!("--backend gpu fails: {e}"),
        }
    }
    Ok(())
}
