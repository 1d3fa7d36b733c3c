//! The buffers' records as the shader declares them (`xpbd.wgsl`), and their packing from a
//! [`DeviceModel`]: the one place where the host's and the shader's layouts must agree.

use bytemuck::{Pod, Zeroable};
use springbake_core::nalgebra::Vector3;
use springbake_core::solver::device::DeviceModel;

/// Nodes per reduction chunk (the shader's `CHUNK`).
pub const CHUNK: u32 = 1024;
/// Threads per workgroup (every entry point's `@workgroup_size`).
pub const WORKGROUP: u32 = 64;
/// Most planes the shader's parameters hold.
pub const MAX_PLANES: usize = 8;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Params {
    pub gravity: [f32; 4],
    pub dt: f32,
    pub inv_dt: f32,
    pub inv_dt2: f32,
    pub friction: f32,
    pub node_count: u32,
    pub plane_count: u32,
    pub body_count: u32,
    pub group_offset: u32,
    pub capsule_count: u32,
    pub point_count: u32,
    pub push_chunks: u32,
    /// Cells in all, for the frame's census.
    pub cell_count: u32,
    pub planes: [[f32; 4]; MAX_PLANES],
}

/// A capsule at a substep's end and start (the shader's `Capsule`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Capsule {
    pub centre: [f32; 4],
    pub axis: [f32; 4],
    pub before_centre: [f32; 4],
    pub before_axis: [f32; 4],
}

impl Capsule {
    pub fn pack(
        (now, before): &(
            springbake_core::solver::Capsule,
            springbake_core::solver::Capsule,
        ),
    ) -> Capsule {
        let v = |v: &Vector3<f64>, w: f64| [v.x as f32, v.y as f32, v.z as f32, w as f32];
        Capsule {
            centre: v(&now.centre, now.radius),
            axis: v(&now.axis, now.length),
            before_centre: v(&before.centre, now.friction),
            before_axis: v(&before.axis, 0.0),
        }
    }
}

/// Slots of the shader's `push` per chunk (its `PUSH_CHUNK`).
pub const PUSH_CHUNK: u32 = 1024;
/// Most substeps in one output frame (the per-substep uniforms and totals are sized for it).
pub const MAX_SUBSTEPS: u32 = 4096;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Node {
    pub mass: f32,
    pub inv_mass: f32,
    /// Bit 0: pinned; bit 1: takes rigid contacts itself.
    pub flags: u32,
    pub body: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Cell {
    pub nodes: [u32; 8],
    pub inv_h: f32,
    /// < 0: no volume constraint.
    pub hydro: f32,
    pub dev: f32,
    pub odd: u32,
    pub axis: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Point {
    pub nodes: [u32; 8],
    pub weights: [f32; 8],
    pub reach: f32,
    pub pad: [f32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Body {
    pub reference: [f32; 4],
    pub start: u32,
    pub end: u32,
    pub damping: f32,
    pub cancel: u32,
    pub chunk_start: u32,
    pub chunk_end: u32,
    pub pad: [u32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Chunk {
    pub body: u32,
    pub start: u32,
    pub end: u32,
    pub pad: u32,
}

/// Bytes of one `Sums` or `BodyOut` record.
pub const SIXTEEN_FLOATS: u64 = 64;

fn f4(v: [f64; 3]) -> [f32; 4] {
    [v[0] as f32, v[1] as f32, v[2] as f32, 0.0]
}

/// The model's records, ready to upload.
pub struct Packed {
    pub x: Vec<[f32; 4]>,
    pub v: Vec<[f32; 4]>,
    pub nodes: Vec<Node>,
    pub pins: Vec<[f32; 4]>,
    pub cells: Vec<Cell>,
    pub points: Vec<Point>,
    /// The points' order, then each group's `[start, end)` (from `params.group_offset`).
    pub index: Vec<u32>,
    pub bodies: Vec<Body>,
    pub chunks: Vec<Chunk>,
}

pub fn pack(model: &DeviceModel) -> Packed {
    let n = model.position.len();
    let mut body_of = vec![0u32; n];
    for (b, body) in model.bodies.iter().enumerate() {
        for i in body.nodes.clone() {
            body_of[i as usize] = b as u32;
        }
    }
    let nodes = (0..n)
        .map(|i| Node {
            mass: model.mass[i] as f32,
            inv_mass: model.inv_mass[i] as f32,
            flags: u32::from(model.pin[i].is_some()) | (u32::from(model.node_contact[i]) << 1),
            body: body_of[i],
        })
        .collect();
    let cells = model
        .cells
        .iter()
        .map(|c| Cell {
            nodes: c.nodes,
            inv_h: c.inv_h as f32,
            hydro: c.volume_compliance.map_or(-1.0, |a| a as f32),
            dev: c.shear_compliance as f32,
            odd: u32::from(c.odd),
            axis: f4(c.axis_root),
        })
        .collect();
    let points = (0..model.point_nodes.len())
        .map(|i| Point {
            nodes: model.point_nodes[i],
            weights: model.point_weights[i].map(|w| w as f32),
            reach: model.point_reach[i] as f32,
            pad: [0.0; 3],
        })
        .collect();
    let mut index = model.point_order.clone();
    for g in &model.point_groups {
        index.extend([g.start, g.end]);
    }
    if index.is_empty() {
        index.push(0);
    }
    let (mut bodies, mut chunks) = (Vec::new(), Vec::new());
    for (b, body) in model.bodies.iter().enumerate() {
        let chunk_start = chunks.len() as u32;
        let mut start = body.nodes.start;
        while start < body.nodes.end {
            let end = (start + CHUNK).min(body.nodes.end);
            chunks.push(Chunk {
                body: b as u32,
                start,
                end,
                pad: 0,
            });
            start = end;
        }
        bodies.push(Body {
            reference: [0.0; 4],
            start: body.nodes.start,
            end: body.nodes.end,
            damping: body.damping_rate as f32,
            cancel: u32::from(body.cancel_torque),
            chunk_start,
            chunk_end: chunks.len() as u32,
            pad: [0; 2],
        });
    }
    Packed {
        x: model.position.iter().map(|&p| f4(p)).collect(),
        v: model.velocity.iter().map(|&p| f4(p)).collect(),
        nodes,
        pins: model
            .pin
            .iter()
            .map(|p| f4(p.unwrap_or([0.0; 3])))
            .collect(),
        cells,
        points,
        index,
        bodies,
        chunks,
    }
}

/// Each body's mean node position (the shader's reference point for its sums, so they are
/// taken near the body and keep f32's precision).
pub fn references(bodies: &mut [Body], x: &[Vector3<f64>]) {
    for body in bodies {
        let range = body.start as usize..body.end as usize;
        let count = range.len().max(1) as f64;
        let mean = x[range].iter().sum::<Vector3<f64>>() / count;
        body.reference = [mean.x as f32, mean.y as f32, mean.z as f32, 0.0];
    }
}
