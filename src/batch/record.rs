//! The record a completed job leaves in its out folder (`.coif-job.json`): the coif version,
//! the job's normalised manifest line and the SHA-256 of each input file. `--resume` skips
//! a job exactly when the record on disk equals the one its inputs give now.

use super::manifest::BatchJob;
use crate::error::Error;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

/// File name of the record inside a job's out folder.
pub const RECORD: &str = ".coif-job.json";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Record {
    pub coif_version: String,
    /// The manifest line, parsed and serialised again (keys in a fixed order, paths as
    /// written).
    pub params: serde_json::Value,
    /// SHA-256 (hex) of each input file, by manifest key.
    pub inputs: BTreeMap<String, String>,
}

impl Record {
    /// The record `job` would leave now: reads and hashes its inputs.
    pub fn of(job: &BatchJob) -> crate::Result<Record> {
        let params = serde_json::to_value(&job.entry)
            .map_err(|e| Error::Invalid(format!("job {}: {e}", job.id())))?;
        let inputs = job
            .inputs()
            .into_iter()
            .map(|(k, p)| {
                refuse_stream(k, &p)?;
                Ok((k.to_string(), sha256_file(&p)?))
            })
            .collect::<crate::Result<_>>()?;
        Ok(Record {
            coif_version: env!("CARGO_PKG_VERSION").to_string(),
            params,
            inputs,
        })
    }

    pub fn path(job: &BatchJob) -> PathBuf {
        job.out().join(RECORD)
    }

    /// The record on disk, if there is a readable one (an unreadable one does not match).
    pub fn read(job: &BatchJob) -> Option<Record> {
        let text = std::fs::read_to_string(Record::path(job)).ok()?;
        serde_json::from_str(&text).ok()
    }

    /// Writes the record into `dir`, the job's temporary folder: it is put in place with the
    /// job's files, all together or not at all.
    pub fn write_in(&self, dir: &Path) -> crate::Result<()> {
        let v = serde_json::to_value(self).map_err(|e| Error::Invalid(e.to_string()))?;
        crate::io::write_json(&dir.join(RECORD), &v)
    }
}

/// A job's input is hashed here and read again by each step, so a pipe or device (which
/// reads once) would reach the steps empty: refused with a message naming it. Missing files
/// are left to the hash, which names them.
fn refuse_stream(key: &str, path: &Path) -> crate::Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() && !m.is_dir() => Err(Error::bad_file(
            path,
            format!(
                "key `{key}`: not a regular file (a pipe or device); a batch job's inputs are \
                 hashed for its record and read by every step, so they must be files that can \
                 be read more than once"
            ),
        )),
        _ => Ok(()),
    }
}

/// SHA-256 of a file's bytes, lower-case hex.
pub fn sha256_file(path: &Path) -> crate::Result<String> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    #[test]
    fn sha256_of_a_known_string() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("abc");
        std::fs::write(&p, b"abc").unwrap();
        assert_eq!(
            super::sha256_file(&p).unwrap(),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
