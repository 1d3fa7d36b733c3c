// The small-step XPBD substep of springbake-core's `solver::xpbd`, stage for stage, in f32.
// One entry point per stage; the host dispatches them in the CPU's order.
//
// A node's position is kept in three parts, `base + prev + x`: `base` is where it was at the
// frame's start (from the host's f64 state), `prev` how far it had moved since by the
// substep's start, and `x` its move in this substep. The velocity is `x / Δt` and never
// loses the substep's move to f32's rounding of a whole coordinate (at 1 m and 720 substeps
// a second that rounding alone is 4e-5 m/s a substep, and it grows into position errors
// quadratically); the host adds `prev + x` to its f64 positions after the frame. A cell
// works on its nodes relative to its first node, a plane on a point's distance to it. Every pass writes
// disjoint slots (cells and point groups a colour at a time, reductions over fixed chunks in
// a fixed tree), so a run gives the same bits every time on one adapter.

struct Params {
    gravity: vec4<f32>,
    dt: f32,
    inv_dt: f32,
    inv_dt2: f32,
    friction: f32,
    node_count: u32,
    plane_count: u32,
    body_count: u32,
    group_offset: u32,
    capsule_count: u32,
    point_count: u32,
    // Chunks of PUSH_CHUNK slots over `push`'s node and point slots.
    push_chunks: u32,
    cell_count: u32,
    planes: array<vec4<f32>, 8>,
}

// A capsule manipulator at a substep's end (`centre.w` its radius, `axis.w` its length) and at
// its start (`before_centre.w` its friction).
struct Capsule {
    centre: vec4<f32>,
    axis: vec4<f32>,
    before_centre: vec4<f32>,
    before_axis: vec4<f32>,
}

struct Step {
    index: u32,
}

struct Span {
    start: u32,
    end: u32,
}

struct Node {
    mass: f32,
    inv_mass: f32,
    // bit 0: pinned; bit 1: takes rigid contacts itself.
    flags: u32,
    body: u32,
}

struct Cell {
    nodes: array<u32, 8>,
    inv_h: f32,
    // Compliances (multiplied by 1/Δt² here); the volume's is < 0 where there is none.
    hydro: f32,
    dev: f32,
    odd: u32,
    axis: vec4<f32>,
}

struct Point {
    nodes: array<u32, 8>,
    weights: array<f32, 8>,
    reach: f32,
    pad0: f32,
    pad1: f32,
    pad2: f32,
}

struct Body {
    reference: vec4<f32>,
    start: u32,
    end: u32,
    damping: f32,
    cancel: u32,
    chunk_start: u32,
    chunk_end: u32,
    pad0: u32,
    pad1: u32,
}

struct Chunk {
    body: u32,
    start: u32,
    end: u32,
    pad: u32,
}

// Sixteen partial sums of a chunk.
struct Sums {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
    d: vec4<f32>,
}

