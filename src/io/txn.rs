//! All-or-nothing output folders. A command that writes a folder `out` writes into a
//! temporary folder beside it, `.<name>.coif-tmp-<pid>` (same file system), and
//! [`Txn::commit`] puts it in place at the end: files of the old `out` that the run did not
//! write are hard-linked into the new folder first (a render saved in a model folder
//! survives; coif's own `.coif-*` files are not carried over), then the two are swapped in
//! one `renameat2(RENAME_EXCHANGE)` and the old one removed. A run that fails or is
//! interrupted removes its temporary folder and leaves `out` as it was. Per file,
//! [`super::write_atomic`] already never leaves a half-written file; this makes a run's files
//! one unit, so no `curves.json` of one run lies beside `strands.hair` of another.
//!
//! A lock file beside `out` (`.<name>.coif-lock`, flock) refuses a second run into the same
//! folder ([`Error::Busy`], exit 75). Temporaries of dead runs (folders with the tag above,
//! `write_atomic`'s `.coif-<pid>-*.tmp` files) are removed when a run into that folder starts.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What marks a temporary folder, followed by the pid of the run that made it.
pub const TMP_TAG: &str = ".coif-tmp-";
/// Suffix of the lock file beside an output folder.
pub const LOCK_TAG: &str = ".coif-lock";

/// Temporary folders this process is writing (a pid alone cannot tell: in a container each
/// run may get the same pid).
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live_insert(p: &Path) {
    LIVE.lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(p.into());
}

fn live_remove(p: &Path) {
    LIVE.lock()
        .unwrap_or_else(|e| e.into_inner())
        .retain(|q| q != p);
}

/// Held while a run makes `out`'s parents and takes its lock, and while a run that did not
/// commit removes the parents it made: with batch jobs at once in one process, a failing
/// job could otherwise remove an empty parent just after another job made sure of it and
/// before its lock file lies there.
static PARENTS: Mutex<()> = Mutex::new(());

