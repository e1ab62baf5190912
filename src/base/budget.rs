//! The memory budget a run may use, and the check that refuses work estimated to exceed it
//! before anything is allocated or written (an allocation failure aborts the process with
//! no message, and an OOM kill leaves half-written outputs).

use crate::error::{Error, Result};
use std::fmt;

/// Bytes a run may use and where that figure came from (named in every refusal).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Budget {
    pub bytes: u64,
    pub source: String,
}

/// What sizes an estimate: an option the user can lower, or an input file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cause {
    Option,
    Input,
}

impl Budget {
    pub fn new(bytes: u64, source: impl Into<String>) -> Self {
        Budget {
            bytes,
            source: source.into(),
        }
    }

    /// From `--max-memory SIZE`.
    pub fn from_option(s: &str) -> std::result::Result<Self, String> {
        parse_size(s).map(|b| Budget::new(b, "--max-memory"))
    }

    /// The machine's: the smallest of the cgroup's memory limit, the address-space limit
    /// (`ulimit -v`) and MemAvailable; with none readable, unlimited.
    pub fn machine() -> Self {
        let mut best: Option<Budget> = None;
        let mut take = |b: Option<Budget>| {
            if let Some(b) = b {
                if best.as_ref().is_none_or(|x| b.bytes < x.bytes) {
                    best = Some(b);
                }
            }
        };
        take(cgroup_limit());
        take(rlimit_as());
        take(mem_available());
        best.unwrap_or_else(|| Budget::new(u64::MAX, "no limit found"))
    }

    /// Refuses `needed` bytes over the budget: `what` names the option or input that sizes
    /// the allocation and `detail` how the estimate is made up.
    pub fn check(&self, cause: Cause, what: &str, needed: u64, detail: &str) -> Result<()> {
        if needed <= self.bytes {
            return Ok(());
        }
        Err(Error::OverBudget {
            cause,
            msg: format!(
                "{what} needs an estimated {}{}, over the memory budget of {} ({}); {}",
                Bytes(needed),
                if detail.is_empty() {
                    String::new()
                } else {
                    format!(" ({detail})")
                },
                Bytes(self.bytes),
                self.source,
                match cause {
                    Cause::Option => "lower the option or raise --max-memory",
                    Cause::Input => "use a smaller input or raise --max-memory",
                }
            ),
        })
    }
}

/// `4G`, `512M`, `1.5G`, `800K`, `1073741824`: K, M, G and T are powers of 1024 (as Slurm's
/// `--mem` and docker's `--memory` read them); an optional `B`, `iB` or `b` may follow.
pub fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let unit = unit.trim().to_ascii_uppercase();
    let unit = unit
        .strip_suffix("IB")
        .or_else(|| unit.strip_suffix('B'))
        .unwrap_or(&unit);
    let shift = match unit {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("expected a size like 4G or 512M, got {s:?}")),
    };
    let v: f64 = num
        .parse()
        .map_err(|_| format!("expected a size like 4G or 512M, got {s:?}"))?;
    let bytes = v * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("size {s:?} is not a positive number of bytes"));
    }
    Ok(bytes as u64)
}

/// A byte count as people read it: "1.5 GiB", "300 MiB", "12 KiB", "100 B".
pub struct Bytes(pub u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = self.0 as f64;
        for (shift, unit) in [(40, "TiB"), (30, "GiB"), (20, "MiB"), (10, "KiB")] {
            let u = (1u64 << shift) as f64;
            if b >= u {
                return write!(f, "{:.1} {unit}", b / u);
            }
        }
        write!(f, "{} B", self.0)
    }
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

/// cgroup v2 `memory.max` of this process's group, else cgroup v1's `memory.limit_in_bytes`;
/// "max" and v1's near-2^63 "no limit" count as none.
fn cgroup_limit() -> Option<Budget> {
    let cg = read("/proc/self/cgroup")?;
    let mut candidates = Vec::new();
    for line in cg.lines() {
        let mut parts = line.splitn(3, ':');
        let (_, ctrl, path) = (parts.next()?, parts.next()?, parts.next()?);
        if ctrl.is_empty() {
            candidates.push(format!("/sys/fs/cgroup{path}/memory.max"));
            candidates.push("/sys/fs/cgroup/memory.max".to_string());
        } else if ctrl.split(',').any(|c| c == "memory") {
            candidates.push(format!("/sys/fs/cgroup/memory{path}/memory.limit_in_bytes"));
            candidates.push("/sys/fs/cgroup/memory/memory.limit_in_bytes".to_string());
        }
    }
    candidates.into_iter().find_map(|p| {
        let v: u64 = read(&p)?.trim().parse().ok()?;
        (v < 1 << 60).then(|| Budget::new(v, format!("the cgroup limit in {p}")))
    })
}

/// The address-space limit (`ulimit -v`): allocations past it fail and abort the process.
fn rlimit_as() -> Option<Budget> {
    let limits = read("/proc/self/limits")?;
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    let soft = line.split_whitespace().nth(3)?;
    let v: u64 = soft.parse().ok()?;
    Some(Budget::new(
        v,
        "the address-space limit (ulimit -v) in /proc/self/limits",
    ))
}

fn mem_available() -> Option<Budget> {
    let info = read("/proc/meminfo")?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(Budget::new(kb * 1024, "MemAvailable in /proc/meminfo"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_powers_of_1024() {
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("512mib"), Ok(512 << 20));
        assert_eq!(parse_size("1.5G"), Ok(3 << 29));
        assert_eq!(parse_size("800K"), Ok(800 << 10));
        assert_eq!(parse_size("1000"), Ok(1000));
        for bad in ["", "G", "4X", "-1G", "0", "1e400"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn check_names_the_cause_estimate_and_budget() {
        let b = Budget::new(1 << 30, "--max-memory");
        assert!(b.check(Cause::Option, "--cells 80", 1 << 30, "").is_ok());
        let e = b
            .check(Cause::Option, "--cells 100000", 3 << 30, "cells")
            .unwrap_err();
        assert_eq!(e.exit_code(), 64);
        let m = e.to_string();
        assert!(
            m.contains("--cells 100000")
                && m.contains("3.0 GiB")
                && m.contains("1.0 GiB (--max-memory)"),
            "{m}"
        );
        let e = b.check(Cause::Input, "big.png", 2 << 30, "").unwrap_err();
        assert_eq!(e.exit_code(), 65);
    }

    #[test]
    fn the_machine_budget_is_positive_and_says_where_it_came_from() {
        let b = Budget::machine();
        assert!(b.bytes > 0 && !b.source.is_empty(), "{b:?}");
    }
}
