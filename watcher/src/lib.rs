//! Watch mode: re-run a job (in springbake, a bake) whenever the files it depends on change.
//!
//! The crate is generic over the work: the host supplies a [`WatchJob`] that names its input
//! files and runs once per change; the [`Watcher`] watches those files' folders (so editor
//! save patterns — rename-over, delete-and-recreate — are seen), debounces bursts, runs the job
//! on a worker thread, cancels a run whose inputs changed under it, keeps going after failures
//! and reports each step as a [`WatchEvent`] (a human line via `Display`, a JSON line via
//! `serde`). [`atomic::write_atomically`] is the helper jobs use so a failed run never damages
//! the last good output; [`install_ctrlc`] wires Ctrl-C to the stop token.

pub mod atomic;
mod cancel;
mod event;
mod job;
mod watcher;
mod watchset;

pub use atomic::{write_atomically, write_atomically_with, write_set_atomically};
pub use cancel::CancelToken;
pub use event::WatchEvent;
pub use job::{JobError, RunSummary, WatchJob};
pub use watcher::{WatchBackend, WatchError, WatchOptions, Watcher};

/// Sets `stop` on Ctrl-C (SIGINT; also SIGTERM and SIGHUP where the platform has them), so
/// [`Watcher::run_until`] cancels the run in flight and returns. A second Ctrl-C while the first
/// is still being honoured exits the process at once with status 130.
///
/// The handler is process-wide and can be installed once; a second call is an error.
pub fn install_ctrlc(stop: CancelToken) -> Result<(), WatchError> {
    ctrlc::set_handler(move || {
        if stop.is_cancelled() {
            std::process::exit(130);
        }
        stop.cancel();
    })
    .map_err(|e| WatchError::Signal(e.to_string()))
}
