//! springbake's GPU backend: the small-step XPBD substep of `springbake_core::solver::xpbd` as
//! wgpu compute shaders (`xpbd.wgsl`: WGSL, so Vulkan, Metal and DX12 alike; Mesa's lavapipe
//! runs it on a machine without a GPU). A [`GpuSolver`] is built from a world's
//! [`DeviceModel`] and attached to the world, which then hands it each output frame's
//! substeps (see `springbake_core::solver::device`). The lattice's fixed colouring becomes
//! one dispatch per colour; per-body sums are fixed-tree reductions over fixed chunks; the
//! state is read back once per output frame.

mod layout;
mod profile;

pub use layout::MAX_SUBSTEPS;

use bytemuck::cast_slice as bytes;
use layout::{Body, Packed, Params, MAX_PLANES, PUSH_CHUNK, SIXTEEN_FLOATS, WORKGROUP};
use rayon::prelude::*;
use springbake_core::nalgebra::Vector3;
use springbake_core::solver::device::{
    DeviceCensus, DeviceFrame, DeviceModel, DeviceSolver, DeviceTotals,
};
use springbake_core::solver::Capsule;
use wgpu::util::DeviceExt;

/// Substeps recorded in one compute pass.
const SUBSTEPS_PER_PASS: u32 = 64;

/// Why there is no GPU solver.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found (wgpu found no Vulkan, Metal or DX12 device; on Linux without a \
         GPU, Mesa's software driver lavapipe provides one: apt-get install mesa-vulkan-drivers)"
    )]
    NoAdapter,
    #[error("the GPU adapter {adapter} cannot run the solver: {reason}")]
    Unsuitable { adapter: String, reason: String },
    #[error("the world has more than {MAX_PLANES} floor and wall planes")]
    TooManyPlanes,
}

/// What [`probe`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct AdapterSummary {
    /// Name and backend, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan)".
    pub name: String,
    /// A software rasteriser on the CPU (lavapipe, WARP, SwiftShader).
    pub software: bool,
}

fn request_adapter() -> Result<(wgpu::Instance, wgpu::Adapter), GpuError> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let options = wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    };
    let adapter =
        pollster::block_on(instance.request_adapter(&options)).map_err(|_| GpuError::NoAdapter)?;
    Ok((instance, adapter))
}

fn summary(adapter: &wgpu::Adapter) -> AdapterSummary {
    let info = adapter.get_info();
    AdapterSummary {
        name: format!("{} ({:?})", info.name, info.backend),
        software: info.device_type == wgpu::DeviceType::Cpu,
    }
}

/// The adapter a [`GpuSolver`] would run on, if there is one.
pub fn probe() -> Result<AdapterSummary, GpuError> {
    request_adapter().map(|(_, adapter)| summary(&adapter))
}

/// One dispatch of a substep: its entry point, the colour span it covers (bind group 1's
/// offset), its workgroups.
struct Dispatch<'a> {
    pipeline: &'a wgpu::ComputePipeline,
    span: Option<u32>,
    groups: u32,
}

/// A stage of the substep (named as [`GpuSolver::profile`] reports it) and its dispatches.
struct Stage<'a>(&'static str, Vec<Dispatch<'a>>);

/// The shader's entry points.
struct Pipelines {
    predict: wgpu::ComputePipeline,
    solve_cells: wgpu::ComputePipeline,
    torque_sums: wgpu::ComputePipeline,
    torque_finish: wgpu::ComputePipeline,
    torque_apply: wgpu::ComputePipeline,
    contact_nodes: wgpu::ComputePipeline,
    contact_points: wgpu::ComputePipeline,
    barrier_cells: wgpu::ComputePipeline,
    velocities: wgpu::ComputePipeline,
    damp_sums: wgpu::ComputePipeline,
    damp_finish: wgpu::ComputePipeline,
    damp_apply: wgpu::ComputePipeline,
    push_sums: wgpu::ComputePipeline,
    push_finish: wgpu::ComputePipeline,
    cell_census: wgpu::ComputePipeline,
}