struct BodyOut {
    centre: vec4<f32>,
    // The centre relative to the body's reference point. Torque pass: the turn to remove;
    // damping pass: the angular velocity.
    turn: vec4<f32>,
    velocity: vec4<f32>,
    // x: 1 where the pass acts on the body.
    on: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> x: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> prev: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> predicted: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> vel: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> nodes: array<Node>;
@group(0) @binding(6) var<storage, read> pins: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> moved: array<u32>;
@group(0) @binding(8) var<storage, read> cells: array<Cell>;
@group(0) @binding(9) var<storage, read> points: array<Point>;
// The points' visiting order, then each group's [start, end) into it.
@group(0) @binding(10) var<storage, read> index: array<u32>;
@group(0) @binding(11) var<storage, read> bodies: array<Body>;
@group(0) @binding(12) var<storage, read> chunks: array<Chunk>;
@group(0) @binding(13) var<storage, read_write> sums: array<Sums>;
@group(0) @binding(14) var<storage, read_write> body_out: array<BodyOut>;
@group(0) @binding(15) var<storage, read_write> depth: array<atomic<u32>>;
// `w`: the node's inverse mass (the cells and points read it with the position, one load).
@group(0) @binding(16) var<storage, read> base: array<vec4<f32>>;
// Per substep, `capsule_count` capsules.
@group(0) @binding(17) var<storage, read> capsules: array<Capsule>;
// The capsules' push per node, then per point (force xyz, N; work w, J); then the chunks'
// sums; then each substep's total.
@group(0) @binding(18) var<storage, read_write> push: array<vec4<f32>>;
// The frame's census, per workgroup of cells: (elastic energy J, least corner volume ratio,
// inverted cells, 0); two halves, the one a census dispatch writes chosen by its bind group 2
// index (0: in the last substep before the contacts, 1: after the frame).
@group(0) @binding(19) var<storage, read_write> census: array<vec4<f32>>;
@group(1) @binding(0) var<uniform> span: Span;
@group(2) @binding(0) var<uniform> substep: Step;

const COLLAPSE_J: f32 = 0.2;
const WG: u32 = 64u;

fn good(d: f32) -> bool {
    // Positive and finite (3.4e38 is f32's largest).
    return d > 0.0 && d < 3.0e38;
}

// ---- Stage 1: prediction and pins ----------------------------------------------------------

@compute @workgroup_size(64)
fn predict(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.node_count {
        return;
    }
    let travel = prev[i].xyz + x[i].xyz;
    prev[i] = vec4<f32>(travel, 0.0);
    let node = nodes[i];
    var next = vec3<f32>(0.0);
    if node.mass > 0.0 {
        let v = vel[i].xyz + params.gravity.xyz * params.dt;
        vel[i] = vec4<f32>(v, 0.0);
        next = v * params.dt;
    }
    if (node.flags & 1u) != 0u {
        next = (pins[i].xyz - base[i].xyz) - travel;
    }
    x[i] = vec4<f32>(next, 0.0);
    predicted[i] = vec4<f32>(next, 0.0);
}

// ---- Stage 3: the cells' constraints (cells::solve_cell, lanes::solve_cubes) ---------------

var<private> lx: array<vec3<f32>, 8>;
var<private> lw: array<f32, 8>;
// Each local node's base and travel relative to the cell's first node's.
var<private> lrel: array<vec3<f32>, 8>;
// The cell's corrections of each local node: written back on their own, so a node's move in
// the substep is not rounded to the cell's size.
var<private> ldx: array<vec3<f32>, 8>;

fn move_node(k: u32, d: vec3<f32>) {
    lx[k] += d;
    ldx[k] += d;
}

fn signs(c: u32, inv_h: f32) -> vec3<f32> {
    return vec3<f32>(
        select(-inv_h, inv_h, (c & 1u) == 0u),
        select(-inv_h, inv_h, (c & 2u) == 0u),
        select(-inv_h, inv_h, (c & 4u) == 0u),
    );
}

// Six times the cell's Kuhn volume, d · S, and its gradient in closed form
// (solver::xpbd::cells::cube_volume): -S at node 0, S at node 7, the rest below.
fn six_volume_gradient() -> array<vec3<f32>, 8> {
    let d = lx[7] - lx[0];
    let u1 = lx[1] - lx[0];
    let u2 = lx[2] - lx[0];
    let u3 = lx[3] - lx[0];
    let u4 = lx[4] - lx[0];
    let u5 = lx[5] - lx[0];
    let u6 = lx[6] - lx[0];
    let a1 = u3 - u5;
    let a2 = u6 - u3;
    let a3 = u5 - u6;
    let s = cross(u1, a1) + cross(u2, a2) + cross(u4, a3);
    return array<vec3<f32>, 8>(
        -s,
        cross(a1, d),
        cross(a2, d),
        cross(d, u1 - u2),
        cross(a3, d),
        cross(d, u4 - u1),
        cross(d, u2 - u4),
        s,
    );
}

fn cube_volume_step(inv_v: f32, alpha: f32) {
    var grad = six_volume_gradient();
    let six_v = dot(lx[7] - lx[0], grad[7]);
    let sixth = 1.0 / 6.0;
    let value = six_v * sixth * inv_v - 1.0;
    var denominator = alpha;
    for (var k = 0u; k < 8u; k++) {
        grad[k] = grad[k] * sixth;
        denominator += lw[k] * dot(grad[k], grad[k]) * inv_v * inv_v;
    }
    if !good(denominator) {
        return;
    }
    let dl = -value / denominator * inv_v;
    for (var k = 0u; k < 8u; k++) {
        move_node(k, grad[k] * (lw[k] * dl));
    }
}

fn project_corner(c: u32, g: array<vec3<f32>, 3>, value: f32, alpha: f32) {
    let nb = vec3<u32>(c ^ 1u, c ^ 2u, c ^ 4u);
    let apex = -(g[0] + g[1] + g[2]);
    let denominator = alpha + lw[c] * dot(apex, apex) + lw[nb.x] * dot(g[0], g[0])
        + lw[nb.y] * dot(g[1], g[1]) + lw[nb.z] * dot(g[2], g[2]);
    if !good(denominator) {
        return;
    }
    let dl = -value / denominator;
    move_node(c, apex * (lw[c] * dl));
    move_node(nb.x, g[0] * (lw[nb.x] * dl));
    move_node(nb.y, g[1] * (lw[nb.y] * dl));
    move_node(nb.z, g[2] * (lw[nb.z] * dl));
}

fn shear(c: u32, inv_h: f32, alpha: f32, r: vec3<f32>) {
    let s = signs(c, inv_h);
    let f = array<vec3<f32>, 3>(
        (lx[c ^ 1u] - lx[c]) * s.x,
        (lx[c ^ 2u] - lx[c]) * s.y,
        (lx[c ^ 4u] - lx[c]) * s.z,
    );
    var we: array<vec3<f32>, 3>;
    var sum = 0.0;
    for (var j = 0u; j < 3u; j++) {
        for (var i = 0u; i < 3u; i++) {
            let e = 0.5 * (dot(f[i], f[j]) - select(0.0, 1.0, i == j));
            let w = e * r[i] * r[j];
            we[i][j] = w;
            sum += e * w;
        }
    }
    let value = sqrt(sum);
    if !(value > 1e-14) {
        return;
    }
    let inv = 1.0 / value;
    let g = array<vec3<f32>, 3>(
        (f[0] * we[0][0] + f[1] * we[1][0] + f[2] * we[2][0]) * inv * s.x,
        (f[0] * we[0][1] + f[1] * we[1][1] + f[2] * we[2][1]) * inv * s.y,
        (f[0] * we[0][2] + f[1] * we[1][2] + f[2] * we[2][2]) * inv * s.z,
    );
    project_corner(c, g, value, alpha);
}

fn barrier(c: u32, inv_h: f32) {
    let s = signs(c, inv_h);
    let f0 = (lx[c ^ 1u] - lx[c]) * s.x;
    let f1 = (lx[c ^ 2u] - lx[c]) * s.y;
    let f2 = (lx[c ^ 4u] - lx[c]) * s.z;
    let first = cross(f1, f2);
    let j = dot(f0, first);
    if j >= COLLAPSE_J {
        return;
    }
    let g = array<vec3<f32>, 3>(first * s.x, cross(f2, f0) * s.y, cross(f0, f1) * s.z);
    project_corner(c, g, j - COLLAPSE_J, 0.0);
}

fn load_cell(cell: Cell) {
    let first = cell.nodes[0];
    let origin = base[first].xyz;
    let travel = prev[first].xyz;
    for (var k = 0u; k < 8u; k++) {
        let n = cell.nodes[k];
        lrel[k] = (base[n].xyz - origin) + (prev[n].xyz - travel);
        lx[k] = lrel[k] + x[n].xyz;
        ldx[k] = vec3<f32>(0.0);
        lw[k] = base[n].w;
    }
}

fn store_cell(cell: Cell) {
    for (var k = 0u; k < 8u; k++) {
        let n = cell.nodes[k];
        x[n] = vec4<f32>(x[n].xyz + ldx[k], 0.0);
    }
}

@compute @workgroup_size(64)
fn solve_cells(@builtin(global_invocation_id) id: vec3<u32>) {
    let j = span.start + id.x;
    if j >= span.end {
        return;
    }
    let cell = cells[j];
    load_cell(cell);
    let inv_h = cell.inv_h;
    if cell.hydro >= 0.0 {
        cube_volume_step(inv_h * inv_h * inv_h, cell.hydro * params.inv_dt2);
    }
    let dev = cell.dev * params.inv_dt2;
    // Each parity's corners spelled out, so that every index into the cell's private arrays
    // is a constant once `shear` is inlined, not read from a vector chosen at run time (on an
    // H200: the cells' pass at 128³ 1.39 -> 1.34 ms a substep).
    let axis = cell.axis.xyz;
    if cell.odd != 0u {
        shear(1u, inv_h, dev, axis);
        shear(2u, inv_h, dev, axis);
        shear(4u, inv_h, dev, axis);
        shear(7u, inv_h, dev, axis);
    } else {
        shear(0u, inv_h, dev, axis);
        shear(3u, inv_h, dev, axis);
        shear(5u, inv_h, dev, axis);
        shear(6u, inv_h, dev, axis);
    }
    for (var c = 0u; c < 8u; c++) {
        barrier(c, inv_h);
    }
    store_cell(cell);
}

// ---- The frame's census, after its last substep (measures.rs and cells::energy) -----------

var<workgroup> census_scratch: array<vec4<f32>, 64>;

// Corner c's F: its three edges times s_k / h.
fn corner_f(c: u32, inv_h: f32) -> array<vec3<f32>, 3> {
    let s = signs(c, inv_h);
    return array<vec3<f32>, 3>(
        (lx[c ^ 1u] - lx[c]) * s.x,
        (lx[c ^ 2u] - lx[c]) * s.y,
        (lx[c ^ 4u] - lx[c]) * s.z,
    );
}

// Corner c's volume ratio det F.
fn corner_ratio(c: u32, inv_h: f32) -> f32 {
    let f = corner_f(c, inv_h);
    return dot(f[0], cross(f[1], f[2]));
}

// Σ r_i r_j E_ij² of corner c's Green strain (the shear constraint's value, squared).
fn strain_squared(c: u32, inv_h: f32, r: vec3<f32>) -> f32 {
    let f = corner_f(c, inv_h);
    var sum = 0.0;
    for (var j = 0u; j < 3u; j++) {
        for (var i = 0u; i < 3u; i++) {
            let e = 0.5 * (dot(f[i], f[j]) - select(0.0, 1.0, i == j));
            sum += e * e * r[i] * r[j];
        }
    }
    return sum;
}

fn cube_volume() -> f32 {
    return dot(lx[7] - lx[0], six_volume_gradient()[7]) / 6.0;
}

// Each cell's energy (½ C² / compliance for its volume and four shear corners), its least
// corner ratio and whether that is 0 or less; a workgroup's sum, minimum and count by a
// fixed tree.
@compute @workgroup_size(64)
fn cell_census(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) count: vec3<u32>,
) {
    var own = vec4<f32>(0.0, 3.0e38, 0.0, 0.0);
    if id.x < params.cell_count {
        let cell = cells[id.x];
        load_cell(cell);
        let inv_h = cell.inv_h;
        var energy = 0.0;
        if cell.hydro > 0.0 {
            let c_h = cube_volume() * inv_h * inv_h * inv_h - 1.0;
            energy += 0.5 * c_h * c_h / cell.hydro;
        }
        let r = cell.axis.xyz;
        var shear = 0.0;
        // The parity's corners: 0, 3, 5, 6 or 1, 2, 4, 7.
        var evens = array<u32, 4>(0u, 3u, 5u, 6u);
        for (var q = 0u; q < 4u; q++) {
            let even = evens[q];
            shear += strain_squared(select(even, 7u - even, cell.odd != 0u), inv_h, r);
        }
        if cell.dev > 0.0 {
            energy += 0.5 * shear / cell.dev;
        }
        var least = 3.0e38;
        for (var c = 0u; c < 8u; c++) {
            least = min(least, corner_ratio(c, inv_h));
        }
        own = vec4<f32>(energy, least, select(0.0, 1.0, least <= 0.0), 0.0);
    }
    census_scratch[lid.x] = own;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half = half / 2u) {
        if lid.x < half {
            let a = census_scratch[lid.x];
            let b = census_scratch[lid.x + half];
            census_scratch[lid.x] = vec4<f32>(a.x + b.x, min(a.y, b.y), a.z + b.z, 0.0);
        }
        workgroupBarrier();
    }
    if lid.x == 0u {
        census[substep.index * count.x + wg.x] = census_scratch[0];
    }
}

