//! Shards: job k (from 0, in manifest order) belongs to shard k mod N, so N machines split a
//! manifest with no coordinator. Shard indices are 0-based: `--shard 0/4` .. `--shard 3/4`.

use crate::error::Error;

/// Shard `index` of `count` (0 <= index < count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// The whole manifest.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    pub fn new(index: usize, count: usize, what: &str) -> crate::Result<Shard> {
        if count == 0 {
            return Err(Error::Invalid(format!(
                "{what}: the shard count must be at least 1"
            )));
        }
        if index >= count {
            return Err(Error::Invalid(format!(
                "{what}: shard index {index} is not below the count {count} (indices are 0-based: 0..{})",
                count - 1
            )));
        }
        Ok(Shard { index, count })
    }

    /// Whether the job at `position` (0-based, manifest order) is in this shard.
    pub fn contains(&self, position: usize) -> bool {
        position % self.count == self.index
    }

    /// `--shard I/N`.
    pub fn parse(s: &str) -> crate::Result<Shard> {
        let bad = || Error::Invalid(format!("--shard: expected I/N (0 <= I < N), got {s:?}"));
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let i = i.trim().parse().map_err(|_| bad())?;
        let n = n.trim().parse().map_err(|_| bad())?;
        Shard::new(i, n, "--shard")
    }

    /// The shard an array job gives through its environment, read with `get`:
    /// Slurm's SLURM_ARRAY_TASK_ID less SLURM_ARRAY_TASK_MIN (0 when unset), of
    /// SLURM_ARRAY_TASK_COUNT (else MAX - MIN + 1); else Kubernetes' JOB_COMPLETION_INDEX of
    /// COIF_SHARDS. None when neither is set.
    pub fn from_env(get: impl Fn(&str) -> Option<String>) -> crate::Result<Option<Shard>> {
        let num = |k: &str| -> crate::Result<Option<usize>> {
            match get(k) {
                None => Ok(None),
                Some(v) => v.trim().parse().map(Some).map_err(|_| {
                    Error::Invalid(format!("{k}={v:?} is not a non-negative integer"))
                }),
            }
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let count = match (num("SLURM_ARRAY_TASK_COUNT")?, num("SLURM_ARRAY_TASK_MAX")?) {
                (Some(c), _) => c,
                (None, Some(max)) if max >= min => max - min + 1,
                (None, Some(max)) => {
                    return Err(Error::Invalid(format!(
                        "SLURM_ARRAY_TASK_MAX={max} is below SLURM_ARRAY_TASK_MIN={min}"
                    )))
                }
                (None, None) => {
                    return Err(Error::Invalid(
                        "SLURM_ARRAY_TASK_ID is set but neither SLURM_ARRAY_TASK_COUNT nor \
                         SLURM_ARRAY_TASK_MAX: give --shard I/N"
                            .into(),
                    ))
                }
            };
            if id < min {
                return Err(Error::Invalid(format!(
                    "SLURM_ARRAY_TASK_ID={id} is below SLURM_ARRAY_TASK_MIN={min}"
                )));
            }
            return Shard::new(
                id - min,
                count,
                "SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT",
            )
            .map(Some);
        }
        if let Some(i) = num("JOB_COMPLETION_INDEX")? {
            let n = num("COIF_SHARDS")?.ok_or_else(|| {
                Error::Invalid(
                    "JOB_COMPLETION_INDEX is set but COIF_SHARDS (the Job's completions) is not"
                        .into(),
                )
            })?;
            return Shard::new(i, n, "JOB_COMPLETION_INDEX/COIF_SHARDS").map(Some);
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn parse_and_membership() {
        let s = Shard::parse("1/3").unwrap();
        assert_eq!(s, Shard { index: 1, count: 3 });
        let mine: Vec<usize> = (0..8).filter(|&k| s.contains(k)).collect();
        assert_eq!(mine, [1, 4, 7]);
        for bad in ["3/3", "1/0", "x/2", "2", "-1/2", "1/2/3"] {
            assert!(Shard::parse(bad).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn every_job_in_exactly_one_shard() {
        for n in 1..6 {
            for k in 0..20 {
                let owners = (0..n).filter(|&i| Shard { index: i, count: n }.contains(k));
                assert_eq!(owners.count(), 1);
            }
        }
    }

    #[test]
    fn environments() {
        assert_eq!(Shard::from_env(env(&[])).unwrap(), None);
        let slurm = [
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
        ];
        assert_eq!(
            Shard::from_env(env(&slurm)).unwrap(),
            Some(Shard { index: 5, count: 8 })
        );
        let one_based = [
            ("SLURM_ARRAY_TASK_ID", "1"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "4"),
        ];
        assert_eq!(
            Shard::from_env(env(&one_based)).unwrap(),
            Some(Shard { index: 0, count: 4 })
        );
        let k8s = [("JOB_COMPLETION_INDEX", "2"), ("COIF_SHARDS", "3")];
        assert_eq!(
            Shard::from_env(env(&k8s)).unwrap(),
            Some(Shard { index: 2, count: 3 })
        );
        for bad in [
            &[
                ("SLURM_ARRAY_TASK_ID", "8"),
                ("SLURM_ARRAY_TASK_COUNT", "8"),
            ][..],
            &[("SLURM_ARRAY_TASK_ID", "3")][..],
            &[
                ("SLURM_ARRAY_TASK_ID", "0"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_MAX", "4"),
            ][..],
            &[
                ("SLURM_ARRAY_TASK_ID", "x"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ][..],
            &[("JOB_COMPLETION_INDEX", "0")][..],
            &[("JOB_COMPLETION_INDEX", "3"), ("COIF_SHARDS", "3")][..],
        ] {
            let e = Shard::from_env(env(bad)).unwrap_err();
            assert_eq!(e.exit_code(), 64, "{bad:?}: {e}");
        }
    }
}
