//! Live reload: a [`springbake_watcher::Watcher`] on a background thread whose job only tells
//! the UI to re-open the file. It watches the scene file and every source it names (a mesh or
//! baked glTF: just the file), re-reading that list after each change.

use springbake_pipeline::watch::BakeInput;
use springbake_watcher::{CancelToken, JobError, RunSummary, WatchJob, WatchOptions, Watcher};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::thread::JoinHandle;

/// The watch job: each run sends one message.
pub struct ReloadJob {
    pub input: PathBuf,
    pub notify: Sender<()>,
    /// Called after sending, to wake a sleeping UI (egui's `request_repaint`).
    pub wake: Box<dyn Fn() + Send>,
}

/// Files the viewer depends on for `input`.
pub fn watched_inputs(input: &Path) -> Vec<PathBuf> {
    let is_scene = input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if !is_scene {
        return vec![input.to_path_buf()];
    }
    match BakeInput::Scene(input.to_path_buf()).load() {
        Ok(loaded) => loaded.inputs(),
        Err(_) => vec![input.to_path_buf()],
    }
}

impl WatchJob for ReloadJob {
    fn watched_paths(&mut self) -> Vec<PathBuf> {
        watched_inputs(&self.input)
    }

    fn run(&mut self, _cancel: &CancelToken) -> Result<RunSummary, JobError> {
        self.notify
            .send(())
            .map_err(|_| JobError::failed("the viewer has closed"))?;
        (self.wake)();
        Ok(RunSummary::default())
    }
}

/// A running watcher; dropping it stops the thread.
pub struct Reloader {
    pub changes: Receiver<()>,
    stop: CancelToken,
    thread: Option<JoinHandle<()>>,
}

impl Reloader {
    /// Watch `input` (the first message comes on the first change, not at start).
    pub fn start(input: &Path, wake: Box<dyn Fn() + Send>) -> Reloader {
        let (tx, rx) = channel();
        let stop = CancelToken::new();
        let job = ReloadJob {
            input: input.to_path_buf(),
            notify: tx,
            wake,
        };
        let options = WatchOptions {
            run_on_start: false,
            ..WatchOptions::default()
        };
        let thread_stop = stop.clone();
        let thread = std::thread::Builder::new()
            .name("springbake-view-watch".into())
            .spawn(move || {
                if let Err(e) = Watcher::new(job, options).run_until(&thread_stop, |_| {}) {
                    eprintln!("springbake: live reload is off: {e}");
                }
            })
            .ok();
        Reloader {
            changes: rx,
            stop,
            thread,
        }
    }

    /// True when something changed since the last call (several changes count once).
    pub fn changed(&self) -> bool {
        let mut any = false;
        while self.changes.try_recv().is_ok() {
            any = true;
        }
        any
    }
}

impl Drop for Reloader {
    fn drop(&mut self) {
        self.stop.cancel();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
