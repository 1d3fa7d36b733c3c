//! Where a GPU substep's time goes: each stage of [`GpuSolver::stages`] recorded in its own
//! compute pass between two timestamp queries, for the benchmark (`examples/gpu_bench.rs
//! --profile`). Needs an adapter with timestamp queries (NVIDIA, AMD and Intel drivers have
//! them; lavapipe too).

use crate::GpuSolver;

/// Timestamps one query set holds (wgpu's limit).
const MAX_QUERIES: u32 = wgpu::QUERY_SET_MAX_QUERIES;

impl GpuSolver {
    /// Seconds per substep of each stage (by name, in the substep's order), averaged over up
    /// to `substeps` substeps replayed from the state the last frame left (the solver's next
    /// frame uploads its own state, so this changes no result). Each stage is its own pass
    /// here, so the total exceeds a batched frame's by a pass's start per stage.
    pub fn profile(&mut self, substeps: u32) -> Result<Vec<(&'static str, f64)>, String> {
        if !self
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
        {
            return Err(format!("{} has no timestamp queries", self.adapter.name));
        }
        let stages = self.stages();
        let per_substep = 2 * stages.len() as u32;
        let substeps = substeps.clamp(1, MAX_QUERIES / per_substep);
        let count = per_substep * substeps;
        let queries = self.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("stage timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count,
        });
        let buffer = |usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: 8 * u64::from(count),
                usage,
                mapped_at_creation: false,
            })
        };
        let resolved = buffer(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC);
        let readback = buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("profile"),
            });
        let mut index = 0;
        for k in 0..substeps {
            for stage in &stages {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(stage.0),
                    timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                        query_set: &queries,
                        beginning_of_pass_write_index: Some(index),
                        end_of_pass_write_index: Some(index + 1),
                    }),
                });
                pass.set_bind_group(0, &self.state, &[]);
                pass.set_bind_group(2, &self.steps, &[k * self.step_align]);
                self.record(&mut pass, &stage.1);
                index += 2;
            }
        }
        encoder.resolve_query_set(&queries, 0..count, &resolved, 0);
        encoder.copy_buffer_to_buffer(&resolved, 0, &readback, 0, 8 * u64::from(count));
        self.queue.submit([encoder.finish()]);
        self.map_read(&readback)?;
        let ticks: Vec<u64> = {
            let view = readback.get_mapped_range(..).map_err(|e| e.to_string())?;
            bytemuck::cast_slice(&view[..]).to_vec()
        };
        self.failure()?;
        let seconds_per_tick = f64::from(self.queue.get_timestamp_period()) * 1e-9;
        let mut totals: Vec<(&'static str, f64)> = stages.iter().map(|s| (s.0, 0.0)).collect();
        for (k, pair) in ticks.chunks_exact(2).enumerate() {
            let spent = pair[1].saturating_sub(pair[0]) as f64 * seconds_per_tick;
            totals[k % stages.len()].1 += spent / f64::from(substeps);
        }
        Ok(totals)
    }
}
