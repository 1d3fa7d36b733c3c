//! The watch loop against real file events in temp folders: one test per editor save pattern,
//! failure and recovery, cancellation mid-run, and a watch set that grows after a run.
//!
//! The fake job "bakes" by concatenating its sources into an output file next to them (so the
//! output's own events must not trigger runs), optionally sleeping per "frame" while polling
//! its cancel token. Tests wait on conditions with a 10 s deadline and check the output's
//! content and the exact number of runs.

// Helpers outside `#[test]` functions unwrap too: a failed setup step should fail the test.
#![allow(clippy::unwrap_used)]

use springbake_watcher::{
    write_atomically, CancelToken, JobError, RunSummary, WatchBackend, WatchEvent, WatchJob,
    WatchOptions, Watcher,
};
use std::fs;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

const DEADLINE: Duration = Duration::from_secs(10);
const DEBOUNCE: Duration = Duration::from_millis(150);

/// Where the job's inputs come from.
#[derive(Clone)]
enum Sources {
    /// These files, in order.
    Fixed(Vec<PathBuf>),
    /// A "scene" file listing one source per line (relative to its folder); the scene itself
    /// is watched too.
    Scene(PathBuf),
}

struct ConcatJob {
    sources: Sources,
    output: PathBuf,
    frames: u32,
    frame_sleep: Duration,
    /// How many times `run` was called.
    runs: usize,
}

impl ConcatJob {
    fn source_list(&self) -> Result<Vec<PathBuf>, JobError> {
        match &self.sources {
            Sources::Fixed(paths) => Ok(paths.clone()),
            Sources::Scene(scene) => {
                let text = fs::read_to_string(scene).map_err(|e| {
                    JobError::failed(format!("{}: cannot read scene: {e}", scene.display()))
                })?;
                let dir = scene.parent().unwrap();
                Ok(text
                    .lines()
                    .filter(|l| !l.trim().is_empty())
                    .map(|l| dir.join(l.trim()))
                    .collect())
            }
        }
    }
}

impl WatchJob for ConcatJob {
    fn watched_paths(&mut self) -> Vec<PathBuf> {
        let mut paths = match &self.sources {
            Sources::Scene(scene) => vec![scene.clone()],
            Sources::Fixed(_) => vec![],
        };
        paths.extend(self.source_list().unwrap_or_default());
        paths
    }

    fn run(&mut self, cancel: &CancelToken) -> Result<RunSummary, JobError> {
        self.runs += 1;
        let sources = self.source_list()?;
        let mut content = String::new();
        for source in &sources {
            let text = fs::read_to_string(source).map_err(|e| {
                JobError::failed(format!("{}: cannot read source: {e}", source.display()))
            })?;
            if text.contains("PANIC") {
                panic!("fake job panics on {}", source.display());
            }
            if text.contains("BROKEN") {
                return Err(JobError::failed(format!(
                    "{}: line 1: BROKEN marker",
                    source.display()
                )));
            }
            content.push_str(&text);
        }
        for _frame in 0..self.frames {
            cancel.check()?;
            thread::sleep(self.frame_sleep);
        }
        cancel.check()?;
        write_atomically(&self.output, content.as_bytes()).map_err(JobError::failed)?;
        Ok(RunSummary {
            frames: self.frames,
            outputs: vec![self.output.clone()],
            message: format!("{} sources", sources.len()),
        })
    }
}

struct Harness {
    dir: tempfile::TempDir,
    output: PathBuf,
    events: Arc<Mutex<Vec<WatchEvent>>>,
    stop: CancelToken,
    thread: Option<JoinHandle<ConcatJob>>,
}

struct Setup<'a> {
    files: &'a [(&'a str, &'a str)],
    /// `None`: the job reads `files` in order. `Some(name)`: the job reads the scene `name`.
    scene: Option<&'a str>,
    frames: u32,
    frame_sleep: Duration,
    debounce: Duration,
    backend: WatchBackend,
}

impl Default for Setup<'_> {
    fn default() -> Self {
        Setup {
            files: &[("a.txt", "A1"), ("b.txt", "B1")],
            scene: None,
            frames: 1,
            frame_sleep: Duration::ZERO,
            debounce: DEBOUNCE,
            backend: WatchBackend::Native,
        }
    }
}

