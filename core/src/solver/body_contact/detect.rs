//! Detection of body–body and body–collider contacts (the narrow phase of
//! [`super::contact_pass`]): surface samples against triangles with the segment from their
//! previous position, the nearest face, edge–edge contacts, collider queries.

use super::*;

/// Position and velocity of a surface sample.
pub(super) fn sample(
    surface: &SurfacePoints,
    nodes: &NodeState,
    i: usize,
) -> (Vector3<f64>, Vector3<f64>) {
    let (ids, w) = (&surface.nodes[i], &surface.weights[i]);
    let (mut x, mut v) = (Vector3::zeros(), Vector3::zeros());
    for c in 0..8 {
        x += nodes.position[ids[c] as usize] * w[c];
        v += nodes.velocity[ids[c] as usize] * w[c];
    }
    (x, v)
}

fn inside(p: &Vector3<f64>, lo: &Vector3<f64>, hi: &Vector3<f64>) -> bool {
    (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k])
}

/// `[x, v, box min, box max]`: contact sample `i`'s position and velocity when it lies in
/// `[lo, hi]`, and the box its segment from the previous position sweeps, grown by `reach`
/// (the grid query box).
fn swept_sample(
    input: &PassInput,
    i: usize,
    lo: &Vector3<f64>,
    hi: &Vector3<f64>,
    reach: f64,
) -> Option<[Vector3<f64>; 4]> {
    let (x, v) = sample(input.surface, input.nodes, i);
    if !inside(&x, lo, hi) {
        return None;
    }
    let prev = x - v * input.dt;
    Some([
        x,
        v,
        x.inf(&prev).add_scalar(-reach),
        x.sup(&prev).add_scalar(reach),
    ])
}

/// The triangles a point can meet, as [`best_face`] reads them.
trait Faces {
    /// The corners of triangle `t`.
    fn corners(&self, t: usize) -> [Vector3<f64>; 3];
    /// Its box (the corners' bounds).
    fn bounds(&self, t: usize) -> (Vector3<f64>, Vector3<f64>);
    /// Its unit normal ([`triangle_normal`]; zero for a degenerate triangle).
    fn normal(&self, t: usize) -> Vector3<f64>;
    /// The velocity of its point at barycentric weights `w`.
    fn velocity(&self, t: usize, w: [f64; 3]) -> Vector3<f64>;
}

/// A body's display triangles in the step (boxes and normals from [`BodyMesh::update`]).
struct MeshFaces<'a>(&'a BodyMesh);

impl Faces for MeshFaces<'_> {
    fn corners(&self, t: usize) -> [Vector3<f64>; 3] {
        self.0.corners(t)
    }
    fn bounds(&self, t: usize) -> (Vector3<f64>, Vector3<f64>) {
        (self.0.faces[t].0, self.0.faces[t].1)
    }
    fn normal(&self, t: usize) -> Vector3<f64> {
        self.0.faces[t].2
    }
    fn velocity(&self, t: usize, w: [f64; 3]) -> Vector3<f64> {
        let tri = self.0.triangles[t];
        (0..3).map(|k| self.0.v[tri[k] as usize] * w[k]).sum()
    }
}

/// A static collider's triangles (normals computed when it was built; it does not move).
struct ColliderFaces<'a>(&'a StaticCollider);

impl Faces for ColliderFaces<'_> {
    fn corners(&self, t: usize) -> [Vector3<f64>; 3] {
        self.0.corners(t)
    }
    fn bounds(&self, t: usize) -> (Vector3<f64>, Vector3<f64>) {
        let [a, b, c] = self.0.corners(t);
        (a.inf(&b).inf(&c), a.sup(&b).sup(&c))
    }
    fn normal(&self, t: usize) -> Vector3<f64> {
        self.0.normals[t]
    }
    fn velocity(&self, _: usize, _: [f64; 3]) -> Vector3<f64> {
        Vector3::zeros()
    }
}

