//! Runs one shard of a manifest: each job's steps in order, up to `--jobs` jobs at once on
//! worker threads, a failing job recorded and the rest carrying on, records for `--resume`,
//! and the summary file.

use super::manifest::{self, BatchJob};
use super::record::Record;
use super::shard::Shard;
use super::timings::BatchTimings;
use crate::error::Error;
use crate::gpu::engine::{BackendChoice, Engine};
use crate::timings::{GpuTime, PeakScope, RunTimings};
use anyhow::Context;
use serde::Serialize;
use serde_json::json;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

/// What `coif batch` was asked.
#[derive(Clone, Debug)]
pub struct BatchOptions {
    pub manifest: PathBuf,
    /// `--shard`; None: from the environment ([`Shard::from_env`]), else the whole manifest.
    pub shard: Option<Shard>,
    pub resume: bool,
    /// None: `<manifest>.summary.json`, or `<manifest>.shard-I-of-N.summary.json`.
    pub summary: Option<PathBuf>,
    pub backend: BackendChoice,
    /// `--max-memory`; None: the machine's ([`crate::base::budget::Budget::machine`]).
    pub max_memory: Option<crate::base::budget::Budget>,
    /// `--jobs`: jobs run at once, each on a worker thread and an engine of its own with
    /// the memory budget divided between them.
    pub jobs: NonZeroUsize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Ok,
    /// `--resume` found a matching record.
    Skipped,
    Failed,
    /// SIGINT/SIGTERM stopped it at a stage boundary; its folder is as it was.
    Interrupted,
    /// Not started: the batch was interrupted before it.
    #[serde(rename = "not-run")]
    NotRun,
}

/// One job's outcome, as the summary lists it.
#[derive(Clone, Debug, Serialize)]
pub struct JobOutcome {
    pub id: String,
    pub line: usize,
    pub status: Status,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exit_code: Option<i32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
    pub seconds: f64,
    /// Stages, GPU time and peak memory of a job that ran (not of a skipped one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub timings: Option<serde_json::Value>,
}

#[derive(Clone, Debug)]
pub struct Summary {
    pub path: PathBuf,
    pub shard: Shard,
    pub jobs: Vec<JobOutcome>,
    /// The signal that interrupted the batch, if one did.
    pub interrupted: Option<i32>,
    /// 0 when every job succeeded or was skipped; 128 + the signal when interrupted; else
    /// the first failing job's exit code.
    pub exit_code: i32,
}

impl Summary {
    pub fn count(&self, s: Status) -> usize {
        self.jobs.iter().filter(|j| j.status == s).count()
    }
}

/// The exit code of an error as the command line computes it: the first coif error in its
/// chain, else 1.
pub fn exit_code(e: &anyhow::Error) -> i32 {
    e.chain()
        .find_map(|c| c.downcast_ref::<Error>())
        .map_or(1, Error::exit_code)
}

fn default_summary(manifest: &Path, shard: Shard) -> PathBuf {
    let mut name = manifest.file_name().unwrap_or_default().to_os_string();
    if shard.count > 1 {
        name.push(format!(".shard-{}-of-{}", shard.index, shard.count));
    }
    name.push(".summary.json");
    manifest.with_file_name(name)
}

