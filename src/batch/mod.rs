//! `coif batch`: jobs from a manifest (`jobs.jsonl`), one shard of them, a record per
//! completed job for `--resume`, and a summary of every job's outcome.

pub mod manifest;
pub mod record;
pub mod run;
pub mod shard;
pub mod timings;

pub use manifest::{BatchJob, Entry, Step};
pub use run::{current_job, run, BatchOptions, JobOutcome, Status, Summary};
pub use shard::Shard;

#[cfg(test)]
mod schema_tests;