/// The XPBD substep on a GPU (module docs).
pub struct GpuSolver {
    adapter: AdapterSummary,
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipelines: Pipelines,
    state: wgpu::BindGroup,
    spans: wgpu::BindGroup,
    /// Each substep's index, at `step_align` bytes apart.
    steps: wgpu::BindGroup,
    step_align: u32,
    /// Slots of `push` for the nodes and points.
    push_slots: u32,
    /// Byte offset of each span in the span buffer: the cells' colours, then the points'.
    span_offsets: Vec<u32>,
    /// Cells or point groups in each span.
    span_sizes: Vec<u32>,
    cell_colours: usize,
    params_buffer: wgpu::Buffer,
    params: Params,
    buffers: Buffers,
    state_layout: wgpu::BindGroupLayout,
    bodies: Vec<Body>,
    chunk_count: u32,
    staging: wgpu::Buffer,
    has_points: bool,
    /// Each node's inverse mass: `base`'s `w`.
    inv_mass: Vec<f32>,
    /// The frame's positions and velocities in f32 on their way up, kept between frames (a
    /// fresh 64 MB a frame at 128³ cost the host its pages' zeroing every frame).
    upload: (Vec<[f32; 4]>, Vec<[f32; 4]>),
    /// Errors wgpu reported outside a call's result (its default is to panic).
    errors: std::sync::Arc<std::sync::Mutex<Option<String>>>,
}

const STORAGE_BINDINGS: [(u32, bool); 19] = [
    (1, false),
    (2, false),
    (3, false),
    (4, false),
    (5, true),
    (6, true),
    (7, false),
    (8, true),
    (9, true),
    (10, true),
    (11, true),
    (12, true),
    (13, false),
    (14, false),
    (15, false),
    (16, true),
    (17, true),
    (18, false),
    (19, false),
];

fn storage(device: &wgpu::Device, label: &str, contents: &[u8]) -> wgpu::Buffer {
    // A binding may not be empty.
    let zero = [0u8; 16];
    let contents = if contents.is_empty() {
        &zero[..]
    } else {
        contents
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
    })
}

fn groups(count: u32) -> u32 {
    count.div_ceil(WORKGROUP)
}