/// Reads and checks the whole manifest, then runs the shard's jobs. Errors are those of the
/// manifest, the shard or the summary file; a failing job is in the summary instead.
/// With `timings`, also writes the batch's timings file there (stages totalled over the
/// completed jobs).
pub fn run(opts: &BatchOptions, timings: Option<&Path>) -> anyhow::Result<Summary> {
    let jobs = manifest::load(&opts.manifest)?;
    let shard = match opts.shard {
        Some(s) => s,
        None => Shard::from_env(|k| std::env::var(k).ok())?.unwrap_or(Shard::ALL),
    };
    let path = match &opts.summary {
        Some(p) => p.clone(),
        // Beside /dev/stdin or /dev/fd/63 is no place for a file.
        None if !manifest::is_regular(&opts.manifest) => {
            return Err(Error::Invalid(format!(
                "{}: the manifest is not a regular file (a pipe?), so the summary has no \
                 folder to go beside it: give --summary FILE",
                opts.manifest.display()
            ))
            .into())
        }
        None => default_summary(&opts.manifest, shard),
    };
    let mine: Vec<&BatchJob> = jobs
        .iter()
        .enumerate()
        .filter(|(k, _)| shard.contains(*k))
        .map(|(_, j)| j)
        .collect();
    let t0 = Instant::now();
    // Never more workers than jobs: a lone worker keeps the per-job peak memory and the
    // whole budget.
    let workers = opts.jobs.get().min(mine.len()).max(1);
    let engines = engines(opts, workers)?;
    let engine = &engines[0];
    let bar = indicatif::ProgressBar::new(mine.len() as u64).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
            .expect("static template"),
    );
    let mut slots: Vec<Option<(JobOutcome, Option<RunTimings>)>> = vec![None; mine.len()];
    let next = AtomicUsize::new(0);
    std::thread::scope(|s| -> anyhow::Result<()> {
        let (tx, rx) = mpsc::channel::<Event>();
        for (w, engine) in engines.iter().enumerate() {
            let (tx, next, mine) = (tx.clone(), &next, &mine);
            // Each job runs on a worker thread of its own so that the thread-local stage
            // collection ([`crate::timings::collect`]) holds that job's stages only.
            std::thread::Builder::new()
                .name(format!("coif-batch-{w}"))
                // The main thread's usual 8 MiB, where the jobs ran before, not a spawned
                // thread's 2 MiB.
                .stack_size(8 << 20)
                .spawn_scoped(s, move || loop {
                    // A job boundary: after a signal no job starts; the rest are not run.
                    if crate::interrupt::pending().is_some() {
                        break;
                    }
                    // Taken in manifest order, so jobs start in that order.
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(job) = mine.get(k) else { break };
                    if tx.send(Event::Started(k)).is_err() {
                        break;
                    }
                    let done = run_one(engine, job, opts.resume, workers == 1);
                    if tx.send(Event::Done(k, Box::new(done))).is_err() {
                        break;
                    }
                })
                .context("cannot start a batch worker thread")?;
        }
        drop(tx);
        // Only this thread prints, so lines never interleave; they come in completion order.
        let mut running: Vec<usize> = Vec::new();
        for ev in rx {
            match ev {
                Event::Started(k) => running.push(k),
                Event::Done(k, done) => {
                    running.retain(|&r| r != k);
                    let (o, warnings, jt) = *done;
                    report(&bar, &o, &warnings);
                    slots[k] = Some((o, jt));
                    bar.inc(1);
                }
            }
            let ids: Vec<&str> = running.iter().map(|&r| mine[r].id()).collect();
            bar.set_message(ids.join(" "));
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    // In manifest order; a job that never started was stopped by a signal.
    let mut outcomes = Vec::with_capacity(mine.len());
    let mut done: Vec<RunTimings> = Vec::new();
    for (job, slot) in mine.iter().zip(slots) {
        match slot {
            Some((o, jt)) => {
                if let (Status::Ok, Some(jt)) = (o.status, jt) {
                    done.push(jt);
                }
                outcomes.push(o);
            }
            None => outcomes.push(JobOutcome {
                id: job.id().to_string(),
                line: job.line,
                status: Status::NotRun,
                exit_code: None,
                message: None,
                seconds: 0.0,
                timings: None,
            }),
        }
    }
    let interrupted = crate::interrupt::pending();
    let exit_code = match interrupted {
        Some(sig) => 128 + sig,
        None => outcomes.iter().find_map(|o| o.exit_code).unwrap_or(0),
    };
    let done: Vec<&RunTimings> = done.iter().collect();
    let agg = BatchTimings::of(&done);
    let summary = Summary {
        path,
        shard,
        jobs: outcomes,
        interrupted,
        exit_code,
    };
    let doc = json!({
        "coif_version": env!("CARGO_PKG_VERSION"),
        "manifest": opts.manifest,
        "shard": {"index": shard.index, "count": shard.count,
                  "rule": "job k (from 0, in manifest order) is in shard k mod count"},
        "resume": opts.resume,
        "backend": engine.describe(),
        "jobs_at_once": workers,
        "jobs_in_manifest": jobs.len(),
        "counts": {
            "jobs": summary.jobs.len(),
            "ok": summary.count(Status::Ok),
            "skipped": summary.count(Status::Skipped),
            "failed": summary.count(Status::Failed),
            "interrupted": summary.count(Status::Interrupted),
            "not_run": summary.count(Status::NotRun),
        },
        "interrupted": interrupted.map(crate::interrupt::name),
        "exit_code": exit_code,
        "seconds": t0.elapsed().as_secs_f64(),
        "timings": agg,
        "jobs": summary.jobs,
    });
    if let Some(d) = summary.path.parent().filter(|d| !d.as_os_str().is_empty()) {
        crate::io::ensure_dir(d)?;
    }
    crate::io::write_json(&summary.path, &doc)?;
    if let Some(p) = timings {
        let t = RunTimings {
            wall_seconds: t0.elapsed().as_secs_f64(),
            stages: agg.stage_totals(),
            gpu: match super::timings::pass_totals(&done) {
                Some(p) => GpuTime::Measured(p),
                None => GpuTime::take(engine),
            },
            peak_rss_bytes: done
                .iter()
                .filter_map(|t| t.peak_rss_bytes)
                .chain(crate::timings::peak_rss_bytes())
                .max(),
            peak_rss_scope: PeakScope::Process,
        };
        crate::timings::write(p, "batch", engine, &t)?;
    }
    Ok(summary)
}

thread_local! {
    /// The id of the job this thread is running, for log lines to name it.
    static CURRENT: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
}

/// The id of the batch job running on this thread, if any: with jobs at once a log line
/// (a segmentation warning, say) would otherwise not say which job it is about.
pub fn current_job() -> Option<String> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Sets this thread's job id until dropped.
struct CurrentJob;

impl CurrentJob {
    fn set(id: &str) -> CurrentJob {
        CURRENT.with(|c| *c.borrow_mut() = Some(id.to_string()));
        CurrentJob
    }
}

impl Drop for CurrentJob {
    fn drop(&mut self) {
        CURRENT.with(|c| *c.borrow_mut() = None);
    }
}

/// What a worker tells the thread that prints: job k (in the shard's order) started, or
/// ended with its outcome, warnings and timings.
enum Event {
    Started(usize),
    Done(usize, Box<(JobOutcome, Vec<String>, Option<RunTimings>)>),
}

/// An engine per worker: a job's GPU pass times ([`GpuTime::take`]) are then its own (on the
/// GPU backend each worker opens its own device), and each holds its share of the memory
/// budget so that the jobs running at once stay within it together.
fn engines(opts: &BatchOptions, workers: usize) -> anyhow::Result<Vec<Engine>> {
    let budget = opts
        .max_memory
        .clone()
        .unwrap_or_else(crate::base::budget::Budget::machine);
    let share = match workers {
        1 => budget,
        n => crate::base::budget::Budget::new(
            budget.bytes / n as u64,
            format!(
                "{} divided by --jobs {n}: fewer jobs at once give each more",
                budget.source
            ),
        ),
    };
    (0..workers)
        .map(|_| {
            let mut e = Engine::new(opts.backend)?;
            e.set_budget(share.clone());
            // Every job's GPU passes are timed where the adapter can (for the summary).
            e.gpu().map(|g| g.time_passes());
            Ok(e)
        })
        .collect()
}

/// Runs one job and times it: its outcome, its warnings, and its timings when it ran (not
/// when skipped). `own_peak`: no other job runs meanwhile, so the peak memory may be reset
/// and reported as the job's; otherwise it is the process's.
fn run_one(
    engine: &Engine,
    job: &BatchJob,
    resume: bool,
    own_peak: bool,
) -> (JobOutcome, Vec<String>, Option<RunTimings>) {
    let _current = CurrentJob::set(job.id());
    let t = Instant::now();
    let scope = match own_peak && crate::timings::reset_peak_rss() {
        true => PeakScope::Job,
        false => PeakScope::Process,
    };
    let ((result, stages), wall) = (
        crate::timings::collect(|| run_job(engine, job, resume)),
        t.elapsed().as_secs_f64(),
    );
    let ran = !matches!(result, Ok((true, _)));
    let jt = ran.then(|| RunTimings {
        wall_seconds: wall,
        stages,
        gpu: GpuTime::take(engine),
        peak_rss_bytes: crate::timings::peak_rss_bytes(),
        peak_rss_scope: scope,
    });
    let (status, err, warnings) = match result {
        Ok((skipped, warnings)) => (
            if skipped { Status::Skipped } else { Status::Ok },
            None,
            warnings,
        ),
        Err(e) if is_interrupt(&e) => (Status::Interrupted, Some(e), Vec::new()),
        Err(e) => (Status::Failed, Some(e), Vec::new()),
    };
    let o = JobOutcome {
        id: job.id().to_string(),
        line: job.line,
        status,
        exit_code: err.as_ref().map(exit_code),
        // A later step reads an earlier step's files in the job's temporary folder, and an
        // error there names it: the user knows the job's folder.
        message: err.as_ref().map(|e| {
            let out = job.out();
            let tmp = crate::io::txn::tmp_path(&out);
            format!("{e:#}").replace(&*tmp.to_string_lossy(), &out.to_string_lossy())
        }),
        seconds: wall,
        timings: jt.as_ref().map(RunTimings::to_json),
    };
    (o, warnings, jt)
}

/// Prints a finished job's warnings (named by the job) and its line.
fn report(bar: &indicatif::ProgressBar, o: &JobOutcome, warnings: &[String]) {
    bar.suspend(|| {
        for w in warnings {
            eprintln!("coif: warning: {}: {w}", o.id);
        }
        match (&o.status, &o.message) {
            (Status::Failed, Some(m)) => {
                println!("failed  {} (exit {}): {m}", o.id, o.exit_code.unwrap_or(1))
            }
            (Status::Skipped, _) => println!("skipped {} (record matches)", o.id),
            (Status::Interrupted, _) => println!("stopped {} (interrupted)", o.id),
            _ => println!("ok      {} in {:.1} s", o.id, o.seconds),
        }
    });
}

fn is_interrupt(e: &anyhow::Error) -> bool {
    e.chain()
        .any(|c| matches!(c.downcast_ref::<Error>(), Some(Error::Interrupted(_))))
}

/// Runs a job's steps; Ok(true) when `--resume` skipped it. Returns the steps' warnings. The
/// steps and the record are written into a temporary folder put in place of `out` when all
/// are done: a job that fails or is interrupted leaves its folder (and its old record) as
/// they were.
fn run_job(engine: &Engine, job: &BatchJob, resume: bool) -> anyhow::Result<(bool, Vec<String>)> {
    let record = Record::of(job)?;
    if resume && Record::read(job).as_ref() == Some(&record) {
        return Ok((true, Vec::new()));
    }
    let out = job.out();
    let txn = crate::io::txn::Txn::begin(&out)?;
    let tmp = txn.dir().to_path_buf();
    let mut warnings = Vec::new();
    // Labels and messages name the real folder, not the temporary one; each step's stages
    // under its command's name.
    for (shown, j) in job.jobs().iter().zip(job.jobs_into(&tmp)) {
        let (r, stages) = crate::timings::collect(|| crate::jobs::run(engine, &j));
        crate::timings::record_prefixed(j.command(), &stages);
        let r = r.with_context(|| shown.label())?;
        warnings.extend(r.relabel(&tmp, &out).warnings);
    }
    record.write_in(&tmp)?;
    crate::interrupt::check()?;
    txn.commit()?;
    Ok((false, warnings))
}