// ---- Stage 3c and 5b: per-body rigid motion over fixed chunks ------------------------------

var<workgroup> scratch: array<Sums, 64>;

fn add_sums(a: Sums, b: Sums) -> Sums {
    return Sums(a.a + b.a, a.b + b.b, a.c + b.c, a.d + b.d);
}

// The workgroup's `own` sums added by a fixed tree (every thread calls it; all get the sum).
fn sums_tree(t: u32, own: Sums) -> Sums {
    scratch[t] = own;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half = half / 2u) {
        if t < half {
            scratch[t] = add_sums(scratch[t], scratch[t + half]);
        }
        workgroupBarrier();
    }
    return scratch[0];
}

// Thread t of a chunk adds nodes t, t + 64, … in order; then a fixed tree.
fn reduce_chunk(chunk: u32, t: u32, own: Sums) {
    let total = sums_tree(t, own);
    if t == 0u {
        sums[chunk] = total;
    }
}

fn zero_sums() -> Sums {
    return Sums(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
}

// Inertia terms of mass m at r: (yy+zz, xx+zz, xx+yy) and (−xy, −xz, −yz).
fn inertia_diag(r: vec3<f32>, m: f32) -> vec3<f32> {
    let q = r * r;
    return vec3<f32>(q.y + q.z, q.x + q.z, q.x + q.y) * m;
}

fn inertia_off(r: vec3<f32>, m: f32) -> vec3<f32> {
    return -vec3<f32>(r.x * r.y, r.x * r.z, r.y * r.z) * m;
}

// Sums of the torque pass, r about the body's reference point, d the elastic correction
// x − x̃: a = (m, m r), b.xyz = m r × d, c.xyz / d.xyz = the inertia's diagonal / off
// diagonal, and m d in (b.w, c.w, d.w).
@compute @workgroup_size(64)
fn torque_sums(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let chunk = chunks[wg.x];
    let reference = bodies[chunk.body].reference.xyz;
    var own = zero_sums();
    var md = vec3<f32>(0.0);
    for (var i = chunk.start + lid.x; i < chunk.end; i += WG) {
        let m = nodes[i].mass;
        let r = (base[i].xyz - reference) + prev[i].xyz;
        let d = x[i].xyz - predicted[i].xyz;
        own.a += vec4<f32>(m, r * m);
        own.b += vec4<f32>(cross(r, d) * m, 0.0);
        own.c += vec4<f32>(inertia_diag(r, m), 0.0);
        own.d += vec4<f32>(inertia_off(r, m), 0.0);
        md += d * m;
    }
    own.b.w = md.x;
    own.c.w = md.y;
    own.d.w = md.z;
    reduce_chunk(wg.x, lid.x, own);
}

fn inverse3(m: mat3x3<f32>) -> mat3x3<f32> {
    let det = determinant(m);
    if det == 0.0 || !(abs(det) < 3.0e38) {
        return mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    }
    let a = m[0];
    let b = m[1];
    let c = m[2];
    let adj = transpose(mat3x3<f32>(cross(b, c), cross(c, a), cross(a, b)));
    return adj * (1.0 / det);
}

// A body's chunk sums, by the body's workgroup (all its threads call this): thread t adds
// chunks t, t + 64, … in order; then a fixed tree. One thread adding 2048 chunks (a 128³
// lattice) took 0.48 ms a substep on an H200; this takes a 64th of the loads in a row.
fn body_sums(body: Body, t: u32) -> Sums {
    var own = zero_sums();
    for (var k = body.chunk_start + t; k < body.chunk_end; k += WG) {
        own = add_sums(own, sums[k]);
    }
    return sums_tree(t, own);
}

// Inertia about the centre c (relative to the reference) from the sums about the reference.
fn inertia_about(s: Sums, c: vec3<f32>, mass: f32) -> mat3x3<f32> {
    let dg = s.c.xyz - inertia_diag(c, mass);
    let off = s.d.xyz - inertia_off(c, mass);
    return mat3x3<f32>(
        vec3<f32>(dg.x, off.x, off.y),
        vec3<f32>(off.x, dg.y, off.z),
        vec3<f32>(off.y, off.z, dg.z),
    );
}

// One workgroup per body.
@compute @workgroup_size(64)
fn torque_finish(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let b = wg.x;
    if b >= params.body_count {
        return;
    }
    let body = bodies[b];
    let s = body_sums(body, lid.x);
    if lid.x != 0u {
        return;
    }
    let mass = s.a.x;
    var out = BodyOut(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
    if body.cancel != 0u && mass > 0.0 {
        let c = s.a.yzw / mass;
        let md = vec3<f32>(s.b.w, s.c.w, s.d.w);
        let torque = s.b.xyz - cross(c, md);
        let inv = inverse3(inertia_about(s, c, mass));
        out.centre = vec4<f32>(c, 0.0);
        out.turn = vec4<f32>(inv * torque, 0.0);
        out.on = vec4<f32>(select(0.0, 1.0, determinant(inv) != 0.0));
    }
    body_out[b] = out;
}

@compute @workgroup_size(64)
fn torque_apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.node_count {
        return;
    }
    let node = nodes[i];
    let out = body_out[node.body];
    if out.on.x == 0.0 || node.mass <= 0.0 {
        return;
    }
    let reference = bodies[node.body].reference.xyz;
    let r = (base[i].xyz - reference) + prev[i].xyz - out.centre.xyz;
    let p = x[i].xyz - cross(out.turn.xyz, r);
    x[i] = vec4<f32>(p, 0.0);
}

// ---- Stage 4: rigid contact (xpbd::contact::Surfaces::resolve, planes only) ----------------

struct Contact {
    correction: vec3<f32>,
    depth: f32,
    // The capsules' part of the correction, and its dot with their surfaces' motion.
    from_capsules: vec3<f32>,
    capsule_work: f32,
}

fn friction_part(slip: vec3<f32>, limit: f32) -> vec3<f32> {
    let size = length(slip);
    if size <= limit {
        return slip;
    }
    return slip * (limit / size);
}

// The contact of a point at `at + travel + step` that was at `at + travel` at the substep's
// start (`step` its move in the substep): xpbd::contact::Surfaces::resolve with the moves
// taken from the start, and each plane's depth from the point's distance to it.
fn resolve(at: vec3<f32>, travel: vec3<f32>, step0: vec3<f32>) -> Contact {
    var out = Contact(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
    var step = step0;
    for (var k = 0u; k < params.plane_count; k++) {
        let plane = params.planes[k];
        let n = plane.xyz;
        let depth = ((plane.w - dot(n, at)) - dot(n, travel)) - dot(n, step);
        if depth > 0.0 {
            let moved_to = step + n * depth;
            let slip = moved_to - n * dot(moved_to, n);
            let fixed = moved_to - friction_part(slip, params.friction * depth);
            out.correction += fixed - step;
            out.depth = max(out.depth, depth);
            step = fixed;
        }
    }
    if params.capsule_count == 0u {
        return out;
    }
    // The capsules (xpbd::contact::Surfaces::resolve), on whole coordinates.
    let start = at + travel;
    for (var k = 0u; k < params.capsule_count; k++) {
        let cap = capsules[step_index() * params.capsule_count + k];
        let centre = cap.centre.xyz;
        let axis = cap.axis.xyz;
        let radius = cap.centre.w;
        let half = 0.5 * cap.axis.w;
        let p = start + step;
        let s = clamp(dot(p - centre, axis), -half, half);
        let axis_point = centre + axis * s;
        let offset = p - axis_point;
        let dist = length(offset);
        let depth = radius - dist;
        if depth > 0.0 {
            var n = fallback_normal(axis);
            if dist > 1e-12 {
                n = offset / dist;
            }
            let moved_to = step + n * depth;
            let surface_then = cap.before_centre.xyz + cap.before_axis.xyz * s + n * radius;
            let surface_now = axis_point + n * radius;
            let travel_of_surface = surface_now - surface_then;
            let relative = moved_to - travel_of_surface;
            let slip = relative - n * dot(relative, n);
            let fixed = moved_to - friction_part(slip, cap.before_centre.w * depth);
            out.correction += fixed - step;
            out.from_capsules += fixed - step;
            out.capsule_work += dot(fixed - step, travel_of_surface);
            out.depth = max(out.depth, depth);
            step = fixed;
        }
    }
    return out;
}

fn step_index() -> u32 {
    return substep.index;
}

// Manipulator::fallback_normal: a direction perpendicular to the axis.
fn fallback_normal(axis: vec3<f32>) -> vec3<f32> {
    var trial = vec3<f32>(0.0, 1.0, 0.0);
    if abs(axis.x) < 0.9 {
        trial = vec3<f32>(1.0, 0.0, 0.0);
    }
    return normalize(cross(axis, trial));
}

fn note_depth(d: f32) {
    if d > 0.0 {
        atomicMax(&depth[0], bitcast<u32>(d));
    }
}

@compute @workgroup_size(64)
fn contact_nodes(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.node_count {
        return;
    }
    moved[i] = 0u;
    push[i] = vec4<f32>(0.0);
    let node = nodes[i];
    if (node.flags & 2u) == 0u || node.inv_mass <= 0.0 {
        return;
    }
    let c = resolve(base[i].xyz, prev[i].xyz, x[i].xyz);
    if c.depth > 0.0 {
        x[i] = vec4<f32>(x[i].xyz + c.correction, 0.0);
        moved[i] = 1u;
        note_depth(c.depth);
        let k = node.mass * params.inv_dt2;
        push[i] = vec4<f32>(c.from_capsules * k, c.capsule_work * k);
    }
}

fn beyond_reach(n: u32, reach: f32) -> bool {
    for (var k = 0u; k < params.plane_count; k++) {
        let plane = params.planes[k];
        let gap = ((dot(plane.xyz, base[n].xyz) - plane.w) + dot(plane.xyz, prev[n].xyz))
            + dot(plane.xyz, x[n].xyz);
        if gap <= reach {
            return false;
        }
    }
    let p = base[n].xyz + prev[n].xyz + x[n].xyz;
    for (var k = 0u; k < params.capsule_count; k++) {
        let cap = capsules[step_index() * params.capsule_count + k];
        let h = cap.axis.xyz * (0.5 * cap.axis.w);
        let a = cap.centre.xyz - h;
        let b = cap.centre.xyz + h;
        let grow = vec3<f32>(cap.centre.w + reach);
        let lo = min(a, b) - grow;
        let hi = max(a, b) + grow;
        if all(p >= lo) && all(p <= hi) {
            return false;
        }
    }
    return true;
}

@compute @workgroup_size(64)
fn contact_points(@builtin(global_invocation_id) id: vec3<u32>) {
    let g = span.start + id.x;
    if g >= span.end {
        return;
    }
    let first = index[params.group_offset + 2u * g];
    let last = index[params.group_offset + 2u * g + 1u];
    for (var o = first; o < last; o++) {
        let slot = params.node_count + index[o];
        push[slot] = vec4<f32>(0.0);
        let point = points[index[o]];
        if beyond_reach(point.nodes[0], point.reach) {
            continue;
        }
        var at = vec3<f32>(0.0);
        var travel = vec3<f32>(0.0);
        var step = vec3<f32>(0.0);
        var denominator = 0.0;
        for (var c = 0u; c < 8u; c++) {
            let n = point.nodes[c];
            let w = point.weights[c];
            at += base[n].xyz * w;
            travel += prev[n].xyz * w;
            step += x[n].xyz * w;
            denominator += w * w * base[n].w;
        }
        if denominator <= 0.0 {
            continue;
        }
        let c = resolve(at, travel, step);
        if c.depth <= 0.0 {
            continue;
        }
        note_depth(c.depth);
        let scale = params.inv_dt2 / denominator;
        push[slot] = vec4<f32>(c.from_capsules * scale, c.capsule_work * scale);
        for (var k = 0u; k < 8u; k++) {
            let n = point.nodes[k];
            let step = c.correction * (point.weights[k] * base[n].w / denominator);
            x[n] = vec4<f32>(x[n].xyz + step, 0.0);
            moved[n] = 1u;
        }
    }
}

@compute @workgroup_size(64)
fn barrier_cells(@builtin(global_invocation_id) id: vec3<u32>) {
    let j = span.start + id.x;
    if j >= span.end {
        return;
    }
    let cell = cells[j];
    var any = false;
    for (var k = 0u; k < 8u; k++) {
        any = any || moved[cell.nodes[k]] != 0u;
    }
    if !any {
        return;
    }
    load_cell(cell);
    for (var c = 0u; c < 8u; c++) {
        barrier(c, cell.inv_h);
    }
    store_cell(cell);
}

// ---- The capsules' push on the bodies, summed in a fixed order ------------------------------

var<workgroup> push_scratch: array<vec4<f32>, 64>;

const PUSH_CHUNK: u32 = 1024u;

// The workgroup's `own` values summed by a fixed tree (every thread calls it; all get the sum).
fn push_tree(t: u32, own: vec4<f32>) -> vec4<f32> {
    push_scratch[t] = own;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half = half / 2u) {
        if t < half {
            push_scratch[t] += push_scratch[t + half];
        }
        workgroupBarrier();
    }
    return push_scratch[0];
}

// Chunk `wg.x` of the node and point slots into its partial sum.
@compute @workgroup_size(64)
fn push_sums(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let slots = params.node_count + params.point_count;
    let start = wg.x * PUSH_CHUNK;
    let end = min(start + PUSH_CHUNK, slots);
    var own = vec4<f32>(0.0);
    for (var i = start + lid.x; i < end; i += WG) {
        own += push[i];
    }
    let total = push_tree(lid.x, own);
    if lid.x == 0u {
        push[slots + wg.x] = total;
    }
}

// The chunks' sums: this substep's total (thread t adds chunks t, t + 64, … in order;
// then a fixed tree).
@compute @workgroup_size(64)
fn push_finish(@builtin(local_invocation_id) lid: vec3<u32>) {
    let slots = params.node_count + params.point_count;
    var own = vec4<f32>(0.0);
    for (var c = lid.x; c < params.push_chunks; c += WG) {
        own += push[slots + c];
    }
    let total = push_tree(lid.x, own);
    if lid.x == 0u {
        push[slots + params.push_chunks + substep.index] = total;
    }
}

// ---- Stage 5: velocities and the deformation damping ---------------------------------------

@compute @workgroup_size(64)
fn velocities(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.node_count {
        return;
    }
    if nodes[i].mass > 0.0 {
        vel[i] = vec4<f32>(x[i].xyz * params.inv_dt, 0.0);
    }
}

// Sums of the damping pass: a = (m, m r), b = (m v, ·), c/d inertia as above, and the
// momentum m r × v in (b.w, c.w, d.w).
@compute @workgroup_size(64)
fn damp_sums(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let chunk = chunks[wg.x];
    let reference = bodies[chunk.body].reference.xyz;
    var own = zero_sums();
    var mrv = vec3<f32>(0.0);
    for (var i = chunk.start + lid.x; i < chunk.end; i += WG) {
        let m = nodes[i].mass;
        let r = (base[i].xyz - reference) + prev[i].xyz + x[i].xyz;
        let v = vel[i].xyz;
        own.a += vec4<f32>(m, r * m);
        own.b += vec4<f32>(v * m, 0.0);
        own.c += vec4<f32>(inertia_diag(r, m), 0.0);
        own.d += vec4<f32>(inertia_off(r, m), 0.0);
        mrv += cross(r, v) * m;
    }
    own.b.w = mrv.x;
    own.c.w = mrv.y;
    own.d.w = mrv.z;
    reduce_chunk(wg.x, lid.x, own);
}

// One workgroup per body.
@compute @workgroup_size(64)
fn damp_finish(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let b = wg.x;
    if b >= params.body_count {
        return;
    }
    let body = bodies[b];
    if body.damping <= 0.0 {
        if lid.x == 0u {
            body_out[b] = BodyOut(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
        }
        return;
    }
    let s = body_sums(body, lid.x);
    if lid.x != 0u {
        return;
    }
    var out = BodyOut(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
    let mass = s.a.x;
    if mass > 0.0 {
        let c = s.a.yzw / mass;
        let v = s.b.xyz / mass;
        let momentum = vec3<f32>(s.b.w, s.c.w, s.d.w) - cross(c, v) * mass;
        let inv = inverse3(inertia_about(s, c, mass));
        out.centre = vec4<f32>(c, 0.0);
        out.turn = vec4<f32>(inv * momentum, 0.0);
        out.velocity = vec4<f32>(v, 0.0);
        out.on = vec4<f32>(min(body.damping * params.dt, 1.0));
    }
    body_out[b] = out;
}

@compute @workgroup_size(64)
fn damp_apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.node_count {
        return;
    }
    let body = nodes[i].body;
    let out = body_out[body];
    let pull = out.on.x;
    if pull == 0.0 {
        return;
    }
    let v = vel[i].xyz;
    let r = (base[i].xyz - bodies[body].reference.xyz) + prev[i].xyz + x[i].xyz - out.centre.xyz;
    let rigid = out.velocity.xyz + cross(out.turn.xyz, r);
    vel[i] = vec4<f32>(v + (rigid - v) * pull, 0.0);
}
