//! The bake as a [`WatchJob`]: what `springbake watch` and the viewer's live reload drive.

use crate::{
    bake, default_scene_for_mesh, load_scene, BakeHooks, LoadedScene, MeshOverrides, PipelineError,
};
use springbake_watcher::{CancelToken, JobError, RunSummary, WatchJob};
use std::path::PathBuf;

/// What to bake: a scene file, or a bare mesh with the default scene.
#[derive(Debug, Clone)]
pub enum BakeInput {
    Scene(PathBuf),
    Mesh(PathBuf, MeshOverrides),
}

impl BakeInput {
    /// Load (re-read) the scene this input describes.
    pub fn load(&self) -> Result<LoadedScene, PipelineError> {
        match self {
            BakeInput::Scene(path) => load_scene(path),
            BakeInput::Mesh(path, overrides) => Ok(default_scene_for_mesh(path, overrides)),
        }
    }
}

/// Re-bakes its input on every run. With `plugins`, the Python plug-ins for the input are
/// discovered again for every run (an edited plug-in is reloaded) and their files watched
/// with the scene's inputs.
pub struct BakeJob {
    pub input: BakeInput,
    pub plugins: bool,
}

impl BakeJob {
    /// The folder plug-ins are discovered for: the scene's (or the bare mesh's).
    fn plugin_dir(&self, loaded: Option<&LoadedScene>) -> Option<PathBuf> {
        match (loaded, &self.input) {
            (Some(l), _) => Some(l.read_root()),
            (None, BakeInput::Scene(p) | BakeInput::Mesh(p, _)) => {
                p.parent().map(|d| d.to_path_buf())
            }
        }
    }
}

impl WatchJob for BakeJob {
    fn watched_paths(&mut self) -> Vec<PathBuf> {
        let loaded = self.input.load().ok();
        let mut paths = match &loaded {
            Some(loaded) => loaded.inputs(),
            // A broken scene: watch the scene file itself so fixing it triggers a run.
            None => match &self.input {
                BakeInput::Scene(p) | BakeInput::Mesh(p, _) => vec![p.clone()],
            },
        };
        if self.plugins {
            let dir = self.plugin_dir(loaded.as_ref());
            paths.extend(springbake_usd::python_plugins::plugin_files(dir.as_deref()));
        }
        paths
    }

    fn run(&mut self, cancel: &CancelToken) -> Result<RunSummary, JobError> {
        let loaded = self.input.load().map_err(JobError::failed)?;
        let dir = self.plugin_dir(Some(&loaded));
        let (registry, _) = crate::registry_with_plugins(dir.as_deref(), self.plugins);
        let is_cancelled = || cancel.is_cancelled();
        let mut hooks = BakeHooks {
            cancelled: Some(&is_cancelled),
            ..BakeHooks::default()
        };
        match bake(&registry, &loaded, &mut hooks) {
            Ok(outcome) => {
                let frames = outcome.report.frames.len();
                let nodes: usize = outcome.report.bodies.iter().map(|b| b.nodes).sum();
                let inverted = outcome
                    .report
                    .frames
                    .iter()
                    .map(|f| f.inverted_cells)
                    .max()
                    .unwrap_or(0);
                Ok(RunSummary {
                    frames: frames as u32,
                    outputs: outcome.outputs,
                    message: format!(
                        "{} bodies, {nodes} nodes, simulate {:.2} s, max inverted cells {inverted}",
                        outcome.report.bodies.len(),
                        outcome.report.seconds.simulate
                    ),
                })
            }
            Err(e) if e.is_cancelled() => Err(JobError::Cancelled),
            Err(e) => Err(JobError::failed(e)),
        }
    }
}
