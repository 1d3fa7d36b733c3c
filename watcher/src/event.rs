//! What the watch loop tells people and tools: [`WatchEvent`], one human line each through
//! `Display`, one JSON object each through `serde` (for a host's `--json` mode).

use crate::job::RunSummary;
use serde::{Serialize, Serializer};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// One thing that happened in the watch loop, in order.
///
/// JSON form: an object with an `"event"` tag in snake case, paths as strings (lossy for
/// non-UTF-8 names) and durations as `duration_secs` floats, e.g.
/// `{"event":"failed","run":2,"error":"...","duration_secs":0.12}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum WatchEvent {
    /// The set of watched files changed: before the first run and whenever a run's
    /// `watched_paths` differs from the previous set.
    WatchSetChanged {
        /// The whole set now watched, as the job named them.
        #[serde(serialize_with = "serialize_paths")]
        paths: Vec<PathBuf>,
        /// Newly watched paths.
        #[serde(serialize_with = "serialize_paths")]
        added: Vec<PathBuf>,
        /// Paths no longer watched.
        #[serde(serialize_with = "serialize_paths")]
        removed: Vec<PathBuf>,
    },
    /// Watched files changed (after the debounce window); a run follows.
    Changed {
        #[serde(serialize_with = "serialize_paths")]
        paths: Vec<PathBuf>,
    },
    /// Run number `run` (counting from 1) started.
    Started { run: u64 },
    /// A run succeeded.
    Finished {
        run: u64,
        summary: RunSummary,
        #[serde(rename = "duration_secs", serialize_with = "serialize_secs")]
        duration: Duration,
    },
    /// A run failed. Reported once per failed run; the watcher keeps watching and the next
    /// change runs the job again.
    Failed {
        run: u64,
        error: String,
        #[serde(rename = "duration_secs", serialize_with = "serialize_secs")]
        duration: Duration,
    },
    /// A run was cancelled (a watched file changed during it, or the loop is stopping).
    Cancelled {
        run: u64,
        #[serde(rename = "duration_secs", serialize_with = "serialize_secs")]
        duration: Duration,
    },
    /// Something the user should know that does not stop the loop (e.g. a folder that cannot
    /// be watched, an error from the OS notification backend).
    Warning { message: String },
    /// The loop ended because the stop token was set.
    Stopped { runs: u64 },
}

impl WatchEvent {
    /// The event as one line of JSON (no trailing newline).
    pub fn to_json_line(&self) -> String {
        // Serialization cannot fail: every field is a string, number or list of them.
        serde_json::to_string(self).unwrap_or_else(|e| {
            format!(
                "{{\"event\":\"warning\",\"message\":{:?}}}",
                format!("cannot serialize event: {e}")
            )
        })
    }
}

impl fmt::Display for WatchEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WatchEvent::WatchSetChanged {
                paths,
                added,
                removed,
            } => {
                write!(f, "watching {} file{}", paths.len(), plural(paths.len()))?;
                if !added.is_empty() {
                    write!(f, "; added {}", join(added))?;
                }
                if !removed.is_empty() {
                    write!(f, "; removed {}", join(removed))?;
                }
                Ok(())
            }
            WatchEvent::Changed { paths } => write!(f, "changed: {}", join(paths)),
            WatchEvent::Started { run } => write!(f, "run {run}: started"),
            WatchEvent::Finished {
                run,
                summary,
                duration,
            } => {
                write!(
                    f,
                    "run {run}: baked {} frame{} in {}",
                    summary.frames,
                    plural(summary.frames as usize),
                    secs(*duration)
                )?;
                if !summary.outputs.is_empty() {
                    write!(f, " -> {}", join(&summary.outputs))?;
                }
                if !summary.message.is_empty() {
                    write!(f, " ({})", summary.message)?;
                }
                Ok(())
            }
            WatchEvent::Failed {
                run,
                error,
                duration,
            } => write!(
                f,
                "run {run}: FAILED after {}: {error} (last good output kept; waiting for changes)",
                secs(*duration)
            ),
            WatchEvent::Cancelled { run, duration } => {
                write!(f, "run {run}: cancelled after {}", secs(*duration))
            }
            WatchEvent::Warning { message } => write!(f, "warning: {message}"),
            WatchEvent::Stopped { runs } => {
                write!(f, "stopped after {runs} run{}", plural(*runs as usize))
            }
        }
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

fn join(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn secs(duration: Duration) -> String {
    format!("{:.2} s", duration.as_secs_f64())
}

/// Serializes paths as strings, lossily for non-UTF-8 names (serde's own impl would fail).
pub(crate) fn serialize_paths<S: Serializer>(paths: &[PathBuf], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(paths.iter().map(|p| lossy(p)))
}

fn lossy(path: &Path) -> String {
    path.to_string_lossy().into_owned()
}

fn serialize_secs<S: Serializer>(duration: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(duration.as_secs_f64())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn finished() -> WatchEvent {
        WatchEvent::Finished {
            run: 3,
            summary: RunSummary {
                frames: 120,
                outputs: vec![PathBuf::from("out/jelly.glb")],
                message: "2 bodies".into(),
            },
            duration: Duration::from_millis(1250),
        }
    }

    #[test]
    fn display_is_one_line_per_event() {
        assert_eq!(
            finished().to_string(),
            "run 3: baked 120 frames in 1.25 s -> out/jelly.glb (2 bodies)"
        );
        let failed = WatchEvent::Failed {
            run: 4,
            error: "src/a.obj: line 3: bad face".into(),
            duration: Duration::from_millis(20),
        };
        assert_eq!(
            failed.to_string(),
            "run 4: FAILED after 0.02 s: src/a.obj: line 3: bad face \
             (last good output kept; waiting for changes)"
        );
        let set = WatchEvent::WatchSetChanged {
            paths: vec!["scene.toml".into(), "a.obj".into()],
            added: vec!["a.obj".into()],
            removed: vec![],
        };
        assert_eq!(set.to_string(), "watching 2 files; added a.obj");
        assert_eq!(
            WatchEvent::Changed {
                paths: vec!["a.obj".into(), "b.obj".into()]
            }
            .to_string(),
            "changed: a.obj, b.obj"
        );
        assert_eq!(
            WatchEvent::Stopped { runs: 1 }.to_string(),
            "stopped after 1 run"
        );
        for event in [finished(), failed, set] {
            assert!(!event.to_string().contains('\n'));
        }
    }

    #[test]
    fn json_lines_are_tagged_objects() {
        let value: serde_json::Value = serde_json::from_str(&finished().to_json_line()).unwrap();
        assert_eq!(
            value,
            serde_json::json!({
                "event": "finished",
                "run": 3,
                "summary": {"frames": 120, "outputs": ["out/jelly.glb"], "message": "2 bodies"},
                "duration_secs": 1.25,
            })
        );
        let cancelled = WatchEvent::Cancelled {
            run: 2,
            duration: Duration::from_millis(500),
        };
        assert_eq!(
            cancelled.to_json_line(),
            r#"{"event":"cancelled","run":2,"duration_secs":0.5}"#
        );
    }

    #[cfg(unix)]
    #[test]
    fn non_utf8_paths_still_serialize() {
        use std::os::unix::ffi::OsStrExt;
        let odd = PathBuf::from(std::ffi::OsStr::from_bytes(b"caf\xe9.obj"));
        let line = WatchEvent::Changed { paths: vec![odd] }.to_json_line();
        let value: serde_json::Value = serde_json::from_str(&line).unwrap();
        assert_eq!(value["paths"][0], "caf\u{fffd}.obj");
    }
}
