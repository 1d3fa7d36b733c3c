//! The watch loop: [`Watcher`] owns the OS notification backend, debounces file events,
//! runs the [`WatchJob`] on a worker thread, cancels and restarts it when its inputs change
//! mid-run, and reports everything as [`WatchEvent`]s.

use crate::cancel::CancelToken;
use crate::event::WatchEvent;
use crate::job::{JobError, RunSummary, WatchJob};
use crate::watchset::WatchSet;
use std::collections::BTreeSet;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::thread::{self, Scope, ScopedJoinHandle};
use std::time::{Duration, Instant, SystemTime};

/// How often the loop looks at the stop token while nothing else happens.
const STOP_POLL: Duration = Duration::from_millis(50);

/// Where file events come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WatchBackend {
    /// The OS's notification API (inotify, FSEvents, ReadDirectoryChangesW, kqueue).
    #[default]
    Native,
    /// Scan the watched folders every `interval`: for network shares and containers where
    /// native notifications do not arrive. Each scan compares modification times (whole
    /// seconds) and content hashes of every file in the watched folders, so prefer an interval
    /// around a second when large files (e.g. the outputs) share those folders.
    Poll { interval: Duration },
}

/// Settings of a [`Watcher`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WatchOptions {
    /// Quiet time after the last relevant event before a run starts: a burst of saves inside
    /// it (an editor's temp file, rename, chmod) becomes one run.
    pub debounce: Duration,
    /// Run the job once at start, before any change.
    pub run_on_start: bool,
    /// Where file events come from.
    pub backend: WatchBackend,
}

impl Default for WatchOptions {
    fn default() -> Self {
        WatchOptions {
            debounce: Duration::from_millis(200),
            run_on_start: true,
            backend: WatchBackend::Native,
        }
    }
}

/// Errors that stop the watch loop from starting (failed runs are events, not errors).
#[derive(Debug, thiserror::Error)]
pub enum WatchError {
    /// The OS notification backend could not be created (e.g. the inotify instance limit).
    #[error("cannot start the file watcher: {0}")]
    Backend(#[from] notify::Error),
    /// The worker thread for a run could not be spawned.
    #[error("cannot start a worker thread for the job: {0}")]
    Thread(#[source] std::io::Error),
    /// The Ctrl-C handler could not be installed (e.g. one is already set).
    #[error("cannot install the Ctrl-C handler: {0}")]
    Signal(String),
}

/// Re-runs a [`WatchJob`] whenever one of its watched files changes.
///
/// ```no_run
/// use springbake_watcher::{CancelToken, JobError, RunSummary, WatchJob, WatchOptions, Watcher};
/// use std::path::PathBuf;
///
/// struct Bake;
/// impl WatchJob for Bake {
///     fn watched_paths(&mut self) -> Vec<PathBuf> {
///         vec!["scene.toml".into()]
///     }
///     fn run(&mut self, cancel: &CancelToken) -> Result<RunSummary, JobError> {
///         for _frame in 0..120 {
///             cancel.check()?;
///             // ... step and record a frame ...
///         }
///         Ok(RunSummary { frames: 120, ..Default::default() })
///     }
/// }
///
/// let stop = CancelToken::new();
/// springbake_watcher::install_ctrlc(stop.clone())?;
/// Watcher::new(Bake, WatchOptions::default()).run_until(&stop, |event| println!("{event}"))?;
/// # Ok::<(), springbake_watcher::WatchError>(())
/// ```
pub struct Watcher<J: WatchJob> {
    job: J,
    options: WatchOptions,
}

/// What the worker thread hands back after a run.
struct Done<J> {
    job: J,
    result: Result<RunSummary, JobError>,
    /// `None` when `watched_paths` panicked: keep the previous set.
    paths: Option<Vec<PathBuf>>,
    duration: Duration,
    /// Wall-clock start of the run, to catch sources that changed before they were watched.
    started_at: SystemTime,
}

/// Messages into the loop: file events and "the worker is done".
enum Msg {
    Fs(notify::Result<notify::Event>),
    JobDone,
}

/// A run in flight.
struct Running<'scope, J> {
    run: u64,
    cancel: CancelToken,
    handle: ScopedJoinHandle<'scope, Done<J>>,
}

/// Sends [`Msg::JobDone`] when dropped: at the end of the worker, panicking or not.
struct NotifyOnDrop(Sender<Msg>);

impl Drop for NotifyOnDrop {
    fn drop(&mut self) {
        let _ = self.0.send(Msg::JobDone);
    }
}

impl<J: WatchJob> Watcher<J> {
    pub fn new(job: J, options: WatchOptions) -> Self {
        Watcher { job, options }
    }

