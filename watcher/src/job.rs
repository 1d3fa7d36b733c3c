//! The contract between the watcher and the work it drives: the [`WatchJob`] trait, what a run
//! returns ([`RunSummary`]) and how it fails ([`JobError`]).

use crate::cancel::CancelToken;
use serde::Serialize;
use springbake_core::plugin::PluginError;
use std::path::PathBuf;

/// The work the watcher re-runs when its inputs change (in springbake: one bake of a scene).
///
/// The job is moved to a worker thread for each run and comes back afterwards, so it must be
/// `Send`; calls never overlap.
pub trait WatchJob: Send {
    /// The files the job depends on (the scene file and every source it names).
    ///
    /// Called once before the first run and again after every run, successful or not, so a
    /// scene that starts naming a new source gets that source watched. Return at least the
    /// files you know even when the job is broken (e.g. the scene file when it fails to parse):
    /// an unwatched file cannot trigger the run that would fix things. Relative paths are
    /// taken relative to the current directory. Paths that do not exist (yet) are fine.
    fn watched_paths(&mut self) -> Vec<PathBuf>;

    /// Runs the job once.
    ///
    /// Must poll `cancel` often (a bake checks it every frame) and return
    /// `Err(JobError::Cancelled)` promptly once it is set: the watcher waits for this run to
    /// return before starting the next one. A failing run must leave its last good output
    /// untouched (write outputs with [`crate::atomic::write_atomically`]); the watcher only
    /// reports the failure.
    fn run(&mut self, cancel: &CancelToken) -> Result<RunSummary, JobError>;
}

/// What a successful run produced.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RunSummary {
    /// How many frames were baked.
    pub frames: u32,
    /// The files written.
    #[serde(serialize_with = "crate::event::serialize_paths")]
    pub outputs: Vec<PathBuf>,
    /// Free-form detail for people (e.g. "3 bodies, 1240 springs, max stretch 4.1 %").
    pub message: String,
}

/// Why a run did not produce a result.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum JobError {
    /// The run saw its [`CancelToken`] set and stopped early.
    #[error("cancelled")]
    Cancelled,
    /// The run failed; the message says what and where (file, data path or line).
    #[error("{0}")]
    Failed(String),
}

impl JobError {
    /// A failure with this message.
    pub fn failed(message: impl std::fmt::Display) -> Self {
        JobError::Failed(message.to_string())
    }

    /// A failure from an error and its chain of sources, joined with `": "`.
    pub fn from_error(error: &(dyn std::error::Error + 'static)) -> Self {
        let mut message = error.to_string();
        let mut source = error.source();
        while let Some(cause) = source {
            let text = cause.to_string();
            if !message.contains(&text) {
                message.push_str(": ");
                message.push_str(&text);
            }
            source = cause.source();
        }
        JobError::Failed(message)
    }
}

impl From<PluginError> for JobError {
    fn from(error: PluginError) -> Self {
        JobError::from_error(&error)
    }
}

impl From<String> for JobError {
    fn from(message: String) -> Self {
        JobError::Failed(message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("cannot read scene.toml")]
    struct Outer(#[source] std::io::Error);

    #[test]
    fn from_error_joins_the_source_chain() {
        let err = Outer(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "no such file",
        ));
        assert_eq!(
            JobError::from_error(&err),
            JobError::Failed("cannot read scene.toml: no such file".into())
        );
    }

    #[test]
    fn plugin_errors_keep_their_location() {
        let err = PluginError::invalid("/tmp/a.obj", "bad face index").at("line 17");
        assert_eq!(
            JobError::from(err).to_string(),
            "/tmp/a.obj: line 17: bad face index"
        );
    }
}
