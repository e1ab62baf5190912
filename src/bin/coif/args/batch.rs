//! `coif batch`: the jobs of a manifest, one shard of them, with `--resume` and `--jobs`.

use super::{BackendArgs, Request};
use clap::Args;
use coif::batch::{BatchOptions, Shard};
use std::num::NonZeroUsize;
use std::path::PathBuf;

#[derive(Args)]
pub struct BatchArgs {
    /// The manifest: one JSON job per line (blank and `#` lines skipped); paths relative to
    /// its folder.
    manifest: PathBuf,
    /// Run shard I of N (0-based: 0 <= I < N): job k in manifest order is in shard k mod N.
    /// Default: SLURM_ARRAY_TASK_ID (less SLURM_ARRAY_TASK_MIN) of SLURM_ARRAY_TASK_COUNT,
    /// else JOB_COMPLETION_INDEX of COIF_SHARDS, else every job.
    #[arg(long, value_parser = parse_shard)]
    shard: Option<Shard>,
    /// Skip the jobs whose record (.coif-job.json in their out folder) matches: same coif
    /// version, parameters and input hashes.
    #[arg(long)]
    resume: bool,
    /// The summary file (default <manifest>.summary.json, or
    /// <manifest>.shard-I-of-N.summary.json for a shard).
    #[arg(long)]
    summary: Option<PathBuf>,
    /// Run up to N jobs at once (N >= 1), started in manifest order, each on a worker thread
    /// of its own, all sharing the CPU threads: one job's serial stages overlap another's
    /// parallel work. The memory budget (--max-memory, else the machine's) is divided by the
    /// jobs run at once. With more than one at once a job's peak memory in the summary is the
    /// process's, and the ok/failed lines come in completion order (the summary stays in
    /// manifest order). 1 runs the jobs in turn.
    #[arg(long, value_name = "N", default_value = "2", value_parser = parse_jobs)]
    jobs: NonZeroUsize,
    #[command(flatten)]
    backend: BackendArgs,
}

fn parse_jobs(s: &str) -> Result<NonZeroUsize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) => NonZeroUsize::new(n)
            .ok_or_else(|| "expected at least 1 job at once (1 runs the jobs in turn)".into()),
        Err(_) => Err(format!(
            "expected a whole number of jobs to run at once (1 or more), got {s:?}"
        )),
    }
}

fn parse_shard(s: &str) -> Result<Shard, String> {
    Shard::parse(s).map_err(|e| e.to_string())
}

impl BatchArgs {
    pub fn request(self) -> Request {
        Request::Batch(BatchOptions {
            manifest: self.manifest,
            shard: self.shard,
            resume: self.resume,
            summary: self.summary,
            backend: self.backend.backend,
            // Set from the global --max-memory by main.
            max_memory: None,
            jobs: self.jobs,
        })
    }
}