impl GpuSolver {
    /// Upload `model` to the best adapter there is.
    pub fn new(model: &DeviceModel) -> Result<GpuSolver, GpuError> {
        if model.planes.len() > MAX_PLANES {
            return Err(GpuError::TooManyPlanes);
        }
        let (_instance, adapter) = request_adapter()?;
        let summary = summary(&adapter);
        let unsuitable = |reason: String| GpuError::Unsuitable {
            adapter: summary.name.clone(),
            reason,
        };
        let limits = adapter.limits();
        if limits.max_storage_buffers_per_shader_stage < STORAGE_BINDINGS.len() as u32 {
            return Err(unsuitable(format!(
                "it binds {} storage buffers per stage, the solver needs {}",
                limits.max_storage_buffers_per_shader_stage,
                STORAGE_BINDINGS.len()
            )));
        }
        let node_count = model.position.len() as u32;
        let most = [
            node_count,
            model.cells.len() as u32,
            model.point_groups.len() as u32,
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        if groups(most) > limits.max_compute_workgroups_per_dimension {
            return Err(unsuitable(format!(
                "{most} nodes or cells need more workgroups than its {} per dispatch",
                limits.max_compute_workgroups_per_dimension
            )));
        }
        let bodies = model.bodies.len() as u32;
        if bodies > limits.max_compute_workgroups_per_dimension {
            return Err(unsuitable(format!(
                "{bodies} bodies need more workgroups than its {} per dispatch",
                limits.max_compute_workgroups_per_dimension
            )));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("springbake xpbd"),
            required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| unsuitable(e.to_string()))?;
        let errors = std::sync::Arc::new(std::sync::Mutex::new(None));
        let sink = errors.clone();
        device.on_uncaptured_error(std::sync::Arc::new(move |e: wgpu::Error| {
            if let Ok(mut slot) = sink.lock() {
                slot.get_or_insert_with(|| e.to_string());
            }
        }));
        let packed = layout::pack(model);
        let spans: Vec<(u32, u32)> = model
            .cell_colours
            .iter()
            .chain(&model.point_colours)
            .map(|r| (r.start, r.end))
            .collect();
        let align = limits.min_uniform_buffer_offset_alignment.max(8);
        let mut params = Params {
            gravity: [
                model.gravity[0] as f32,
                model.gravity[1] as f32,
                model.gravity[2] as f32,
                0.0,
            ],
            dt: 0.0,
            inv_dt: 0.0,
            inv_dt2: 0.0,
            friction: model.friction as f32,
            node_count,
            plane_count: model.planes.len() as u32,
            body_count: packed.bodies.len() as u32,
            group_offset: model.point_order.len() as u32,
            capsule_count: 0,
            point_count: model.point_nodes.len() as u32,
            push_chunks: 0,
            cell_count: model.cells.len() as u32,
            planes: [[0.0; 4]; MAX_PLANES],
        };
        for (k, (n, offset)) in model.planes.iter().enumerate() {
            params.planes[k] = [n[0] as f32, n[1] as f32, n[2] as f32, *offset as f32];
        }
        let params_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        params.push_chunks = (node_count + model.point_nodes.len() as u32).div_ceil(PUSH_CHUNK);
        let buffers = Buffers::upload(&device, &packed, params.push_chunks);
        let (state_layout, span_layout) = bind_group_layouts(&device);
        let state = buffers.bind_group(&device, &state_layout, &params_buffer);
        let span_values: Vec<[u32; 2]> = spans.iter().map(|&(a, b)| [a, b]).collect();
        let spans_group = offset_table(&device, &span_layout, "spans", &span_values, align);
        let step_values: Vec<[u32; 2]> = (0..MAX_SUBSTEPS).map(|k| [k, 0]).collect();
        let steps = offset_table(&device, &span_layout, "substeps", &step_values, align);
        let pipelines = build_pipelines(&device, &state_layout, &span_layout);
        let push_slots = node_count + model.point_nodes.len() as u32;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: 3 * 16 * u64::from(node_count.max(1))
                + 16
                + 16 * u64::from(MAX_SUBSTEPS)
                + 2 * 16 * u64::from(groups(model.cells.len() as u32)),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        if let Some(error) = errors.lock().ok().and_then(|mut e| e.take()) {
            return Err(unsuitable(error));
        }
        Ok(GpuSolver {
            errors,
            adapter: summary,
            device,
            queue,
            pipelines,
            state,
            spans: spans_group,
            steps,
            step_align: align,
            push_slots,

            span_offsets: (0..spans.len() as u32).map(|k| k * align).collect(),
            span_sizes: spans.iter().map(|(start, end)| end - start).collect(),
            cell_colours: model.cell_colours.len(),
            params_buffer,
            params,
            buffers,
            state_layout,
            bodies: packed.bodies,
            chunk_count: packed.chunks.len() as u32,
            staging,
            has_points: !model.point_order.is_empty(),
            inv_mass: packed.nodes.iter().map(|n| n.inv_mass).collect(),
            upload: (Vec::new(), Vec::new()),
        })
    }

    /// Map `buffer` for reading once the work submitted so far has run.
    fn map_read(&self, buffer: &wgpu::Buffer) -> Result<(), String> {
        let (sender, receiver) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| drop(sender.send(r)));
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .map_err(|e| e.to_string())?;
        receiver
            .recv()
            .map_err(|e| e.to_string())?
            .map_err(|e| e.to_string())
    }

    /// The first error the device reported (wgpu's validation, lost device, out of memory).
    fn failure(&self) -> Result<(), String> {
        match self.errors.lock().map(|mut e| e.take()) {
            Ok(Some(error)) => Err(error),
            _ => Ok(()),
        }
    }

    /// The adapter this solver runs on.
    pub fn summary(&self) -> &AdapterSummary {
        &self.adapter
    }

