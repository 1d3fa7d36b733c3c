//! Where a bake's solver runs (`[solver] device`, `--device`): on the CPU, or on a GPU through
//! `springbake-gpu` (the XPBD substep as wgpu compute shaders). `auto` takes a hardware GPU for
//! worlds of at least [`AUTO_MIN_NODES`] nodes when the scene uses only what the GPU solver
//! runs, and says why it did not otherwise; `gpu` insists, and names what is missing (exit 2);
//! `cpu` never looks for an adapter.

use crate::PipelineError;
use springbake_core::scene::{DeviceSpec, SceneFile};
use springbake_core::solver::World;

/// Fewest nodes for which `auto` takes a GPU (32³: below it the CPU's few milliseconds a frame
/// are not worth the upload and the adapter's start-up).
pub const AUTO_MIN_NODES: usize = 32_768;

/// Where a bake's solver runs, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// "cpu", or the GPU adapter's name and backend.
    pub name: String,
    pub reason: String,
}

impl Placement {
    /// One line for the log.
    pub fn describe(&self) -> String {
        format!("solver on {}: {}", self.name, self.reason)
    }

    fn cpu(reason: String) -> Result<Placement, PipelineError> {
        Ok(Placement {
            name: "cpu".into(),
            reason,
        })
    }
}

/// Choose the device for `world` (set up from `scene`; `has_events`: the scene has events or
/// attachments, which act between frames through the CPU's contact log) and attach a GPU
/// solver to it when one is chosen.
pub fn place(
    scene: &SceneFile,
    world: &mut World,
    has_events: bool,
) -> Result<Placement, PipelineError> {
    let spec = scene.solver.device;
    let insisted = spec == DeviceSpec::Gpu;
    let refuse = |why: String| {
        if insisted {
            Err(PipelineError::Usage(format!(
                "[solver] device = \"gpu\": {why}; use device = \"auto\" or \"cpu\""
            )))
        } else {
            Placement::cpu(why)
        }
    };
    if spec == DeviceSpec::Cpu {
        return Placement::cpu("[solver] device = \"cpu\"".into());
    }
    let nodes = world.nodes.len();
    if spec == DeviceSpec::Auto && nodes < AUTO_MIN_NODES {
        return Placement::cpu(format!(
            "{nodes} nodes (device = \"auto\" takes a GPU from {AUTO_MIN_NODES})"
        ));
    }
    let model = if has_events {
        Err("events and attachments".to_string())
    } else {
        world.device_model()
    };
    let model = match model {
        Ok(model) => model,
        Err(feature) => return refuse(format!("the GPU solver does not run {feature}")),
    };
    if spec == DeviceSpec::Auto {
        match springbake_gpu::probe() {
            Ok(adapter) if adapter.software => {
                return Placement::cpu(format!(
                    "the only GPU adapter is a software one ({}), slower than the CPU solver",
                    adapter.name
                ))
            }
            Ok(_) => {}
            Err(e) => return Placement::cpu(e.to_string()),
        }
    }
    match springbake_gpu::GpuSolver::new(&model) {
        Ok(solver) => {
            let name = solver.summary().name.clone();
            world.attach_device(Box::new(solver));
            Ok(Placement {
                name,
                reason: format!("{nodes} nodes, device = \"{}\"", spec.name()),
            })
        }
        Err(e) => refuse(e.to_string()),
    }
}
