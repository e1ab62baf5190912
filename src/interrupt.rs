//! SIGINT and SIGTERM as a flag. The command line installs the handlers; long jobs call
//! [`check`] at their stage boundaries and in their loops over frames and jobs, and stop with
//! [`Error::Interrupted`], which removes the run's temporary folder on the way out (see
//! `io::txn`). A second signal while the first is pending ends the process at once; the
//! temporaries it leaves are removed as stale by the next run into that folder.

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

/// The first signal received (0: none).
fn received() -> &'static Arc<AtomicUsize> {
    static SIGNAL: OnceLock<Arc<AtomicUsize>> = OnceLock::new();
    SIGNAL.get_or_init(|| Arc::new(AtomicUsize::new(0)))
}

/// Installs the handlers for SIGINT and SIGTERM (unix; elsewhere the defaults stay).
pub fn install() -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGINT, SIGTERM};
        let pending = Arc::new(AtomicBool::new(false));
        for sig in [SIGINT, SIGTERM] {
            // Actions run in the order registered: the shutdown sees the flag of a signal
            // already received, so only a second one ends the process.
            signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, pending.clone())?;
            signal_hook::flag::register(sig, pending.clone())?;
            signal_hook::flag::register_usize(sig, received().clone(), sig as usize)?;
        }
    }
    Ok(())
}

/// The signal received, if any.
pub fn pending() -> Option<i32> {
    match received().load(Ordering::SeqCst) {
        0 => None,
        s => Some(s as i32),
    }
}

/// A stage boundary: an error when a signal asked the run to stop.
pub fn check() -> Result<()> {
    match pending() {
        Some(s) => Err(Error::Interrupted(s)),
        None => Ok(()),
    }
}

/// A signal's name for messages ("SIGTERM"), or its number.
pub fn name(sig: i32) -> String {
    match sig {
        2 => "SIGINT".into(),
        15 => "SIGTERM".into(),
        s => format!("signal {s}"),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn exit_codes_are_128_plus_the_signal() {
        use crate::error::Error;
        assert_eq!(Error::Interrupted(15).exit_code(), 143);
        assert_eq!(Error::Interrupted(2).exit_code(), 130);
        assert!(Error::Interrupted(15).to_string().contains("SIGTERM"));
    }
}