    /// One substep's stages in the CPU's order, each a name and its dispatches (the same for
    /// every substep of a batch: only the substep's index, bind group 2, changes).
    fn stages(&self) -> Vec<Stage<'_>> {
        let p = &self.pipelines;
        let whole = |pipeline, groups| Dispatch {
            pipeline,
            span: None,
            groups,
        };
        let nodes = groups(self.params.node_count);
        let spans = |pipeline, colours: &mut dyn Iterator<Item = (usize, u32)>| {
            colours
                .map(|(k, count)| Dispatch {
                    pipeline,
                    span: Some(self.span_offsets[k]),
                    groups: groups(count),
                })
                .collect::<Vec<_>>()
        };
        let mut stages = vec![
            Stage("predict", vec![whole(&p.predict, nodes)]),
            Stage("cells", spans(&p.solve_cells, &mut self.cell_counts())),
            Stage("torque sums", vec![whole(&p.torque_sums, self.chunk_count)]),
            Stage(
                "torque finish",
                vec![whole(&p.torque_finish, self.params.body_count)],
            ),
            Stage("torque apply", vec![whole(&p.torque_apply, nodes)]),
        ];
        if self.params.plane_count > 0 || self.params.capsule_count > 0 {
            stages.push(Stage("contact nodes", vec![whole(&p.contact_nodes, nodes)]));
            if self.has_points {
                let points = spans(&p.contact_points, &mut self.point_counts());
                stages.push(Stage("contact points", points));
            }
            if self.params.capsule_count > 0 {
                let sums = whole(&p.push_sums, self.params.push_chunks);
                stages.push(Stage("capsule push", vec![sums, whole(&p.push_finish, 1)]));
            }
            let barrier = spans(&p.barrier_cells, &mut self.cell_counts());
            stages.push(Stage("barrier", barrier));
        }
        stages.extend([
            Stage("velocities", vec![whole(&p.velocities, nodes)]),
            Stage("damp sums", vec![whole(&p.damp_sums, self.chunk_count)]),
            Stage(
                "damp finish",
                vec![whole(&p.damp_finish, self.params.body_count)],
            ),
            Stage("damp apply", vec![whole(&p.damp_apply, nodes)]),
        ]);
        stages
    }

    /// Record the cells' census into half `half` of its buffer (0: the energy's, taken before
    /// the last substep's contacts; 1: after the frame): the half is bind group 2's index,
    /// which the caller sets back for the stages after it.
    fn record_census(&self, pass: &mut wgpu::ComputePass<'_>, half: u32) {
        pass.set_bind_group(2, &self.steps, &[half * self.step_align]);
        let census = Dispatch {
            pipeline: &self.pipelines.cell_census,
            span: None,
            groups: groups(self.params.cell_count),
        };
        self.record(pass, &[census]);
    }

    /// Record `dispatches` into `pass` (bind groups 0 and 2 already set).
    fn record(&self, pass: &mut wgpu::ComputePass<'_>, dispatches: &[Dispatch<'_>]) {
        for d in dispatches.iter().filter(|d| d.groups > 0) {
            pass.set_pipeline(d.pipeline);
            pass.set_bind_group(1, &self.spans, &[d.span.unwrap_or(0)]);
            pass.dispatch_workgroups(d.groups, 1, 1);
        }
    }

    /// Write the frame's capsules (growing their buffer when a frame needs more) and their
    /// count per substep into the parameters.
    fn upload_capsules(&mut self, capsules: &[(Capsule, Capsule)], count: usize) {
        self.params.capsule_count = count as u32;
        if count == 0 {
            return;
        }
        let packed: Vec<layout::Capsule> = capsules.iter().map(layout::Capsule::pack).collect();
        let bytes_needed = std::mem::size_of_val(packed.as_slice()) as u64;
        if bytes_needed > self.buffers.capsules.size() {
            self.buffers.capsules = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("capsules"),
                size: bytes_needed.next_power_of_two(),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let b = &self.buffers;
            self.state = b.bind_group(&self.device, &self.state_layout, &self.params_buffer);
        }
        self.queue
            .write_buffer(&self.buffers.capsules, 0, bytes(&packed));
    }

    /// (span index, cell count) of each cells' colour.
    fn cell_counts(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        (0..self.cell_colours).map(|k| (k, self.span_sizes[k]))
    }

    /// (span index, group count) of each points' colour.
    fn point_counts(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        (self.cell_colours..self.span_sizes.len()).map(|k| (k, self.span_sizes[k]))
    }
}

impl DeviceSolver for GpuSolver {
    fn adapter(&self) -> &str {
        &self.adapter.name
    }

    fn advance(&mut self, frame: DeviceFrame<'_>) -> Result<DeviceTotals, String> {
        let DeviceFrame {
            substeps,
            dt,
            position,
            velocity,
            capsules,
            capsule_count,
        } = frame;
        if position.len() != self.params.node_count as usize {
            return Err("the world's node count changed".into());
        }
        // At most MAX_SUBSTEPS at a time (the viewer's live mode may ask for thousands).
        let mut totals = DeviceTotals::default();
        let mut done = 0;
        while done < substeps {
            let batch = (substeps - done).min(MAX_SUBSTEPS);
            let from = done as usize * capsule_count;
            let to = (done + batch) as usize * capsule_count;
            let part = self.advance_batch(
                batch,
                dt,
                position,
                velocity,
                &capsules[from..to],
                capsule_count,
            )?;
            totals.max_depth = totals.max_depth.max(part.max_depth);
            totals.capsule_force += part.capsule_force;
            totals.capsule_work += part.capsule_work;
            totals.census = part.census;
            done += batch;
        }
        Ok(totals)
    }
}