#[cfg(test)]
thread_local! {
    /// A pause (ms) between making sure of the parent and taking the lock, set by a test on
    /// its thread to hold that window open.
    static PAUSE_BEFORE_LOCK: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

fn is_live(p: &Path) -> bool {
    LIVE.lock()
        .unwrap_or_else(|e| e.into_inner())
        .iter()
        .any(|q| q == p)
}

/// One run's output folder, written in a temporary folder until [`Txn::commit`].
#[derive(Debug)]
pub struct Txn {
    out: PathBuf,
    tmp: PathBuf,
    /// Folders created for `out`'s parent, deepest last: removed again (when empty) by a run
    /// that does not commit.
    created: Vec<PathBuf>,
    lock: Option<Lock>,
    done: bool,
}

fn parent_of(p: &Path) -> &Path {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Refuses an output folder that exists as something other than a folder (an input file,
/// say), before any work (64).
pub fn require_folder_or_absent(out: &Path) -> Result<()> {
    match std::fs::metadata(out) {
        Ok(m) if !m.is_dir() => Err(Error::Invalid(format!(
            "{}: exists and is not a folder; this command writes a folder there (choose \
             another --out)",
            out.display()
        ))),
        _ => Ok(()),
    }
}

/// The temporary folder a run of this process into `out` writes (`out` named as given).
pub fn tmp_path(out: &Path) -> PathBuf {
    let name = out.file_name().unwrap_or_default().to_string_lossy();
    out.with_file_name(format!(".{name}{TMP_TAG}{}", std::process::id()))
}

/// `out` with a name of its own (`--out .` has none: the resolved path is used), the name
/// and the parent folder.
fn named(out: &Path) -> Result<(PathBuf, String, PathBuf)> {
    require_folder_or_absent(out)?;
    let out = match out.file_name() {
        Some(_) => out.to_path_buf(),
        None => out.canonicalize().map_err(|e| Error::io(out, e))?,
    };
    let name = out
        .file_name()
        .ok_or_else(|| Error::Invalid(format!("{}: not a folder to write", out.display())))?
        .to_string_lossy()
        .into_owned();
    let parent = parent_of(&out).to_path_buf();
    Ok((out, name, parent))
}

/// The lock of a folder a command writes in place (`coif video`, which resumes from its own
/// progress), with the stale temporaries beside and inside it removed.
pub fn lock_folder(out: &Path) -> Result<Lock> {
    let (out, name, parent) = named(out)?;
    super::ensure_dir(&parent)?;
    let lock = Lock::acquire(&out.with_file_name(format!(".{name}{LOCK_TAG}")), &out)?;
    clean_stale(&parent, Some(&name))?;
    if out.is_dir() {
        clean_stale(&out, None)?;
    }
    Ok(lock)
}

impl Txn {
    /// Locks `out`, removes stale temporaries beside and inside it, and makes the run's
    /// temporary folder. `out`'s missing parents are created.
    pub fn begin(out: &Path) -> Result<Txn> {
        let (out, name, parent) = named(out)?;
        let parents = PARENTS.lock().unwrap_or_else(|e| e.into_inner());
        let mut created = Vec::new();
        let mut d = parent.as_path();
        while !d.as_os_str().is_empty() && !d.exists() {
            created.push(d.to_path_buf());
            d = match d.parent() {
                Some(p) => p,
                None => break,
            };
        }
        created.reverse();
        super::ensure_dir(&parent)?;
        #[cfg(test)]
        std::thread::sleep(std::time::Duration::from_millis(
            PAUSE_BEFORE_LOCK.with(|p| p.get()),
        ));
        let mut txn = Txn {
            tmp: tmp_path(&out),
            out: out.clone(),
            created,
            lock: None,
            done: false,
        };
        let lock = Lock::acquire(&out.with_file_name(format!(".{name}{LOCK_TAG}")), &out);
        // Released before `txn` can drop on an error: its drop takes the guard too.
        drop(parents);
        txn.lock = Some(lock?);
        clean_stale(&parent, Some(&name))?;
        if out.is_dir() {
            clean_stale(&out, None)?;
        }
        std::fs::create_dir(&txn.tmp).map_err(|e| Error::io(&txn.tmp, e))?;
        live_insert(&txn.tmp);
        Ok(txn)
    }

    /// The temporary folder to write the run's files into.
    pub fn dir(&self) -> &Path {
        &self.tmp
    }

    /// Puts the run's folder in place of `out`.
    pub fn commit(mut self) -> Result<()> {
        let (tmp, out) = (self.tmp.clone(), self.out.clone());
        match std::fs::symlink_metadata(&out) {
            Ok(m) if m.is_dir() => {
                carry_over(&out, &tmp)?;
                // The new folder keeps the old one's permissions.
                let _ = std::fs::set_permissions(&tmp, m.permissions());
                let old = exchange(&tmp, &out)?;
                self.done = true;
                // The old files: a failure here leaves a stale temporary, removed next time.
                if let Err(e) = std::fs::remove_dir_all(&old) {
                    log::warn!("{}: {e}", old.display());
                }
                live_remove(&old);
            }
            Ok(_) => {
                // It was a folder or absent when the run began; something else put a file
                // there since.
                return Err(Error::Invalid(format!(
                    "{}: became a file during the run; the run's files are in {} until \
                     the next run into it",
                    out.display(),
                    tmp.display()
                )));
            }
            Err(_) => {
                std::fs::rename(&tmp, &out).map_err(|e| Error::io(&out, e))?;
                self.done = true;
            }
        }
        // The renames survive a crash once the folder holding them is on disk.
        if let Ok(f) = std::fs::File::open(parent_of(&out)) {
            let _ = f.sync_all();
        }
        Ok(())
    }
}

impl Drop for Txn {
    fn drop(&mut self) {
        if !self.done && self.tmp.exists() {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
        live_remove(&self.tmp);
        self.lock.take();
        if !self.done {
            let _parents = PARENTS.lock().unwrap_or_else(|e| e.into_inner());
            for d in self.created.iter().rev() {
                // Only when empty: another run may have put something there.
                if std::fs::remove_dir(d).is_err() {
                    break;
                }
            }
        }
    }
}

/// Whether `name` is one of coif's temporaries or bookkeeping files (`.coif-*`, a
/// temporary folder, a lock file), which are never carried over into a new folder.
fn is_coif_file(name: &str) -> bool {
    name.starts_with(".coif-") || name.contains(TMP_TAG) || name.ends_with(LOCK_TAG)
}

/// Hard-links (or copies, where links fail) every entry of `old` that `new` lacks into `new`.
fn carry_over(old: &Path, new: &Path) -> Result<()> {
    for e in std::fs::read_dir(old).map_err(|e| Error::io(old, e))? {
        let e = e.map_err(|e| Error::io(old, e))?;
        let name = e.file_name();
        if is_coif_file(&name.to_string_lossy()) {
            continue;
        }
        let dst = new.join(&name);
        if std::fs::symlink_metadata(&dst).is_ok() {
            continue; // the run wrote it: the new one replaces the old one whole
        }
        link_tree(&e.path(), &dst)?;
    }
    Ok(())
}

fn link_tree(src: &Path, dst: &Path) -> Result<()> {
    let m = std::fs::symlink_metadata(src).map_err(|e| Error::io(src, e))?;
    if m.is_dir() {
        std::fs::create_dir(dst).map_err(|e| Error::io(dst, e))?;
        for e in std::fs::read_dir(src).map_err(|e| Error::io(src, e))? {
            let e = e.map_err(|e| Error::io(src, e))?;
            link_tree(&e.path(), &dst.join(e.file_name()))?;
        }
        let _ = std::fs::set_permissions(dst, m.permissions());
        return Ok(());
    }
    #[cfg(unix)]
    if m.file_type().is_symlink() {
        let to = std::fs::read_link(src).map_err(|e| Error::io(src, e))?;
        return std::os::unix::fs::symlink(to, dst).map_err(|e| Error::io(dst, e));
    }
    if std::fs::hard_link(src, dst).is_err() {
        std::fs::copy(src, dst).map_err(|e| Error::io(dst, e))?;
    }
    Ok(())
}

/// Swaps the folders `tmp` and `out`; returns where the old `out` is now. One atomic
/// `renameat2(RENAME_EXCHANGE)` on Linux; elsewhere, or on a file system without it, two
/// renames (a crash between them leaves `out` missing, its old files in the temporary).
fn exchange(tmp: &Path, out: &Path) -> Result<PathBuf> {
    #[cfg(target_os = "linux")]
    {
        use rustix::fs::{renameat_with, RenameFlags, CWD};
        match renameat_with(CWD, tmp, CWD, out, RenameFlags::EXCHANGE) {
            Ok(()) => return Ok(tmp.to_path_buf()),
            Err(e)
                if e == rustix::io::Errno::INVAL
                    || e == rustix::io::Errno::NOSYS
                    || e == rustix::io::Errno::OPNOTSUPP => {}
            Err(e) => return Err(Error::io(out, e.into())),
        }
    }
    let mut aside = tmp.as_os_str().to_owned();
    aside.push("-old");
    let aside = PathBuf::from(aside);
    std::fs::rename(out, &aside).map_err(|e| Error::io(out, e))?;
    live_insert(&aside);
    if let Err(e) = std::fs::rename(tmp, out) {
        let _ = std::fs::rename(&aside, out);
        live_remove(&aside);
        return Err(Error::io(out, e));
    }
    Ok(aside)
}

/// The pid in a temporary's name: after [`TMP_TAG`] for a folder, in `.coif-<pid>-*.tmp`
/// for a file of `write_atomic`.
fn temp_pid(name: &str) -> Option<u32> {
    let digits = if let Some(i) = name.find(TMP_TAG) {
        &name[i + TMP_TAG.len()..]
    } else if name.starts_with(".coif-") && name.ends_with(".tmp") {
        &name[".coif-".len()..]
    } else {
        return None;
    };
    let end = digits
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(digits.len());
    digits[..end].parse().ok()
}

/// Whether the run that made the temporary `path` (pid `pid`) may still be writing it.
fn alive(pid: u32, path: &Path) -> bool {
    if pid == std::process::id() {
        // Ours only if this process registered it (a container may give each run one pid).
        return is_live(path);
    }
    #[cfg(unix)]
    {
        let Some(p) = i32::try_from(pid)
            .ok()
            .and_then(rustix::process::Pid::from_raw)
        else {
            return false;
        };
        // EPERM: the pid lives, under another user.
        !matches!(
            rustix::process::test_kill_process(p),
            Err(rustix::io::Errno::SRCH)
        )
    }
    #[cfg(not(unix))]
    {
        true
    }
}

/// Removes, in `dir`, the temporaries of runs that no longer live: `write_atomic`'s
/// `.coif-<pid>-*.tmp` files and, when `name` is given, the temporary folders of runs into
/// `dir/<name>` (nested ones, made by a step inside a batch job's folder, included).
/// Returns how many were removed.
pub fn clean_stale(dir: &Path, name: Option<&str>) -> Result<usize> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Ok(0);
    };
    let folder_prefix = name.map(|n| format!("{}{TMP_TAG}", n.trim_start_matches('.')));
    let mut removed = 0;
    for e in rd.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        let is_file_temp = n.starts_with(".coif-") && n.ends_with(".tmp");
        let is_folder_temp = folder_prefix
            .as_ref()
            .is_some_and(|p| n.starts_with('.') && n.trim_start_matches('.').starts_with(p));
        if !(is_file_temp || is_folder_temp) {
            continue;
        }
        let p = e.path();
        let Some(pid) = temp_pid(&n) else { continue };
        if alive(pid, &p) {
            continue;
        }
        let r = match e.file_type() {
            Ok(t) if t.is_dir() => std::fs::remove_dir_all(&p),
            _ => std::fs::remove_file(&p),
        };
        match r {
            Ok(()) => {
                log::info!("removed {} (a temporary of dead run {pid})", p.display());
                removed += 1;
            }
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
            Err(err) => return Err(Error::io(&p, err)),
        }
    }
    Ok(removed)
}

/// An exclusive flock on a lock file, held while the value lives; the file is removed when
/// it is released.
#[derive(Debug)]
pub struct Lock {
    path: PathBuf,
    /// Open while the lock is held: closing it releases the flock.
    _file: std::fs::File,
}

impl Lock {
    /// Takes the lock at `path` for writing `out`, or fails at once with [`Error::Busy`].
    pub fn acquire(path: &Path, out: &Path) -> Result<Lock> {
        use std::io::{Read, Seek, Write};
        // The previous holder unlinks the file on release; a lock taken on a file unlinked
        // between our open and our flock guards nothing, so check and try again.
        for _ in 0..16 {
            let mut file = std::fs::OpenOptions::new()
                .create(true)
                .truncate(false)
                .read(true)
                .write(true)
                .open(path)
                .map_err(|e| Error::io(path, e))?;
            #[cfg(unix)]
            {
                use rustix::fs::{flock, fstat, stat, FlockOperation};
                if let Err(e) = flock(&file, FlockOperation::NonBlockingLockExclusive) {
                    if e != rustix::io::Errno::WOULDBLOCK {
                        return Err(Error::io(path, e.into()));
                    }
                    let mut holder = String::new();
                    let _ = file.read_to_string(&mut holder);
                    let holder = match holder.trim().parse::<u32>() {
                        Ok(pid) => format!("coif run {pid}"),
                        Err(_) => "coif run".into(),
                    };
                    return Err(Error::Busy {
                        path: out.to_path_buf(),
                        msg: format!(
                            "another {holder} is writing this folder (lock {}); try again \
                             when it ends",
                            path.display()
                        ),
                    });
                }
                let same = match (fstat(&file), stat(path)) {
                    (Ok(a), Ok(b)) => a.st_dev == b.st_dev && a.st_ino == b.st_ino,
                    _ => false,
                };
                if !same {
                    continue;
                }
            }
            // The holder's pid, for the message a refused run prints.
            let _ = file.set_len(0);
            let _ = file.rewind();
            let _ = write!(file, "{}", std::process::id());
            return Ok(Lock {
                path: path.to_path_buf(),
                _file: file,
            });
        }
        Err(Error::Busy {
            path: out.to_path_buf(),
            msg: format!("its lock {} keeps changing hands", path.display()),
        })
    }
}

impl Drop for Lock {
    fn drop(&mut self) {
        // Unlinked while still held, so a waiting run sees it gone and opens a new one.
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files(d: &Path) -> Vec<(String, Vec<u8>)> {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .flatten()
            .filter(|e| e.path().is_file())
            .map(|e| {
                (
                    e.file_name().to_string_lossy().into_owned(),
                    std::fs::read(e.path()).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    }

    fn names(d: &Path) -> Vec<String> {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn commit_replaces_what_the_run_wrote_and_keeps_the_rest() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("m");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(out.join("strands.hair"), b"old").unwrap();
        std::fs::write(out.join("render.png"), b"picture").unwrap();
        std::fs::write(out.join(".coif-job.json"), b"{}").unwrap();
        let t = Txn::begin(&out).unwrap();
        std::fs::write(t.dir().join("strands.hair"), b"new").unwrap();
        // Before the commit the old folder is untouched.
        assert_eq!(std::fs::read(out.join("strands.hair")).unwrap(), b"old");
        t.commit().unwrap();
        assert_eq!(
            files(&out),
            vec![
                ("render.png".into(), b"picture".to_vec()),
                ("strands.hair".into(), b"new".to_vec())
            ]
        );
        // Nothing of coif's is left beside it.
        assert_eq!(names(d.path()), vec!["m".to_string()]);
    }

    #[test]
    fn a_run_that_does_not_commit_leaves_nothing() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("a/b/m");
        {
            let t = Txn::begin(&out).unwrap();
            std::fs::write(t.dir().join("x"), b"x").unwrap();
        }
        // The parents it made are gone too.
        assert!(names(d.path()).is_empty(), "{:?}", names(d.path()));
    }

    // Batch jobs at once: one job that fails while another into a sibling folder starts
    // must not take the parent folder from under the other's lock file.
    #[test]
    fn a_failing_run_leaves_a_shared_parent_to_a_sibling_starting_meanwhile() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("p/a"), d.path().join("p/b"));
        // The first run makes the parent `p`.
        let first = Txn::begin(&a).unwrap();
        std::thread::scope(|s| {
            let second = s.spawn(|| {
                // Made sure of `p`, then held before its lock file lies there.
                PAUSE_BEFORE_LOCK.with(|p| p.set(300));
                Txn::begin(&b).and_then(Txn::commit)
            });
            std::thread::sleep(std::time::Duration::from_millis(60));
            // The first run fails meanwhile and removes the parents it made, when empty.
            drop(first);
            second.join().unwrap().unwrap();
        });
        assert!(b.is_dir());
    }

    #[test]
    fn a_second_run_into_the_folder_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("m");
        let t = Txn::begin(&out).unwrap();
        // flock locks are per open file: a second open in this process conflicts too.
        let e = Txn::begin(&out).unwrap_err();
        assert_eq!(e.exit_code(), 75, "{e}");
        assert!(
            e.to_string().contains(&std::process::id().to_string()),
            "{e}"
        );
        drop(t);
        Txn::begin(&out).unwrap().commit().unwrap();
        assert!(out.is_dir());
    }

    #[test]
    fn stale_temporaries_of_dead_runs_are_removed() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("m");
        std::fs::create_dir(&out).unwrap();
        // A pid that cannot be alive (above pid_max), and one that is (ours, registered).
        let dead = 4_194_999u32;
        let stale = d.path().join(format!(".m{TMP_TAG}{dead}"));
        let nested = d.path().join(format!("..m{TMP_TAG}{dead}{TMP_TAG}{dead}"));
        let stale_file = out.join(format!(".coif-{dead}-abc.tmp"));
        let other = d.path().join(format!(".n{TMP_TAG}{dead}"));
        std::fs::create_dir(&stale).unwrap();
        std::fs::create_dir(&nested).unwrap();
        std::fs::write(&stale_file, b"x").unwrap();
        std::fs::create_dir(&other).unwrap();
        let t = Txn::begin(&out).unwrap();
        assert!(!stale.exists() && !nested.exists() && !stale_file.exists());
        // Another folder's temporaries are its own run's business.
        assert!(other.exists());
        // A live run's temporary stays.
        assert_eq!(clean_stale(d.path(), Some("m")).unwrap(), 0);
        assert!(t.dir().exists());
    }

    #[test]
    fn pids_in_temporary_names() {
        assert_eq!(temp_pid(".m.coif-tmp-123"), Some(123));
        assert_eq!(temp_pid("..m.coif-tmp-12.coif-tmp-12"), Some(12));
        assert_eq!(temp_pid(".m.coif-tmp-77-old"), Some(77));
        assert_eq!(temp_pid(".coif-4321-Ab3xYz.tmp"), Some(4321));
        assert_eq!(temp_pid(".coif-Ab3xYz.tmp"), None);
    }

    #[test]
    fn a_file_where_the_folder_goes_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let f = d.path().join("image.png");
        std::fs::write(&f, b"png").unwrap();
        let e = Txn::begin(&f).unwrap_err();
        assert_eq!(e.exit_code(), 64);
        assert!(e.to_string().contains("not a folder"), "{e}");
        assert_eq!(std::fs::read(&f).unwrap(), b"png");
    }
}
