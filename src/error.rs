//! One error type for the library; the command line maps it to exit codes.

use std::path::PathBuf;

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file system refused a read or write. The OS error is in the message rather than
    /// a `source`, so that error chains do not print it twice.
    #[error("{}: {err}", path.display())]
    Io { path: PathBuf, err: std::io::Error },
    /// A file was read but its content is unusable (bad image, malformed JSON, wrong size ...).
    #[error("{}: {msg}", path.display())]
    BadFile { path: PathBuf, msg: String },
    /// An argument or in-memory input is unusable.
    #[error("{0}")]
    Invalid(String),
    /// A buffer or an image would exceed a device or format limit and cannot be split
    /// further; `unit` says what `needed` and `limit` count ("bytes", "pixels").
    #[error("{what} needs {needed} {unit}, over the {limit_name} of {limit} {unit}")]
    TooLarge {
        what: String,
        needed: u64,
        limit: u64,
        limit_name: String,
        unit: &'static str,
    },
    /// A run's estimated memory is over the budget (`--max-memory`, else the machine's): 64
    /// when an option sizes it, 65 when an input does.
    #[error("{msg}")]
    OverBudget {
        cause: crate::base::budget::Cause,
        msg: String,
    },
    /// No adapter matched the request (exit code 69, EX_UNAVAILABLE).
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// The device reported an error (validation, out of memory, lost device).
    #[error("GPU error: {0}")]
    Gpu(String),
    /// Another run holds the lock of the folder this one would write (exit 75, EX_TEMPFAIL:
    /// try again later).
    #[error("{}: {msg}", path.display())]
    Busy { path: PathBuf, msg: String },
    /// SIGINT or SIGTERM (the signal's number) stopped the run at a stage boundary; exit
    /// 128 + the number, as a shell reports a process the signal ended.
    #[error(
        "interrupted by {}: stopped at a stage boundary, the run's temporary files removed and \
         its output folder left as it was",
        crate::interrupt::name(*.0)
    )]
    Interrupted(i32),
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err: source,
        }
    }

    pub fn bad_file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::BadFile {
            path: path.into(),
            msg: msg.into(),
        }
    }

    /// Exit code for the command line: sysexits.h where one fits.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::NoAdapter(_) => 69,   // EX_UNAVAILABLE
            Error::Io { .. } => 74,      // EX_IOERR
            Error::BadFile { .. } => 65, // EX_DATAERR
            Error::Invalid(_) => 64,     // EX_USAGE
            Error::TooLarge { .. } => 65,
            Error::OverBudget { cause, .. } => match cause {
                crate::base::budget::Cause::Option => 64,
                crate::base::budget::Cause::Input => 65,
            },
            Error::Gpu(_) => 70,      // EX_SOFTWARE
            Error::Busy { .. } => 75, // EX_TEMPFAIL
            Error::Interrupted(sig) => 128 + sig,
        }
    }
}