impl GpuSolver {
    /// Up to [`MAX_SUBSTEPS`] substeps in one submission, read back at the end.
    fn advance_batch(
        &mut self,
        substeps: u32,
        dt: f64,
        position: &mut [Vector3<f64>],
        velocity: &mut [Vector3<f64>],
        capsules: &[(Capsule, Capsule)],
        capsule_count: usize,
    ) -> Result<DeviceTotals, String> {
        self.upload_capsules(capsules, capsule_count);
        // On the pool: at 2 M nodes each of these passes is tens of milliseconds on one core.
        let (base, vel) = &mut self.upload;
        base.resize(position.len(), [0.0; 4]);
        vel.resize(velocity.len(), [0.0; 4]);
        (base
            .par_iter_mut()
            .zip(position.par_iter())
            .zip(&self.inv_mass[..]))
        .for_each(|((b, v), &w)| *b = [v.x as f32, v.y as f32, v.z as f32, w]);
        (vel.par_iter_mut().zip(velocity.par_iter()))
            .for_each(|(b, v)| *b = [v.x as f32, v.y as f32, v.z as f32, 0.0]);
        self.queue.write_buffer(&self.buffers.base, 0, bytes(base));
        self.queue.write_buffer(&self.buffers.v, 0, bytes(vel));
        self.params.dt = dt as f32;
        self.params.inv_dt = (1.0 / dt) as f32;
        self.params.inv_dt2 = (1.0 / (dt * dt)) as f32;
        self.queue
            .write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&self.params));
        layout::references(&mut self.bodies, position);
        self.queue
            .write_buffer(&self.buffers.bodies, 0, bytemuck::cast_slice(&self.bodies));
        self.queue.write_buffer(&self.buffers.depth, 0, &[0u8; 4]);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        encoder.clear_buffer(&self.buffers.x, 0, None);
        encoder.clear_buffer(&self.buffers.prev, 0, None);
        let stages = self.stages();
        // The census's energy half is taken in the last substep before its contact stages
        // (the cells as the elastic solve left them, as the CPU's `Model::elastic_energy`
        // reads them); the other half (inverted cells, least ratio) after the frame.
        let census_groups = groups(self.params.cell_count);
        let before_contact = (stages.iter())
            .position(|s| s.0.starts_with("contact"))
            .unwrap_or(stages.len());
        let (elastic, contacts) = stages.split_at(before_contact);
        for first in (0..substeps).step_by(SUBSTEPS_PER_PASS as usize) {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("substeps"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, &self.state, &[]);
            for k in first..(first + SUBSTEPS_PER_PASS).min(substeps) {
                pass.set_bind_group(2, &self.steps, &[k * self.step_align]);
                for stage in elastic {
                    self.record(&mut pass, &stage.1);
                }
                if k + 1 == substeps {
                    self.record_census(&mut pass, 0);
                    pass.set_bind_group(2, &self.steps, &[k * self.step_align]);
                }
                for stage in contacts {
                    self.record(&mut pass, &stage.1);
                }
            }
        }
        if census_groups > 0 {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("census"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, &self.state, &[]);
            self.record_census(&mut pass, 1);
        }
        let n = u64::from(self.params.node_count);
        encoder.copy_buffer_to_buffer(&self.buffers.prev, 0, &self.staging, 0, 16 * n);
        encoder.copy_buffer_to_buffer(&self.buffers.x, 0, &self.staging, 16 * n, 16 * n);
        encoder.copy_buffer_to_buffer(&self.buffers.v, 0, &self.staging, 32 * n, 16 * n);
        encoder.copy_buffer_to_buffer(&self.buffers.depth, 0, &self.staging, 48 * n, 4);
        let totals_at = 16 * u64::from(self.push_slots + self.params.push_chunks);
        let totals_bytes = 16 * u64::from(substeps);
        if self.params.capsule_count > 0 && totals_bytes > 0 {
            let to = 48 * n + 16;
            encoder.copy_buffer_to_buffer(
                &self.buffers.push,
                totals_at,
                &self.staging,
                to,
                totals_bytes,
            );
        }
        let census_at = 48 * n + 16 + 16 * u64::from(MAX_SUBSTEPS);
        let census_bytes = 2 * 16 * u64::from(census_groups);
        if census_bytes > 0 {
            encoder.copy_buffer_to_buffer(
                &self.buffers.census,
                0,
                &self.staging,
                census_at,
                census_bytes,
            );
        }
        self.queue.submit([encoder.finish()]);
        self.map_read(&self.staging)?;
        let depth = {
            let view = self
                .staging
                .get_mapped_range(..)
                .map_err(|e| e.to_string())?;
            let floats: &[[f32; 4]] = bytemuck::cast_slice(&view[..48 * n as usize]);
            let (travel, rest) = floats.split_at(n as usize);
            let (step, v) = rest.split_at(n as usize);
            let wide =
                |p: &[f32; 4]| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
            (position.par_iter_mut().zip(travel).zip(step))
                .for_each(|((x, a), b)| *x += wide(a) + wide(b));
            (velocity.par_iter_mut().zip(v)).for_each(|(x, d)| *x = wide(d));
            let at = 48 * n as usize;
            let bits = [view[at], view[at + 1], view[at + 2], view[at + 3]];
            let mut totals = DeviceTotals {
                max_depth: f64::from(f32::from_bits(u32::from_le_bytes(bits))),
                ..DeviceTotals::default()
            };
            if census_bytes > 0 {
                let range = census_at as usize..(census_at + census_bytes) as usize;
                totals.census = Some(census(
                    bytemuck::cast_slice(&view[range]),
                    self.params.cell_count,
                ));
            }
            if self.params.capsule_count > 0 {
                let sums: &[[f32; 4]] =
                    bytemuck::cast_slice(&view[at + 16..at + 16 + 16 * substeps as usize]);
                for p in sums {
                    totals.capsule_force += wide(p);
                    totals.capsule_work += f64::from(p[3]);
                }
            }
            totals
        };
        self.staging.unmap();
        self.failure()?;
        Ok(depth)
    }
}