impl Harness {
    fn start(setup: Setup) -> Harness {
        let dir = tempfile::tempdir().unwrap();
        for (name, content) in setup.files {
            let path = dir.path().join(name);
            fs::create_dir_all(path.parent().unwrap()).unwrap();
            fs::write(path, content).unwrap();
        }
        let sources = match setup.scene {
            Some(scene) => Sources::Scene(dir.path().join(scene)),
            None => Sources::Fixed(
                setup
                    .files
                    .iter()
                    .map(|(n, _)| dir.path().join(n))
                    .collect(),
            ),
        };
        let output = dir.path().join("out.txt");
        let job = ConcatJob {
            sources,
            output: output.clone(),
            frames: setup.frames,
            frame_sleep: setup.frame_sleep,
            runs: 0,
        };
        let options = WatchOptions {
            debounce: setup.debounce,
            run_on_start: true,
            backend: setup.backend,
        };
        let events = Arc::new(Mutex::new(Vec::new()));
        let stop = CancelToken::new();
        let thread = {
            let (events, stop) = (events.clone(), stop.clone());
            thread::spawn(move || {
                Watcher::new(job, options)
                    .run_until(&stop, |e| events.lock().unwrap().push(e.clone()))
                    .unwrap()
            })
        };
        Harness {
            dir,
            output,
            events,
            stop,
            thread: Some(thread),
        }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn events(&self) -> Vec<WatchEvent> {
        self.events.lock().unwrap().clone()
    }

    fn count(&self, pred: impl Fn(&WatchEvent) -> bool) -> usize {
        self.events().iter().filter(|e| pred(e)).count()
    }

    fn started(&self) -> usize {
        self.count(|e| matches!(e, WatchEvent::Started { .. }))
    }

    fn finished(&self) -> usize {
        self.count(|e| matches!(e, WatchEvent::Finished { .. }))
    }

    fn failed(&self) -> usize {
        self.count(|e| matches!(e, WatchEvent::Failed { .. }))
    }

    /// Polls `cond` until it holds or the deadline passes (then fails with the event log).
    fn wait_until(&self, what: &str, cond: impl Fn(&Harness) -> bool) {
        let start = Instant::now();
        while !cond(self) {
            if start.elapsed() > DEADLINE {
                panic!(
                    "timed out after {DEADLINE:?} waiting for {what}; output {:?}; events:\n{}",
                    fs::read_to_string(&self.output).ok(),
                    self.log()
                );
            }
            thread::sleep(Duration::from_millis(10));
        }
    }

    /// Waits until the output holds `expected` and the run that wrote it has reported.
    fn wait_output(&self, expected: &str, finished_runs: usize) {
        self.wait_until(
            &format!("output {expected:?} after {finished_runs} runs"),
            |h| {
                fs::read_to_string(&h.output).ok().as_deref() == Some(expected)
                    && h.finished() >= finished_runs
            },
        );
    }

    /// Lets a few debounce windows pass so a spurious extra run would show up.
    fn settle(&self) {
        thread::sleep(DEBOUNCE * 4);
        self.wait_until("the run in flight to end", |h| {
            let e = h.events();
            h.started()
                == e.iter()
                    .filter(|e| {
                        matches!(
                            e,
                            WatchEvent::Finished { .. }
                                | WatchEvent::Failed { .. }
                                | WatchEvent::Cancelled { .. }
                        )
                    })
                    .count()
        });
    }

    fn log(&self) -> String {
        self.events()
            .iter()
            .map(|e| format!("  {e}\n"))
            .collect::<String>()
    }

    /// Stops the loop, checks it ended cleanly, and returns all events.
    fn stop(mut self) -> Vec<WatchEvent> {
        self.stop.cancel();
        let job = self.thread.take().unwrap().join().unwrap();
        let events = self.events();
        assert!(
            matches!(events.last(), Some(WatchEvent::Stopped { .. })),
            "{}",
            self.log()
        );
        assert_eq!(job.runs, self.started());
        for event in &events {
            let value: serde_json::Value = serde_json::from_str(&event.to_json_line()).unwrap();
            assert!(value["event"].is_string(), "{value}");
            assert!(!event.to_string().contains('\n'));
        }
        events
    }
}

#[test]
fn write_in_place_triggers_one_run() {
    let h = Harness::start(Setup::default());
    h.wait_output("A1B1", 1);
    fs::write(h.path("a.txt"), "A2").unwrap();
    h.wait_output("A2B1", 2);
    h.settle();
    assert_eq!(h.started(), 2, "{}", h.log());
    let events = h.stop();
    assert!(events.contains(&WatchEvent::Changed {
        paths: vec![events_dir(&events).join("a.txt")]
    }));
}

/// The folder of the first watched path (the temp dir as the job named it).
fn events_dir(events: &[WatchEvent]) -> PathBuf {
    events
        .iter()
        .find_map(|e| match e {
            WatchEvent::WatchSetChanged { paths, .. } => {
                Some(paths[0].parent().unwrap().to_path_buf())
            }
            _ => None,
        })
        .unwrap()
}

#[test]
fn temp_file_renamed_over_triggers_one_run() {
    let h = Harness::start(Setup::default());
    h.wait_output("A1B1", 1);
    // Blender's exporters and many editors: write a temp file, rename it over the original.
    let temp = h.path(".b.txt.blend-tmp");
    fs::write(&temp, "B2").unwrap();
    fs::rename(&temp, h.path("b.txt")).unwrap();
    h.wait_output("A1B2", 2);
    h.settle();
    assert_eq!(h.started(), 2, "{}", h.log());
    assert_eq!(h.failed(), 0, "{}", h.log());
    h.stop();
}

#[test]
fn delete_then_recreate_triggers_one_run() {
    let h = Harness::start(Setup::default());
    h.wait_output("A1B1", 1);
    fs::remove_file(h.path("a.txt")).unwrap();
    fs::write(h.path("a.txt"), "A2").unwrap();
    h.wait_output("A2B1", 2);
    h.settle();
    assert_eq!(h.started(), 2, "{}", h.log());
    assert_eq!(h.failed(), 0, "{}", h.log());
    h.stop();
}

#[test]
fn a_burst_of_saves_is_one_run() {
    // A wider quiet window than the other tests: the burst's 10 ms gaps must stay well inside
    // it even when a loaded CI machine stretches a sleep (a 0.94 s gap was seen under load).
    let debounce = Duration::from_millis(1500);
    let h = Harness::start(Setup {
        debounce,
        ..Setup::default()
    });
    h.wait_output("A1B1", 1);
    for i in 0..10 {
        fs::write(h.path("a.txt"), format!("A-{i}")).unwrap();
        thread::sleep(Duration::from_millis(10));
    }
    h.wait_output("A-9B1", 2);
    thread::sleep(debounce * 2);
    h.settle();
    assert_eq!(h.started(), 2, "{}", h.log());
    assert_eq!(h.finished(), 2, "{}", h.log());
    h.stop();
}

#[test]
fn a_vanished_source_fails_once_and_recovers_when_it_returns() {
    let h = Harness::start(Setup::default());
    h.wait_output("A1B1", 1);
    fs::remove_file(h.path("a.txt")).unwrap();
    h.wait_until("a failed run", |h| h.failed() == 1);
    h.settle();
    assert_eq!(h.failed(), 1, "{}", h.log());
    assert_eq!(h.started(), 2, "{}", h.log());
    let error = h
        .events()
        .into_iter()
        .find_map(|e| match e {
            WatchEvent::Failed { error, .. } => Some(error),
            _ => None,
        })
        .unwrap();
    assert!(error.contains("a.txt: cannot read source"), "{error}");
    // The last good output is untouched.
    assert_eq!(fs::read_to_string(&h.output).unwrap(), "A1B1");

    fs::write(h.path("a.txt"), "A3").unwrap();
    h.wait_output("A3B1", 2);
    h.settle();
    assert_eq!(h.started(), 3, "{}", h.log());
    assert_eq!(h.failed(), 1, "{}", h.log());
    h.stop();
}

#[test]
fn a_broken_source_fails_once_keeps_the_output_and_recovers() {
    let h = Harness::start(Setup::default());
    h.wait_output("A1B1", 1);
    fs::write(h.path("b.txt"), "BROKEN").unwrap();
    h.wait_until("a failed run", |h| h.failed() == 1);
    h.settle();
    assert_eq!(h.failed(), 1, "{}", h.log());
    assert_eq!(h.started(), 2, "{}", h.log());
    assert_eq!(fs::read_to_string(&h.output).unwrap(), "A1B1");
    let line = h
        .events()
        .iter()
        .find(|e| matches!(e, WatchEvent::Failed { .. }))
        .unwrap()
        .to_string();
    assert!(line.starts_with("run 2: FAILED after "), "{line}");
    assert!(line.contains("b.txt: line 1: BROKEN marker"), "{line}");

    fs::write(h.path("b.txt"), "B4").unwrap();
    h.wait_output("A1B4", 2);
    h.settle();
    assert_eq!(h.started(), 3, "{}", h.log());
    assert_eq!(h.failed(), 1, "{}", h.log());
    // No temp files of the atomic writer are left next to the output.
    let mut names: Vec<String> = fs::read_dir(h.dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["a.txt", "b.txt", "out.txt"]);
    h.stop();
}

#[test]
fn a_panicking_job_is_a_failed_run_and_the_loop_goes_on() {
    let h = Harness::start(Setup::default());
    h.wait_output("A1B1", 1);
    fs::write(h.path("a.txt"), "PANIC").unwrap();
    h.wait_until("a failed run", |h| h.failed() == 1);
    let error = h
        .events()
        .into_iter()
        .find_map(|e| match e {
            WatchEvent::Failed { error, .. } => Some(error),
            _ => None,
        })
        .unwrap();
    assert!(
        error.starts_with("the job panicked: fake job panics on "),
        "{error}"
    );
    assert_eq!(fs::read_to_string(&h.output).unwrap(), "A1B1");
    fs::write(h.path("a.txt"), "A5").unwrap();
    h.wait_output("A5B1", 2);
    h.settle();
    assert_eq!(h.started(), 3, "{}", h.log());
    h.stop();
}

#[test]
fn a_change_during_a_bake_cancels_it_and_the_newest_content_wins() {
    // 20 frames x 50 ms: a run takes about a second.
    let frame_sleep = Duration::from_millis(50);
    let h = Harness::start(Setup {
        frames: 20,
        frame_sleep,
        ..Setup::default()
    });
    h.wait_output("A1B1", 1);
    fs::write(h.path("a.txt"), "A2").unwrap();
    h.wait_until("run 2 to start", |h| h.started() == 2);
    thread::sleep(Duration::from_millis(100));
    fs::write(h.path("a.txt"), "A3").unwrap();
    h.wait_output("A3B1", 2);
    h.settle();
    let events = h.stop();
    let cancelled: Vec<(u64, Duration)> = events
        .iter()
        .filter_map(|e| match e {
            WatchEvent::Cancelled { run, duration } => Some((*run, *duration)),
            _ => None,
        })
        .collect();
    assert_eq!(cancelled.len(), 1, "{events:#?}");
    assert_eq!(cancelled[0].0, 2);
    // Cancelled within a few frames, not after the whole second.
    assert!(cancelled[0].1 < Duration::from_millis(800), "{cancelled:?}");
    let finished: Vec<u64> = events
        .iter()
        .filter_map(|e| match e {
            WatchEvent::Finished { run, .. } => Some(*run),
            _ => None,
        })
        .collect();
    assert_eq!(finished, [1, 3]);
    assert!(events.contains(&WatchEvent::Started { run: 3 }));
    assert!(!events.contains(&WatchEvent::Started { run: 4 }));
}

#[test]
fn stopping_cancels_a_run_in_flight() {
    // 200 frames x 50 ms: ten seconds unless cancelled.
    let h = Harness::start(Setup {
        frames: 200,
        frame_sleep: Duration::from_millis(50),
        ..Setup::default()
    });
    h.wait_until("run 1 to start", |h| h.started() == 1);
    thread::sleep(Duration::from_millis(100));
    let output = h.output.clone();
    let began = Instant::now();
    let events = h.stop();
    assert!(
        began.elapsed() < Duration::from_secs(2),
        "{:?}",
        began.elapsed()
    );
    assert!(matches!(
        events[events.len() - 2..],
        [
            WatchEvent::Cancelled { run: 1, .. },
            WatchEvent::Stopped { runs: 1 }
        ]
    ));
    assert!(!output.exists());
}

#[test]
fn a_source_added_by_the_scene_gets_watched() {
    let h = Harness::start(Setup {
        files: &[("scene.txt", "a.txt\n"), ("a.txt", "A1"), ("c.txt", "C1")],
        scene: Some("scene.txt"),
        ..Setup::default()
    });
    h.wait_output("A1", 1);
    // c.txt is not watched yet: changing it does nothing.
    fs::write(h.path("c.txt"), "C2").unwrap();
    h.settle();
    assert_eq!(h.started(), 1, "{}", h.log());

    fs::write(h.path("scene.txt"), "a.txt\nc.txt\n").unwrap();
    h.wait_output("A1C2", 2);
    h.wait_until("the watch set to grow", |h| {
        h.events().iter().any(|e| {
            matches!(e, WatchEvent::WatchSetChanged { added, .. }
                if added.len() == 1 && added[0].ends_with("c.txt"))
        })
    });
    fs::write(h.path("c.txt"), "C3").unwrap();
    h.wait_output("A1C3", 3);

    // Dropping it from the scene stops watching it again.
    fs::write(h.path("scene.txt"), "a.txt\n").unwrap();
    h.wait_output("A1", 4);
    h.settle();
    fs::write(h.path("c.txt"), "C4").unwrap();
    h.settle();
    assert_eq!(h.started(), 4, "{}", h.log());
    h.stop();
}

#[test]
fn a_source_changed_before_it_was_watched_is_not_missed() {
    // Runs take ~0.6 s; the new source changes after the run read it but before the run ends
    // and its watch exists.
    let h = Harness::start(Setup {
        files: &[("scene.txt", "a.txt\n"), ("a.txt", "A1"), ("c.txt", "C1")],
        scene: Some("scene.txt"),
        frames: 12,
        frame_sleep: Duration::from_millis(50),
        ..Setup::default()
    });
    h.wait_output("A1", 1);
    fs::write(h.path("scene.txt"), "a.txt\nc.txt\n").unwrap();
    h.wait_until("run 2 to start", |h| h.started() == 2);
    thread::sleep(Duration::from_millis(150));
    fs::write(h.path("c.txt"), "C2").unwrap();
    h.wait_output("A1C2", 3);
    h.settle();
    assert_eq!(h.started(), 3, "{}", h.log());
    let events = h.stop();
    let changed: Vec<&WatchEvent> = events
        .iter()
        .filter(|e| matches!(e, WatchEvent::Changed { .. }))
        .collect();
    assert!(
        matches!(changed[..], [_, WatchEvent::Changed { paths }] if paths.len() == 1 && paths[0].ends_with("c.txt")),
        "{changed:?}"
    );
}

#[test]
fn a_source_in_a_folder_created_later_is_picked_up() {
    let h = Harness::start(Setup {
        files: &[("scene.txt", "a.txt\nsub/deeper/d.txt\n"), ("a.txt", "A1")],
        scene: Some("scene.txt"),
        ..Setup::default()
    });
    h.wait_until("the first run to fail", |h| h.failed() == 1);
    fs::create_dir_all(h.path("sub/deeper")).unwrap();
    fs::write(h.path("sub/deeper/d.txt"), "D1").unwrap();
    h.wait_output("A1D1", 1);
    h.settle();
    // Later edits inside the new folder are seen through its own watch.
    let runs = h.started();
    fs::write(h.path("sub/deeper/d.txt"), "D2").unwrap();
    h.wait_output("A1D2", 2);
    h.settle();
    assert_eq!(h.started(), runs + 1, "{}", h.log());
    h.stop();
}

#[test]
fn the_polling_backend_sees_a_rename_over() {
    let h = Harness::start(Setup {
        backend: WatchBackend::Poll {
            interval: Duration::from_millis(50),
        },
        ..Setup::default()
    });
    h.wait_output("A1B1", 1);
    let temp = h.path("a.txt.tmp");
    fs::write(&temp, "A2").unwrap();
    fs::rename(&temp, h.path("a.txt")).unwrap();
    h.wait_output("A2B1", 2);
    h.settle();
    assert_eq!(h.started(), 2, "{}", h.log());
    h.stop();
}

#[test]
fn relative_watched_paths_are_resolved() {
    // Only this test changes nothing global: it passes absolute and `..`-laden spellings.
    let h = Harness::start(Setup {
        files: &[
            ("scene.txt", "sub/../a.txt\n"),
            ("a.txt", "A1"),
            ("sub/x", ""),
        ],
        scene: Some("scene.txt"),
        ..Setup::default()
    });
    h.wait_output("A1", 1);
    fs::write(h.path("a.txt"), "A2").unwrap();
    h.wait_output("A2", 2);
    h.stop();
}