/// The best face contact of a point at `x` moving at `v` against triangles `candidates` of
/// `faces`: a crossing of the segment from the previous position first, else the nearest face
/// within the layer, or one the point lies just behind (at most `behind` deep).
#[allow(clippy::too_many_arguments)]
fn best_face(
    x: Vector3<f64>,
    v: Vector3<f64>,
    dt: f64,
    h: f64,
    behind: f64,
    candidates: &[u32],
    faces: &impl Faces,
) -> Option<FaceHit> {
    // (segment parameter or distance, hit)
    let mut crossing: Option<(f64, FaceHit)> = None;
    let mut near: Option<(f64, FaceHit)> = None;
    let reach = h.max(behind);
    let (qlo, qhi) = (
        x.inf(&(x - v * dt)).add_scalar(-reach),
        x.sup(&(x - v * dt)).add_scalar(reach),
    );
    for &t in candidates {
        let t = t as usize;
        // Cheap reject: the triangle's box misses the point's reach (grid cells are coarser).
        let (tlo, thi) = faces.bounds(t);
        if (0..3).any(|k| tlo[k] > qhi[k] || thi[k] < qlo[k]) {
            continue;
        }
        let n = faces.normal(t);
        if n == Vector3::zeros() {
            continue;
        }
        let [a, b, c] = faces.corners(t);
        let (bary, interior) = closest_on_triangle(&x, &a, &b, &c);
        let q = a * bary[0] + b * bary[1] + c * bary[2];
        let vq = faces.velocity(t, bary);
        let rel = v - vq;
        let s_now = (x - a).dot(&n);
        let prev = x - rel * dt;
        if s_now < 0.0 && (prev - a).dot(&n) > 0.0 {
            if let Some((u, w)) = segment_crosses_triangle(&prev, &x, &a, &b, &c) {
                if crossing.is_none_or(|c| u < c.0) {
                    let hit = FaceHit {
                        tri: t,
                        bary: w,
                        normal: n,
                        depth: h - s_now,
                        velocity: faces.velocity(t, w),
                    };
                    crossing = Some((u, hit));
                }
            }
        }
        let d = (x - q).norm();
        let side = (x - q).dot(&n);
        let candidate = if side >= 0.0 && d < h {
            let normal = if interior || d <= 1e-12 {
                n
            } else {
                (x - q) / d
            };
            Some((d, normal, h - d))
        } else if side < 0.0 && interior && d < behind {
            Some((d, n, h + d))
        } else {
            None
        };
        if let Some((d, normal, depth)) = candidate {
            if near.is_none_or(|n| d < n.0) {
                let hit = FaceHit {
                    tri: t,
                    bary,
                    normal,
                    depth,
                    velocity: vq,
                };
                near = Some((d, hit));
            }
        }
    }
    crossing.or(near).map(|(_, hit)| hit)
}

/// A sample's contact with a face: triangle, barycentric weights of the face point, normal
/// out of the face's body, depth into the layer, the face point's velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FaceHit {
    tri: usize,
    bary: [f64; 3],
    normal: Vector3<f64>,
    depth: f64,
    velocity: Vector3<f64>,
}

/// Vertex–face contacts of body `a`'s samples with body `b`'s triangles inside `[lo, hi]`;
/// `flipped` when `(a, b)` is the pair the response runs for, the other way round.
pub(super) fn detect_pair(
    bc: &mut BodyContact,
    input: &PassInput,
    (a, b): (usize, usize),
    flipped: bool,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
) {
    let Some(mb) = bc.mesh_of[b] else {
        return;
    };
    if bc.points[a].is_empty() {
        return;
    }
    let (h, dt) = (input.layer.thickness_m, input.dt);
    let stamp = bc.step;
    bc.meshes[mb].update(input.nodes, stamp);
    let mesh = &bc.meshes[mb];
    bc.grid.build(
        lo,
        hi,
        mesh.mean_edge,
        mesh.triangles.len(),
        mesh.faces
            .iter()
            .enumerate()
            .map(|(t, &(tlo, thi, _))| (t as u32, tlo, thi)),
    );
    if bc.grid.is_empty() {
        return;
    }
    let behind = BEHIND_LAYERS * h;
    let faces = MeshFaces(mesh);
    for i in bc.points[a].clone() {
        let Some([x, v, qlo, qhi]) = swept_sample(input, i, &lo, &hi, h.max(behind)) else {
            continue;
        };
        bc.grid.query(&qlo, &qhi, &mut bc.candidates);
        if let Some(hit) = best_face(x, v, dt, h, behind, &bc.candidates, &faces) {
            bc.contacts.push(Contact {
                a: Feature::Point(i),
                b: Feature::Face {
                    mesh: mb,
                    tri: hit.tri,
                    bary: hit.bary,
                },
                normal: hit.normal,
                depth: hit.depth,
                relative_velocity: v - hit.velocity,
                share: input.surface.share[i],
                flipped,
            });
        }
    }
}