/// The frame's census from its two halves of workgroups' (energy, least ratio, inverted, 0):
/// the energy from the first (taken before the last substep's contacts), the rest from the
/// second (after the frame), each added in workgroup order in f64.
fn census(halves: &[[f32; 4]], cells: u32) -> DeviceCensus {
    let (relaxed, after) = halves.split_at(halves.len() / 2);
    let mut c = DeviceCensus {
        cells: cells as usize,
        most_collapsed: f64::INFINITY,
        ..DeviceCensus::default()
    };
    for g in relaxed {
        c.elastic_energy += f64::from(g[0]);
    }
    for g in after {
        c.most_collapsed = c.most_collapsed.min(f64::from(g[1]));
        c.inverted_cells += g[2] as usize;
    }
    c
}

struct Buffers {
    x: wgpu::Buffer,
    prev: wgpu::Buffer,
    predicted: wgpu::Buffer,
    v: wgpu::Buffer,
    nodes: wgpu::Buffer,
    pins: wgpu::Buffer,
    moved: wgpu::Buffer,
    cells: wgpu::Buffer,
    points: wgpu::Buffer,
    index: wgpu::Buffer,
    bodies: wgpu::Buffer,
    chunks: wgpu::Buffer,
    sums: wgpu::Buffer,
    body_out: wgpu::Buffer,
    depth: wgpu::Buffer,
    base: wgpu::Buffer,
    capsules: wgpu::Buffer,
    push: wgpu::Buffer,
    census: wgpu::Buffer,
}

