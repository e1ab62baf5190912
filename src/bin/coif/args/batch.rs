//! `coif batch`: the jobs of a manifest, one shard of them, with `--resume`.

use super::{BackendArgs, Request};
use clap::Args;
use coif::batch::{BatchOptions, Shard};
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
    #[command(flatten)]
    backend: BackendArgs,
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
        })
    }
}
