//! The cancellation flag shared between the watcher, the running job and the host's Ctrl-C
//! handler: a cheap, cloneable [`CancelToken`].

use crate::job::JobError;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A shared "please stop" flag. Clones share the flag: cancelling one cancels all of them.
///
/// The watcher hands a fresh token to every run of the job and sets it when a relevant file
/// changes mid-run; the host uses another one to stop the whole watch loop (see
/// [`crate::install_ctrlc`]).
#[derive(Debug, Clone, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    /// A token that is not cancelled.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets the flag. Idempotent; never un-set.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// Whether [`cancel`](Self::cancel) was called on this token or any clone of it.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }

    /// `Err(JobError::Cancelled)` once cancelled, for `cancel.check()?` inside a job's frame loop.
    pub fn check(&self) -> Result<(), JobError> {
        if self.is_cancelled() {
            Err(JobError::Cancelled)
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_flag() {
        let a = CancelToken::new();
        let b = a.clone();
        assert!(!b.is_cancelled());
        assert!(b.check().is_ok());
        a.cancel();
        assert!(b.is_cancelled());
        assert!(matches!(b.check(), Err(JobError::Cancelled)));
        // A fresh token is independent.
        assert!(!CancelToken::new().is_cancelled());
    }
}