impl Buffers {
    fn upload(device: &wgpu::Device, p: &Packed, push_chunks: u32) -> Buffers {
        let push_slots = p.x.len() + p.points.len() + push_chunks as usize + MAX_SUBSTEPS as usize;
        let zeros = |n: usize| vec![0u8; n];
        Buffers {
            x: storage(device, "x", &zeros(16 * p.x.len())),
            prev: storage(device, "prev", &zeros(16 * p.x.len())),
            predicted: storage(device, "predicted", &zeros(16 * p.x.len())),
            v: storage(device, "v", bytes(&p.v)),
            nodes: storage(device, "nodes", bytes(&p.nodes)),
            pins: storage(device, "pins", bytes(&p.pins)),
            moved: storage(device, "moved", &zeros(4 * p.x.len())),
            cells: storage(device, "cells", bytes(&p.cells)),
            points: storage(device, "points", bytes(&p.points)),
            index: storage(device, "index", bytes(&p.index)),
            bodies: storage(device, "bodies", bytes(&p.bodies)),
            chunks: storage(device, "chunks", bytes(&p.chunks)),
            sums: storage(
                device,
                "sums",
                &zeros(SIXTEEN_FLOATS as usize * p.chunks.len()),
            ),
            body_out: storage(
                device,
                "body_out",
                &zeros(SIXTEEN_FLOATS as usize * p.bodies.len()),
            ),
            depth: storage(device, "depth", &zeros(4)),
            base: storage(device, "base", bytes(&p.x)),
            capsules: storage(device, "capsules", &zeros(64)),
            push: storage(device, "push", &zeros(16 * push_slots)),
            census: storage(
                device,
                "census",
                &zeros(2 * 16 * groups(p.cells.len() as u32) as usize),
            ),
        }
    }

    fn bind_group(
        &self,
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let order = [
            params,
            &self.x,
            &self.prev,
            &self.predicted,
            &self.v,
            &self.nodes,
            &self.pins,
            &self.moved,
            &self.cells,
            &self.points,
            &self.index,
            &self.bodies,
            &self.chunks,
            &self.sums,
            &self.body_out,
            &self.depth,
            &self.base,
            &self.capsules,
            &self.push,
            &self.census,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = order
            .iter()
            .enumerate()
            .map(|(k, buffer)| wgpu::BindGroupEntry {
                binding: k as u32,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("state"),
            layout,
            entries: &entries,
        })
    }
}

fn bind_group_layouts(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
    let entry = |binding: u32, ty: wgpu::BindingType| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty,
        count: None,
    };
    let uniform = |dynamic: bool| wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: dynamic,
        min_binding_size: None,
    };
    let mut entries = vec![entry(0, uniform(false))];
    entries.extend(STORAGE_BINDINGS.iter().map(|&(binding, read_only)| {
        entry(
            binding,
            wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
        )
    }));
    let state = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("state"),
        entries: &entries,
    });
    let span = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("span"),
        entries: &[entry(0, uniform(true))],
    });
    (state, span)
}

/// A uniform buffer of `values`, each at its own `align`-byte offset, and a bind group of
/// `layout` that binds one of them at a dynamic offset.
fn offset_table(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    values: &[[u32; 2]],
    align: u32,
) -> wgpu::BindGroup {
    let mut bytes = vec![0u8; align as usize * values.len().max(1)];
    for (k, v) in values.iter().enumerate() {
        let at = k * align as usize;
        bytes[at..at + 8].copy_from_slice(bytemuck::bytes_of(v));
    }
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &bytes,
        usage: wgpu::BufferUsages::UNIFORM,
    });
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &buffer,
                offset: 0,
                size: wgpu::BufferSize::new(8),
            }),
        }],
    })
}

fn build_pipelines(
    device: &wgpu::Device,
    state: &wgpu::BindGroupLayout,
    span: &wgpu::BindGroupLayout,
) -> Pipelines {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("xpbd.wgsl"),
        source: wgpu::ShaderSource::Wgsl(include_str!("xpbd.wgsl").into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("xpbd"),
        bind_group_layouts: &[Some(state), Some(span), Some(span)],
        immediate_size: 0,
    });
    let make = |entry: &str| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    };
    Pipelines {
        predict: make("predict"),
        solve_cells: make("solve_cells"),
        torque_sums: make("torque_sums"),
        torque_finish: make("torque_finish"),
        torque_apply: make("torque_apply"),
        contact_nodes: make("contact_nodes"),
        contact_points: make("contact_points"),
        barrier_cells: make("barrier_cells"),
        velocities: make("velocities"),
        damp_sums: make("damp_sums"),
        damp_finish: make("damp_finish"),
        damp_apply: make("damp_apply"),
        push_sums: make("push_sums"),
        push_finish: make("push_finish"),
        cell_census: make("cell_census"),
    }
}