/// Edge–edge contacts of body `a`'s display edges with body `b`'s inside `[lo, hi]` (the grid
/// is rebuilt here over `b`'s edges). Only edges whose faces meet at an angle (face normals
/// more than 30° from opposite): between parallel faces the samples' vertex–face contacts
/// already carry the load.
pub(super) fn detect_edges(
    bc: &mut BodyContact,
    input: &PassInput,
    a: usize,
    b: usize,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
) {
    let (Some(ma), Some(mb)) = (bc.mesh_of[a], bc.mesh_of[b]) else {
        return;
    };
    let h = input.layer.thickness_m;
    let stamp = bc.step;
    bc.meshes[ma].update(input.nodes, stamp);
    bc.meshes[mb].update(input.nodes, stamp);
    let (ea, eb) = (&bc.meshes[ma], &bc.meshes[mb]);
    bc.grid.build(
        lo,
        hi,
        eb.mean_edge,
        eb.edges.len(),
        eb.edges.iter().enumerate().map(|(k, &[i, j, _])| {
            let (p, q) = (eb.x[i as usize], eb.x[j as usize]);
            (k as u32, p.inf(&q), p.sup(&q))
        }),
    );
    if bc.grid.is_empty() {
        return;
    }
    let behind = BEHIND_LAYERS * h;
    let parallel = -(30f64.to_radians().cos());
    // One contact per edge of `a`: its nearest qualifying edge of `b`.
    let share = EDGE_SHARE;
    for &[u, w, third] in &ea.edges {
        let (p0, p1) = (ea.x[u as usize], ea.x[w as usize]);
        let (elo, ehi) = (p0.inf(&p1), p0.sup(&p1));
        if (0..3).any(|k| ehi[k] < lo[k] || elo[k] > hi[k]) {
            continue;
        }
        let na = triangle_normal(&p0, &p1, &ea.x[third as usize]);
        let reach = h.max(behind);
        bc.grid.query(
            &elo.add_scalar(-reach),
            &ehi.add_scalar(reach),
            &mut bc.candidates,
        );
        let mut best: Option<(f64, Contact)> = None;
        for &k in &bc.candidates {
            let [i0, i1, i2] = eb.edges[k as usize];
            let (q0, q1) = (eb.x[i0 as usize], eb.x[i1 as usize]);
            let nb = triangle_normal(&q0, &q1, &eb.x[i2 as usize]);
            if na.dot(&nb) < parallel {
                continue;
            }
            let (s, r) = closest_between_segments(&p0, &p1, &q0, &q1);
            if s <= 0.0 || s >= 1.0 || r <= 0.0 || r >= 1.0 {
                continue;
            }
            let cross = (p1 - p0).cross(&(q1 - q0));
            let len = cross.norm();
            if len <= 1e-9 * (p1 - p0).norm() * (q1 - q0).norm() {
                continue;
            }
            let mut n = cross / len;
            if n.dot(&nb) < 0.0 {
                n = -n;
            }
            // Only edges facing each other: a's surface turned towards b.
            if n.dot(&na) >= 0.0 || n.dot(&nb) <= 0.0 {
                continue;
            }
            let (pa, pb) = (p0 + (p1 - p0) * s, q0 + (q1 - q0) * r);
            let gap = (pa - pb).dot(&n);
            if gap >= h || gap <= -behind {
                continue;
            }
            let va = ea.v[u as usize] * (1.0 - s) + ea.v[w as usize] * s;
            let vb = eb.v[i0 as usize] * (1.0 - r) + eb.v[i1 as usize] * r;
            let contact = Contact {
                a: Feature::Edge {
                    mesh: ma,
                    a: u,
                    b: w,
                    s,
                },
                b: Feature::Edge {
                    mesh: mb,
                    a: i0,
                    b: i1,
                    s: r,
                },
                normal: n,
                depth: h - gap,
                relative_velocity: va - vb,
                share,
                flipped: false,
            };
            if best.as_ref().is_none_or(|(g, _)| gap < *g) {
                best = Some((gap, contact));
            }
        }
        if let Some((_, c)) = best {
            bc.contacts.push(c);
        }
    }
}

/// Vertex–face contacts of body `a`'s samples with collider `c` inside `[lo, hi]`.
pub(super) fn detect_collider(
    bc: &mut BodyContact,
    input: &PassInput,
    a: usize,
    c: usize,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
) {
    let (h, dt) = (input.layer.thickness_m, input.dt);
    let behind = BEHIND_LAYERS * h;
    let col = &mut bc.colliders[c];
    for i in bc.points[a].clone() {
        let Some([x, v, qlo, qhi]) = swept_sample(input, i, &lo, &hi, h.max(behind)) else {
            continue;
        };
        col.grid.query(&qlo, &qhi, &mut bc.candidates);
        let faces = ColliderFaces(col);
        if let Some(hit) = best_face(x, v, dt, h, behind, &bc.candidates, &faces) {
            bc.contacts.push(Contact {
                a: Feature::Point(i),
                b: Feature::Static,
                normal: hit.normal,
                depth: hit.depth,
                relative_velocity: v,
                share: input.surface.share[i],
                flipped: false,
            });
        }
    }
}
