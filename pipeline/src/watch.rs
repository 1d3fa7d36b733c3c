//! The bake as a [`WatchJob`]: what `springbake watch` and the viewer's live reload drive.

use crate::{
    bake, default_scene_for_mesh, load_scene, BakeHooks, LoadedScene, MeshOverrides, PipelineError,
};
use springbake_core::plugin::Registry;
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

/// Re-bakes its input on every run.
pub struct BakeJob {
    pub registry: Registry,
    pub input: BakeInput,
}

impl WatchJob for BakeJob {
    fn watched_paths(&mut self) -> Vec<PathBuf> {
        match self.input.load() {
            Ok(loaded) => loaded.inputs(),
            // A broken scene: watch the scene file itself so fixing it triggers a run.
            Err(_) => match &self.input {
                BakeInput::Scene(p) | BakeInput::Mesh(p, _) => vec![p.clone()],
            },
        }
    }

    fn run(&mut self, cancel: &CancelToken) -> Result<RunSummary, JobError> {
        let loaded = self.input.load().map_err(JobError::failed)?;
        let is_cancelled = || cancel.is_cancelled();
        let mut hooks = BakeHooks {
            cancelled: Some(&is_cancelled),
            ..BakeHooks::default()
        };
        match bake(&self.registry, &loaded, &mut hooks) {
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