    /// Watches and runs until `stop` is set, then cancels a run in flight, waits for it and
    /// returns the job. Events go to `on_event` on the calling thread, in order.
    ///
    /// Returns an error only when watching cannot start at all; failed runs are reported as
    /// [`WatchEvent::Failed`] and the loop keeps going.
    pub fn run_until(
        self,
        stop: &CancelToken,
        mut on_event: impl FnMut(&WatchEvent),
    ) -> Result<J, WatchError> {
        let Watcher { job, options } = self;
        let (tx, rx) = mpsc::channel::<Msg>();
        let fs_tx = tx.clone();
        let handler = move |res: notify::Result<notify::Event>| {
            // The loop may be gone while the backend shuts down; nothing to do then.
            let _ = fs_tx.send(Msg::Fs(res));
        };
        let mut backend: Box<dyn notify::Watcher + Send> = match options.backend {
            WatchBackend::Native => Box::new(notify::recommended_watcher(handler)?),
            WatchBackend::Poll { interval } => Box::new(notify::PollWatcher::new(
                handler,
                notify::Config::default()
                    .with_poll_interval(interval)
                    .with_compare_contents(true),
            )?),
        };
        let result = thread::scope(|scope| {
            let mut state = Loop {
                scope,
                tx,
                options,
                set: WatchSet::default(),
                job: Some(job),
                running: None,
                pending: BTreeSet::new(),
                deadline: None,
                runs: 0,
            };
            state.run(&rx, stop, backend.as_mut(), &mut on_event)
        });
        drop(backend);
        result
    }
}

/// The loop's state, alive for one [`Watcher::run_until`].
struct Loop<'scope, 'env, J: WatchJob> {
    scope: &'scope Scope<'scope, 'env>,
    tx: Sender<Msg>,
    options: WatchOptions,
    set: WatchSet,
    /// The job while idle; `None` while it is out on a worker thread.
    job: Option<J>,
    running: Option<Running<'scope, J>>,
    /// Watched paths changed since the last run started.
    pending: BTreeSet<PathBuf>,
    /// When the pending changes are quiet long enough to start a run.
    deadline: Option<Instant>,
    runs: u64,
}

impl<'scope, 'env, J: WatchJob + 'scope> Loop<'scope, 'env, J> {
    fn run(
        &mut self,
        rx: &Receiver<Msg>,
        stop: &CancelToken,
        backend: &mut dyn notify::Watcher,
        on_event: &mut dyn FnMut(&WatchEvent),
    ) -> Result<J, WatchError> {
        if let Some(job) = self.job.as_mut() {
            let paths = job.watched_paths();
            self.update_watch_set(Some(paths), backend, on_event);
        }
        if self.options.run_on_start {
            self.start_run(on_event)?;
        }
        while !stop.is_cancelled() {
            if self.running.is_none() && !self.pending.is_empty() {
                if let Some(deadline) = self.deadline {
                    if Instant::now() >= deadline {
                        self.deadline = None;
                        let paths = std::mem::take(&mut self.pending).into_iter().collect();
                        on_event(&WatchEvent::Changed { paths });
                        self.start_run(on_event)?;
                        continue;
                    }
                }
            }
            let wait = match (self.running.is_none(), self.deadline) {
                (true, Some(deadline)) => deadline
                    .saturating_duration_since(Instant::now())
                    .min(STOP_POLL),
                _ => STOP_POLL,
            };
            match rx.recv_timeout(wait) {
                Ok(Msg::Fs(Ok(event))) => self.on_fs_event(&event, backend, on_event),
                Ok(Msg::Fs(Err(error))) => on_event(&WatchEvent::Warning {
                    message: format!("file watcher: {error}"),
                }),
                Ok(Msg::JobDone) => self.finish_run(backend, on_event),
                Err(RecvTimeoutError::Timeout) => {}
                // Unreachable while `self.tx` lives; end the loop rather than spin.
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        // Stopping: cancel a run in flight and wait for it to hand the job back.
        if let Some(running) = &self.running {
            running.cancel.cancel();
        }
        while self.running.is_some() {
            match rx.recv() {
                Ok(Msg::JobDone) => self.finish_run(backend, on_event),
                Ok(Msg::Fs(_)) => {}
                Err(_) => break,
            }
        }
        on_event(&WatchEvent::Stopped { runs: self.runs });
        // Invariant: with no run in flight the job is home.
        self.job.take().ok_or_else(|| {
            WatchError::Thread(std::io::Error::other("the job was lost with its worker"))
        })
    }

    fn on_fs_event(
        &mut self,
        event: &notify::Event,
        backend: &mut dyn notify::Watcher,
        on_event: &mut dyn FnMut(&WatchEvent),
    ) {
        let relevance = self.set.classify(event);
        if relevance.resync {
            for path in &event.paths {
                self.set.forget_dirs_under(path, backend);
            }
            // A folder that cannot be watched now is retried on the next resync.
            for message in self.set.sync(backend) {
                on_event(&WatchEvent::Warning { message });
            }
        }
        if relevance.changed.is_empty() {
            return;
        }
        self.pending.extend(relevance.changed);
        self.deadline = Some(Instant::now() + self.options.debounce);
        if let Some(running) = &self.running {
            // Its inputs changed: its result would be stale. Restart after the debounce.
            running.cancel.cancel();
        }
    }

    fn start_run(&mut self, on_event: &mut dyn FnMut(&WatchEvent)) -> Result<(), WatchError> {
        let Some(mut job) = self.job.take() else {
            return Ok(());
        };
        self.runs += 1;
        let run = self.runs;
        let cancel = CancelToken::new();
        let worker_cancel = cancel.clone();
        let done_tx = self.tx.clone();
        on_event(&WatchEvent::Started { run });
        let handle = thread::Builder::new()
            .name(format!("springbake-watch-run-{run}"))
            .spawn_scoped(self.scope, move || {
                let _notify = NotifyOnDrop(done_tx);
                let started = Instant::now();
                let started_at = SystemTime::now();
                let result = catch_unwind(AssertUnwindSafe(|| job.run(&worker_cancel)))
                    .unwrap_or_else(|payload| {
                        Err(JobError::Failed(format!(
                            "the job panicked: {}",
                            panic_message(payload.as_ref())
                        )))
                    });
                let duration = started.elapsed();
                let paths = catch_unwind(AssertUnwindSafe(|| job.watched_paths())).ok();
                Done {
                    job,
                    result,
                    paths,
                    duration,
                    started_at,
                }
            })
            .map_err(WatchError::Thread)?;
        self.running = Some(Running {
            run,
            cancel,
            handle,
        });
        Ok(())
    }

    fn finish_run(
        &mut self,
        backend: &mut dyn notify::Watcher,
        on_event: &mut dyn FnMut(&WatchEvent),
    ) {
        let Some(running) = self.running.take() else {
            return;
        };
        let run = running.run;
        let done = match running.handle.join() {
            Ok(done) => done,
            Err(payload) => {
                // Only reachable if dropping the job's result panicked after catch_unwind;
                // the job is gone, so stop running it but keep reporting.
                on_event(&WatchEvent::Failed {
                    run,
                    error: format!("the job's worker died: {}", panic_message(payload.as_ref())),
                    duration: Duration::ZERO,
                });
                return;
            }
        };
        self.job = Some(done.job);
        on_event(&match done.result {
            Ok(summary) => WatchEvent::Finished {
                run,
                summary,
                duration: done.duration,
            },
            Err(JobError::Cancelled) => WatchEvent::Cancelled {
                run,
                duration: done.duration,
            },
            Err(JobError::Failed(error)) => WatchEvent::Failed {
                run,
                error,
                duration: done.duration,
            },
        });
        let added = self.update_watch_set(done.paths, backend, on_event);
        // A newly named source was not watched while this run read it: a change made after the
        // read would be lost. Anything modified since the run started gets a re-run (at worst
        // one extra run when the change came before the read).
        let missed: Vec<PathBuf> = added
            .into_iter()
            .filter(|path| {
                std::fs::metadata(path)
                    .and_then(|m| m.modified())
                    .is_ok_and(|modified| modified >= done.started_at)
            })
            .collect();
        if !missed.is_empty() {
            self.pending.extend(missed);
            self.deadline = Some(Instant::now() + self.options.debounce);
        }
    }

    /// Installs a new set of watched paths, reports it, and returns the newly added ones.
    fn update_watch_set(
        &mut self,
        paths: Option<Vec<PathBuf>>,
        backend: &mut dyn notify::Watcher,
        on_event: &mut dyn FnMut(&WatchEvent),
    ) -> Vec<PathBuf> {
        let changed = match paths {
            Some(paths) => self.set.set_paths(paths),
            None => None,
        };
        let first = self.runs == 0;
        let warnings = self.set.sync(backend);
        let mut newly_added = Vec::new();
        if let Some((added, removed)) = changed {
            newly_added.clone_from(&added);
            on_event(&WatchEvent::WatchSetChanged {
                paths: self.set.paths().to_vec(),
                added,
                removed,
            });
        } else if first {
            on_event(&WatchEvent::WatchSetChanged {
                paths: vec![],
                added: vec![],
                removed: vec![],
            });
        }
        for message in warnings {
            on_event(&WatchEvent::Warning { message });
        }
        newly_added
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic payload".to_string()
    }
}
