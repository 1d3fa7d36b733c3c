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

/// Contact sample `i`'s position and velocity (from the step's cache) when it lies in
/// `[lo, hi]`.
fn sample_in(
    bc: &BodyContact,
    i: usize,
    (lo, hi): (&Vector3<f64>, &Vector3<f64>),
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let (x, v) = (bc.sample_x[i], bc.sample_v[i]);
    inside(&x, lo, hi).then_some((x, v))
}

/// The triangles a point can meet, as [`best_face`] reads them.
pub(super) trait Faces {
    /// The corners of triangle `t`.
    fn corners(&self, t: usize) -> [Vector3<f64>; 3];
    /// Its box (the corners' bounds).
    fn bounds(&self, t: usize) -> (Vector3<f64>, Vector3<f64>);
    /// Its unit normal ([`triangle_normal`]; zero for a degenerate triangle) and the plane's
    /// offset along it (`normal · corner`).
    fn plane(&self, t: usize) -> (Vector3<f64>, f64);
    /// Its fastest corner's speed, m/s.
    fn speed(&self, t: usize) -> f64;
    /// The velocity of its point at barycentric weights `w`.
    fn velocity(&self, t: usize, w: [f64; 3]) -> Vector3<f64>;

    /// A lower bound on the distance from `x` to triangle `t`: its plane's and its box's.
    fn distance_bound(&self, t: usize, x: &Vector3<f64>) -> f64 {
        let (n, offset) = self.plane(t);
        let (lo, hi) = self.bounds(t);
        let gap = (lo - x).sup(&(x - hi)).sup(&Vector3::zeros()).norm();
        (n.dot(x) - offset).abs().max(gap)
    }
}

/// A body's display triangles in the step (boxes, planes and speeds from
/// [`BodyMesh::refresh_all`]).
pub(super) struct MeshFaces<'a>(pub &'a BodyMesh);

impl Faces for MeshFaces<'_> {
    fn corners(&self, t: usize) -> [Vector3<f64>; 3] {
        self.0.corners(t)
    }
    fn bounds(&self, t: usize) -> (Vector3<f64>, Vector3<f64>) {
        (self.0.faces[t].lo, self.0.faces[t].hi)
    }
    fn plane(&self, t: usize) -> (Vector3<f64>, f64) {
        (self.0.faces[t].normal, self.0.faces[t].offset)
    }
    fn speed(&self, t: usize) -> f64 {
        self.0.faces[t].speed
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
    fn plane(&self, t: usize) -> (Vector3<f64>, f64) {
        let n = self.0.normals[t];
        (n, n.dot(&self.0.corners(t)[0]))
    }
    fn speed(&self, _: usize) -> f64 {
        0.0
    }
    fn velocity(&self, _: usize, _: [f64; 3]) -> Vector3<f64> {
        Vector3::zeros()
    }
}

/// A point looking for its face: position `x` and velocity `v` in a step of `dt`, the layer
/// thickness `h`, how deep `behind` a face it may still touch it, and whether the faces are
/// `two_sided` (an open mesh: see [`facing_side`]).
#[derive(Debug, Clone, Copy)]
struct Probe {
    x: Vector3<f64>,
    v: Vector3<f64>,
    dt: f64,
    h: f64,
    behind: f64,
    two_sided: bool,
}

/// The normal of a face with unit normal `n` through corner `a` as the point seen from `prev`
/// (its position at the step's start relative to the face) meets it. A closed surface wound
/// outwards has an inside, behind its faces, out of which a point is pushed to the front. An
/// open mesh (a sheet, a ground plane, a leaf; a voxel export's faces) has none: each face
/// has two fronts, and a point meets the one on the side it comes from. A block lying on a
/// sheet whose faces point down was pushed through it to the sheet's front and then thrown
/// by the layer at tens of metres a second.
fn facing_side(
    probe: &Probe,
    n: Vector3<f64>,
    a: Vector3<f64>,
    prev: Vector3<f64>,
) -> Vector3<f64> {
    if probe.two_sided && (prev - a).dot(&n) < 0.0 {
        -n
    } else {
        n
    }
}

/// A candidate face that can still be the answer: a lower bound on its distance from the
/// point, its place in the candidate list (ties go to the earlier one), its index, and whether
/// the point may have crossed it in the step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Bound {
    distance: f64,
    order: u32,
    tri: u32,
    may_cross: bool,
}

/// What a neighbour list knows of its candidates' distances: per candidate a lower bound on
/// its distance from the sample when the list was built (the candidates in ascending order of
/// it), how far the sample and the faces may have moved since (`slack`: both bodies' largest
/// node displacement), and the faces' fastest corner speed bound (`fastest`, m/s).
#[derive(Debug, Clone, Copy)]
pub(super) struct Ranked<'a> {
    pub lower: &'a [f64],
    pub slack: f64,
    pub fastest: f64,
}

/// The best face contact of `probe` against triangles `candidates` of `faces`: a crossing of
/// the segment from the previous position first (the earliest), else the nearest face within
/// the layer, or one the point lies just behind (at most `behind` deep); ties go to the
/// earlier candidate. `bounds` is scratch.
///
/// A face cannot be nearer than its plane or its box (`max(|s|, box distance)`): the face of
/// the nearest bound is looked at first, then the others in order, skipping any whose bound is
/// no nearer than the nearest face so far unless the point may have crossed it. In a resting
/// pile most candidates are coplanar with the nearest face, or the sides of the partner the
/// point lies below: a point looks at two or three faces instead of thirty.
///
/// With `ranked` candidates (a neighbour list's, nearest first) the search stops at the first
/// candidate that was, when the list was built, farther than what it has found plus how far
/// things have moved since: a face the point may have crossed lies within the step's relative
/// travel, and a nearer face within the found distance, so none past it can be the answer.
/// In a resting pile a sample looks at the few faces under it instead of computing bounds
/// for thirty.
fn best_face(
    probe: Probe,
    candidates: &[u32],
    faces: &impl Faces,
    bounds: &mut Vec<Bound>,
    ranked: Option<Ranked>,
) -> Option<FaceHit> {
    let mut search = FaceSearch::default();
    let Some(ranked) = ranked else {
        bounds.clear();
        for (order, &tri) in candidates.iter().enumerate() {
            if let Some(bound) = candidate_bound(&probe, faces, tri, order as u32) {
                bounds.push(bound);
            }
        }
        if let Some(first) = (0..bounds.len()).min_by(|&i, &j| {
            let (a, b) = (&bounds[i], &bounds[j]);
            a.distance
                .total_cmp(&b.distance)
                .then(a.order.cmp(&b.order))
        }) {
            bounds.swap(0, first);
        }
        for bound in bounds.iter() {
            search.consider(&probe, faces, bound);
        }
        return search.result();
    };
    let reach = probe.h.max(probe.behind);
    let travel = 2.0 * (probe.v.norm() + ranked.fastest) * probe.dt + 1e-9 * probe.h;
    for (order, (&tri, &lower)) in candidates.iter().zip(ranked.lower).enumerate() {
        let found = search
            .near
            .as_ref()
            .map_or(reach, |(n, _, _)| n.distance * (1.0 + DISTANCE_TIE));
        if lower - ranked.slack > found.max(travel) {
            break;
        }
        if let Some(bound) = candidate_bound(&probe, faces, tri, order as u32) {
            search.consider(&probe, faces, &bound);
        }
    }
    search.result()
}

/// Candidate `tri`'s bound for `probe` (`order`: its place among the candidates), `None` when
/// it cannot be the answer: its box misses the point's reach, or it is farther than the
/// layer in front (`behind` behind) and the point cannot have crossed it.
fn candidate_bound(probe: &Probe, faces: &impl Faces, tri: u32, order: u32) -> Option<Bound> {
    let Probe {
        x,
        v,
        dt,
        h,
        behind,
        two_sided,
    } = *probe;
    let reach = h.max(behind);
    let (qlo, qhi) = (
        x.inf(&(x - v * dt)).add_scalar(-reach),
        x.sup(&(x - v * dt)).add_scalar(reach),
    );
    let t = tri as usize;
    // Cheap reject: the triangle's box misses the point's reach (grid cells are coarser).
    let (tlo, thi) = faces.bounds(t);
    if (0..3).any(|k| tlo[k] > qhi[k] || thi[k] < qlo[k]) {
        return None;
    }
    let (n, offset) = faces.plane(t);
    if n == Vector3::zeros() {
        return None;
    }
    // Signed distance from the plane: a crossing needs the point behind the face now,
    // by less than the relative motion of the step could carry it.
    let s = n.dot(&x) - offset;
    let travel = 2.0 * (v.norm() + faces.speed(t)) * dt + 1e-9 * h;
    // An open mesh's face is crossed from either side, and met within the layer on both.
    let s = if two_sided { -s.abs() } else { s };
    let may_cross = s < 0.0 && -s < travel;
    let distance = faces.distance_bound(t, &x);
    let limit = if s >= 0.0 || two_sided { h } else { behind };
    (distance < limit || may_cross).then_some(Bound {
        distance,
        order,
        tri,
        may_cross,
    })
}

/// The best crossing and the best near contact found so far by [`best_face`]:
/// (segment parameter or contact, candidate order, hit).
#[derive(Default)]
struct FaceSearch {
    crossing: Option<(f64, u32, FaceHit)>,
    near: Option<(Near, u32, FaceHit)>,
}

impl FaceSearch {
    /// Look at the face of `bound` unless it cannot beat the nearest face so far.
    fn consider(&mut self, probe: &Probe, faces: &impl Faces, bound: &Bound) {
        let (x, v, dt, h) = (probe.x, probe.v, probe.dt, probe.h);
        if !bound.may_cross
            && self.near.as_ref().is_some_and(|(n, _, _)| {
                bound.distance > n.distance * (1.0 + DISTANCE_TIE)
                    || (bound.distance >= n.distance * PRUNE_TIE && n.facing >= 1.0)
            })
        {
            return;
        }
        let t = bound.tri as usize;
        let [a, b, c] = faces.corners(t);
        let (bary, interior) = closest_on_triangle(&x, &a, &b, &c);
        let q = a * bary[0] + b * bary[1] + c * bary[2];
        let vq = faces.velocity(t, bary);
        let rel = v - vq;
        let prev = x - rel * dt;
        let n = facing_side(probe, faces.plane(t).0, a, prev);
        let s_now = (x - a).dot(&n);
        if s_now < 0.0 && (prev - a).dot(&n) > 0.0 {
            if let Some((u, w)) = segment_crosses_triangle(&prev, &x, &a, &b, &c) {
                let earlier = self
                    .crossing
                    .as_ref()
                    .is_none_or(|b| u < b.0 || (u == b.0 && bound.order < b.1));
                if earlier {
                    let hit = FaceHit {
                        tri: t,
                        bary: w,
                        normal: n,
                        depth: h - s_now,
                        velocity: faces.velocity(t, w),
                        outside_by: 0.0,
                        rim: false,
                    };
                    self.crossing = Some((u, bound.order, hit));
                }
            }
        }
        if let Some(found) = near_contact(probe, q, n, interior) {
            let wins = self
                .near
                .as_ref()
                .is_none_or(|(best, order, _)| found.beats(best, bound.order < *order));
            if wins {
                let hit = FaceHit {
                    tri: t,
                    bary,
                    normal: found.normal,
                    depth: found.depth,
                    velocity: vq,
                    outside_by: found.outside_by(h),
                    rim: found.rim,
                };
                self.near = Some((found, bound.order, hit));
            }
        }
    }

    /// The crossing if any, else the near contact.
    fn result(self) -> Option<FaceHit> {
        self.crossing
            .map(|(_, _, hit)| hit)
            .or(self.near.map(|(_, _, hit)| hit))
    }
}

/// How far beyond a face's edge (in layer thicknesses, across the face) a point in front of
/// it takes a normal between the face's and the direction from the edge: two flat faces
/// pressed together meet along their rims, where a point that bulged a fraction of a
/// millimetre past the other's rim took a normal tilted by a fifth towards the side, and
/// the sideways pushes of the two rims of a stack of cubes did not cancel.
const RIM_BLEND: f64 = 0.5;
/// The cosine (45°) between a face's normal and the direction to a point beyond its edge
/// above which the point counts as in front of the face for [`RIM_BLEND`] (a face beside
/// the point, tying with the face under it at their shared edge, keeps the direction).
const FACING_COSINE: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// The contact of `probe` with the nearest point `q` of a face with unit normal `n` (`interior`:
/// `q` inside the face, not on an edge), when the point lies within the layer in front of it,
/// or at most `behind` behind its interior.
fn near_contact(probe: &Probe, q: Vector3<f64>, n: Vector3<f64>, interior: bool) -> Option<Near> {
    let (x, h) = (probe.x, probe.h);
    let d = (x - q).norm();
    let side = (x - q).dot(&n);
    if side >= 0.0 && d < h {
        let (normal, facing) = if interior || d <= 1e-12 {
            (n, 1.0)
        } else {
            // Beyond an edge: the direction to the point, turned towards the face's normal
            // while the point is more in front of the face than beside it and within
            // RIM_BLEND layers of its extent.
            let toward = (x - q) / d;
            let normal = if side < FACING_COSINE * d {
                toward
            } else {
                let lateral = ((x - q) - n * side).norm();
                let t = (lateral / (RIM_BLEND * h)).min(1.0);
                (n * (1.0 - t) + toward * t).normalize()
            };
            (normal, side / d)
        };
        Some(Near {
            distance: d,
            facing,
            normal,
            depth: h - d,
            rim: !interior && d > 1e-12,
        })
    } else if side < 0.0 && interior && d < probe.behind {
        // Behind the face: the direction to the point is against its normal. A face at the
        // same distance that the point lies in front of wins the tie (a double-sided sheet's
        // coincident faces: the one behind pushed the point through the sheet).
        Some(Near {
            distance: d,
            facing: -1.0,
            normal: n,
            depth: h + d,
            rim: false,
        })
    } else {
        None
    }
}

/// Faces whose distance bound lies this close (relative) to the nearest face so far are not
/// looked at when that face's nearest point is inside it: coplanar faces of a flat region tie
/// with it up to rounding, and none can face the point better.
const PRUNE_TIE: f64 = 1.0 - 1e-12;

/// Distances this close (relative) are a tie, which the face facing the point better wins:
/// faces that meet at an edge or a corner share its nearest point.
const DISTANCE_TIE: f64 = 1e-9;

/// A point's contact with one face, as [`near_contact`] finds it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Near {
    distance: f64,
    /// Cosine between the face's normal and the direction to the point (1 in front of the
    /// face's interior, −1 behind it).
    facing: f64,
    normal: Vector3<f64>,
    depth: f64,
    /// The nearest point is on the face's rim (an edge or a corner), the point beyond it.
    rim: bool,
}

impl Near {
    /// The distance of a contact in front of a face's interior (the point is outside the
    /// face's body there), else 0 ([`FaceHit::outside_by`]).
    fn outside_by(&self, h: f64) -> f64 {
        if self.facing >= 1.0 && self.depth <= h {
            self.distance
        } else {
            0.0
        }
    }

    /// Whether this contact beats `best`: nearer, or as near (within [`DISTANCE_TIE`]) and
    /// facing the point better, or the same in both and `earlier`. The face under a point
    /// that bulged past its rim, not the face beside it, gives the contact's normal.
    fn beats(&self, best: &Near, earlier: bool) -> bool {
        let (d, b) = (self.distance, best.distance);
        if d > b * (1.0 + DISTANCE_TIE) {
            return false;
        }
        if d < b * (1.0 - DISTANCE_TIE) {
            return true;
        }
        self.facing > best.facing || (self.facing == best.facing && (d < b || (d == b && earlier)))
    }
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
    /// How far the point lies in front of the face's interior (outside the partner), m; 0
    /// when it is not known to be outside: behind the face, past its rim, or across it in
    /// the step.
    outside_by: f64,
    /// The point met the face's rim (an edge or a corner), not its interior: the normal is
    /// the direction from the rim.
    rim: bool,
}

/// One ordered pair's vertex–face search, prepared ([`begin_pair`]): body `a`'s samples
/// against body `b`'s triangles (mesh `mesh`) inside `[lo, hi]`, with the pair's neighbour
/// list taken out of the contact state (built, if due, by [`search_pair`]), so the search
/// only reads the state and pairs can be searched side by side.
pub(super) struct PairSearch {
    pair: (usize, usize),
    mesh: usize,
    flipped: bool,
    bounds: (Vector3<f64>, Vector3<f64>),
    /// Layer thickness, step and depth behind a face (the probe's).
    h: f64,
    dt: f64,
    behind: f64,
    /// For a constrained pair, how far in front of a face a contact still acts (see
    /// [`pair_contacts`]).
    front: Option<f64>,
    /// Body `a`'s own display surface is open (its samples' normals have no outside).
    own_open: bool,
    list: neighbours::FaceList,
}

/// Prepare the vertex–face search of body `a`'s samples against body `b`'s triangles inside
/// `[lo, hi]` (`flipped` when `(a, b)` is the pair the response runs for, the other way
/// round); `None` when there is nothing to search. The samples and the mesh must be fresh in
/// this step ([`super::prepare`]); the list may be left to build ([`search_pair`]).
pub(super) fn begin_pair(
    bc: &mut BodyContact,
    input: &PassInput,
    (a, b): (usize, usize),
    flipped: bool,
    (lo, hi): (Vector3<f64>, Vector3<f64>),
    front: Option<f64>,
) -> Option<PairSearch> {
    let mb = bc.mesh_of[b]?;
    if bc.points[a].is_empty() {
        return None;
    }
    let h = input.layer.thickness_m;
    let list = neighbours::take(bc, input, (a, b), lo, hi);
    let own_open = bc.mesh_of[a].is_some_and(|m| !bc.meshes[m].closed);
    Some(PairSearch {
        pair: (a, b),
        own_open,
        mesh: mb,
        flipped,
        bounds: (lo, hi),
        h,
        dt: input.dt,
        behind: BEHIND_LAYERS * h,
        front,
        list,
    })
}

/// The mesh whose grid the prepared search's list is to be built from in this step, if it is.
pub(super) fn grid_needed(search: &PairSearch) -> Option<usize> {
    search.list.is_pending().then_some(search.mesh)
}

/// Build the prepared search's list if it is to be built, then its vertex–face contacts in
/// its samples' order into `out`. Reads the contact state only (pairs run side by side), and
/// `points`: the surface points and the node positions (a sample meeting a rim reads its own
/// surface's normal from its cell, [`SurfacePoints::normal_now`]).
pub(super) fn search_pair(
    bc: &BodyContact,
    points: (&SurfacePoints, &[Vector3<f64>]),
    search: &mut PairSearch,
    out: &mut Vec<Contact>,
) {
    let samples = bc.points[search.pair.0].clone();
    neighbours::build(
        &mut search.list,
        &bc.meshes[search.mesh],
        &bc.sample_x,
        samples,
    );
    // Ranked lists never read the bounds scratch: it stays empty, unallocated.
    pair_contacts(bc, points, search, &mut Vec::new(), out);
}

/// The vertex–face contacts of a prepared search, in its samples' order, into `out`
/// (`bounds` is scratch). Reads the contact state only.
///
/// **Samples left alone.** For a constrained pair a contact farther in front of its face
/// than `front` is dropped ([`super::CONSTRAINT_FRONT`]), and against a closed surface wound
/// outwards ([`BodyMesh::closed`]) a point outside it only ever makes a contact in front of
/// a face (the nearest face of a point outside is seen from its front: the way to any face
/// behind it passes through the surface, nearer), or a crossing within the step's travel.
/// So a sample known to be outside, farther than `front` and the travel from every face,
/// would only make a contact that is dropped, and is not searched. It is known so
/// - when it lies outside the partner's node box (every face lies inside it) by more than
///   that, or
/// - when a search found it in front of a face's interior at distance `d` (every face is as
///   far), less how far both bodies' nodes have moved since (a sample and a face point move
///   no farther than their body's farthest node): it cannot have crossed a face meanwhile.
///
/// A sample not looked at in a step (out of the pair's region, or the pair out of reach)
/// starts over with a search. In a pile 1 cm apart, most of the sides' samples are left
/// alone. The same contacts come out, so the same bits.
pub(super) fn pair_contacts(
    bc: &BodyContact,
    (surface, positions): (&SurfacePoints, &[Vector3<f64>]),
    search: &mut PairSearch,
    bounds: &mut Vec<Bound>,
    out: &mut Vec<Contact>,
) {
    let (lo, hi) = &search.bounds;
    let faces = MeshFaces(&bc.meshes[search.mesh]);
    let list = &mut search.list;
    list.outside_by.resize(list.samples.len(), 0.0);
    let motion = bc.step_motion[search.pair.0] + bc.step_motion[search.pair.1];
    let (closed, partner) = (bc.meshes[search.mesh].closed, bc.boxes[search.pair.1]);
    let mut start = 0;
    for (k, &(i, end)) in list.samples.iter().enumerate() {
        let start_of = start as usize;
        let (i, candidates) = (i as usize, &list.faces[start_of..end as usize]);
        start = end;
        let Some((x, v)) = sample_in(bc, i, (lo, hi)) else {
            list.outside_by[k] = 0.0;
            continue;
        };
        let probe = Probe {
            x,
            v,
            dt: search.dt,
            h: search.h,
            behind: search.behind,
            two_sided: !closed,
        };
        let ranked = Ranked {
            lower: &list.lower[start_of..end as usize],
            slack: list.slack,
            fastest: bc.max_speed[search.pair.1],
        };
        if let Some(front) = search.front.filter(|_| closed) {
            let travel = 2.0 * (v.norm() + ranked.fastest) * search.dt;
            let limit = front.max(travel) + 1e-9 * search.h;
            let off_box = (partner.0 - x)
                .sup(&(x - partner.1))
                .sup(&Vector3::zeros())
                .norm();
            let left = off_box.max(list.outside_by[k] - motion);
            if left > limit {
                list.outside_by[k] = left;
                continue;
            }
        }
        let hit = best_face(probe, candidates, &faces, bounds, Some(ranked));
        list.outside_by[k] = hit.as_ref().map_or(0.0, |hit| hit.outside_by);
        if let Some(hit) = hit {
            let normal = if hit.rim {
                let own = surface.normal_now(i, positions).unwrap_or_default();
                rim_normal(hit.normal, own, search.own_open)
            } else {
                hit.normal
            };
            out.push(Contact {
                a: Feature::Point(i),
                b: Feature::Face {
                    mesh: search.mesh,
                    tri: hit.tri,
                    bary: hit.bary,
                },
                normal,
                depth: hit.depth,
                relative_velocity: v - hit.velocity,
                share: surface.share[i],
                flipped: search.flipped,
            });
        }
    }
}

/// The normal of a sample's contact with a face's rim (`toward`: the direction from the rim
/// to the sample), given the sample's own surface normal `own` (zero where unknown): against
/// its own surface, where the rim lies in front of that surface (on either side of an open
/// one). A rim meets a surface there (a box's edge on a slab, a cube's rim on the cube under
/// it), and the surface's normal is the contact's: the direction from the rim pushed
/// sideways, and a wooden box sliding over a wooden slab at 2 m/s met the slab's points just
/// ahead of its front edge as a wall, reared up on its back edge and stopped in 0.39 m, not
/// Coulomb's 0.51. The samples carry a normal only where their surface is flat (not on a
/// cube's rim, where a rim meets a rim and the direction between them is right).
fn rim_normal(toward: Vector3<f64>, own: Vector3<f64>, open: bool) -> Vector3<f64> {
    let facing = -own.dot(&toward);
    if facing > 0.0 {
        -own
    } else if open && facing < 0.0 {
        own
    } else {
        toward
    }
}

/// Give a finished search's neighbour list back to the contact state.
pub(super) fn end_pair(bc: &mut BodyContact, search: PairSearch) {
    neighbours::put_back(bc, search.pair, search.list);
}

/// Edges closer to parallel than this sine of their angle make no edge–edge contact: the
/// plane through two nearly parallel edges turns with the least twist of either (a cube's
/// rim resting on another's took a normal along the rim's side, which pushed the stack
/// apart), and the samples along such an edge meet the faces beside the other edge anyway.
const MIN_EDGE_SINE: f64 = 0.2;

/// Closest points within this fraction of an edge's ends are its corner's, which the samples
/// there already carry: two perpendicular edges meeting at corners (the rims of cubes side
/// by side) passed the test on rounding and took a normal along neither face.
const EDGE_END: f64 = 1e-6;

/// Least cosine between the edge–edge normal and each edge's face for the edges to face each
/// other. A face perpendicular to the normal gives no direction: its sign is the deformation's
/// (1e-4 in cubes resting side by side, which turned a normal through a centimetre's gap and
/// pulled them together).
const EDGE_FACING: f64 = 0.2;

/// Up to this many of the partner's edges in a pair's region, each edge looks at all of
/// them; more go into a grid. Display meshes of boxes and other simple parts have a few dozen
/// edges, and building a grid over them for every pair in every pass was a tenth of a pile's
/// contact pass (60 cubes 1 cm apart, where no edge met another).
const EDGES_WITHOUT_GRID: usize = 64;

/// What one pair's edge–edge search writes besides its contacts: the partner's edges in the
/// region, a grid over them when there are many, and the candidates of a query. Each pair's
/// task has its own, so pairs run side by side.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct EdgeScratch {
    near: Vec<NearEdge>,
    grid: BoxGrid,
    candidates: Vec<u32>,
}

/// One of the partner's edges in the pair's region: its index, box, and its face's normal.
#[derive(Debug, Clone, Copy, PartialEq)]
struct NearEdge {
    edge: u32,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
    normal: Vector3<f64>,
}

/// Edge–edge contacts of body `a`'s display edges with body `b`'s inside `[lo, hi]` at layer
/// thickness `h`, into `out` (`scratch`: [`EdgeScratch`]). Each edge of `a` looks at the
/// edges of `b` whose boxes come within the reach of its own, in their order. Only edges whose
/// faces meet at an angle (face normals more than 30° from opposite): between parallel faces
/// the samples' vertex–face contacts already carry the load. Both meshes must be up to date
/// in this step ([`super::prepare`]); reads the contact state only, so pairs run side by side.
pub(super) fn detect_edges(
    bc: &BodyContact,
    (a, b): (usize, usize),
    (lo, hi): (Vector3<f64>, Vector3<f64>),
    h: f64,
    scratch: &mut EdgeScratch,
    out: &mut Vec<Contact>,
) {
    let (Some(ma), Some(mb)) = (bc.mesh_of[a], bc.mesh_of[b]) else {
        return;
    };
    let (ea, eb) = (&bc.meshes[ma], &bc.meshes[mb]);
    debug_assert!(ea.is_current(bc.step) && eb.is_current(bc.step));
    let EdgeScratch {
        near,
        grid,
        candidates,
    } = scratch;
    near.clear();
    for (k, &[i, j, third]) in eb.edges.iter().enumerate() {
        let (p, q) = (eb.x[i as usize], eb.x[j as usize]);
        let (elo, ehi) = (p.inf(&q), p.sup(&q));
        if !boxes_apart((&elo, &ehi), (&lo, &hi)) {
            let normal = triangle_normal(&p, &q, &eb.x[third as usize]);
            let edge = k as u32;
            near.push(NearEdge {
                edge,
                lo: elo,
                hi: ehi,
                normal,
            });
        }
    }
    if near.is_empty() {
        return;
    }
    let gridded = near.len() > EDGES_WITHOUT_GRID;
    if gridded {
        let boxes = near.iter().enumerate().map(|(n, e)| (n as u32, e.lo, e.hi));
        grid.build(lo, hi, eb.mean_edge, near.len(), boxes);
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
        let (qlo, qhi) = (elo.add_scalar(-reach), ehi.add_scalar(reach));
        candidates.clear();
        if gridded {
            grid.query(&qlo, &qhi, candidates);
            candidates.sort_unstable();
        } else {
            candidates.extend(0..near.len() as u32);
        }
        let mut best: Option<(f64, Contact)> = None;
        for &n in candidates.iter() {
            let e = &near[n as usize];
            if boxes_apart((&e.lo, &e.hi), (&qlo, &qhi)) {
                continue;
            }
            let [i0, i1, _] = eb.edges[e.edge as usize];
            let (q0, q1, nb) = (eb.x[i0 as usize], eb.x[i1 as usize], e.normal);
            if na.dot(&nb) < parallel {
                continue;
            }
            let (s, r) = closest_between_segments(&p0, &p1, &q0, &q1);
            let inside = EDGE_END..1.0 - EDGE_END;
            if !inside.contains(&s) || !inside.contains(&r) {
                continue;
            }
            let cross = (p1 - p0).cross(&(q1 - q0));
            let len = cross.norm();
            if len <= MIN_EDGE_SINE * (p1 - p0).norm() * (q1 - q0).norm() {
                continue;
            }
            let mut n = cross / len;
            if n.dot(&nb) < 0.0 {
                n = -n;
            }
            // Only edges facing each other: a's surface turned towards b.
            if n.dot(&na) >= -EDGE_FACING || n.dot(&nb) <= EDGE_FACING {
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
            out.push(c);
        }
    }
}

/// Whether boxes `a` and `b` (each its low and high corners) are apart along an axis.
fn boxes_apart(a: (&Vector3<f64>, &Vector3<f64>), b: (&Vector3<f64>, &Vector3<f64>)) -> bool {
    (0..3).any(|k| a.1[k] < b.0[k] || a.0[k] > b.1[k])
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
    bc.update_samples(input.surface, input.nodes, a);
    for i in bc.points[a].clone() {
        let Some((x, v)) = sample_in(bc, i, (&lo, &hi)) else {
            continue;
        };
        // The grid query box: the segment from the previous position, grown by the reach.
        let (prev, reach) = (x - v * dt, h.max(behind));
        let (qlo, qhi) = (
            x.inf(&prev).add_scalar(-reach),
            x.sup(&prev).add_scalar(reach),
        );
        let col = &mut bc.colliders[c];
        col.grid.query(&qlo, &qhi, &mut bc.candidates);
        let probe = Probe {
            x,
            v,
            dt,
            h,
            behind,
            two_sided: col.two_sided,
        };
        let faces = ColliderFaces(col);
        if let Some(hit) = best_face(probe, &bc.candidates, &faces, &mut bc.bounds, None) {
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

#[cfg(test)]
mod tests {
    use super::super::mesh::refine;
    use super::*;
    use crate::shapes::{box_mesh, uv_sphere};

    /// Triangles over moving vertices.
    struct Moving {
        x: Vec<Vector3<f64>>,
        v: Vec<Vector3<f64>>,
        triangles: Vec<[u32; 3]>,
    }

    impl Faces for Moving {
        fn corners(&self, t: usize) -> [Vector3<f64>; 3] {
            self.triangles[t].map(|i| self.x[i as usize])
        }
        fn bounds(&self, t: usize) -> (Vector3<f64>, Vector3<f64>) {
            let [a, b, c] = self.corners(t);
            (a.inf(&b).inf(&c), a.sup(&b).sup(&c))
        }
        fn plane(&self, t: usize) -> (Vector3<f64>, f64) {
            let [a, b, c] = self.corners(t);
            let n = triangle_normal(&a, &b, &c);
            (n, n.dot(&a))
        }
        fn speed(&self, t: usize) -> f64 {
            self.triangles[t]
                .iter()
                .map(|&i| self.v[i as usize].norm())
                .fold(0.0, f64::max)
        }
        fn velocity(&self, t: usize, w: [f64; 3]) -> Vector3<f64> {
            let tri = self.triangles[t];
            (0..3).map(|k| self.v[tri[k] as usize] * w[k]).sum()
        }
    }

    /// The search without bounds: every candidate looked at, in order.
    /// Also says whether the contact is a crossing.
    fn exhaustive(probe: Probe, candidates: &[u32], faces: &Moving) -> Option<(FaceHit, bool)> {
        let Probe { x, v, dt, h, .. } = probe;
        let mut crossing: Option<(f64, FaceHit)> = None;
        let mut near: Option<(Near, FaceHit)> = None;
        for &t in candidates {
            let t = t as usize;
            let (n, _) = faces.plane(t);
            if n == Vector3::zeros() {
                continue;
            }
            let [a, b, c] = faces.corners(t);
            let (bary, interior) = closest_on_triangle(&x, &a, &b, &c);
            let q = a * bary[0] + b * bary[1] + c * bary[2];
            let vq = faces.velocity(t, bary);
            let s_now = (x - a).dot(&n);
            let prev = x - (v - vq) * dt;
            if s_now < 0.0 && (prev - a).dot(&n) > 0.0 {
                if let Some((u, w)) = segment_crosses_triangle(&prev, &x, &a, &b, &c) {
                    if crossing.is_none_or(|c| u < c.0) {
                        let velocity = faces.velocity(t, w);
                        let (depth, tri) = (h - s_now, t);
                        let hit = FaceHit {
                            tri,
                            bary: w,
                            normal: n,
                            depth,
                            velocity,
                            outside_by: 0.0,
                            rim: false,
                        };
                        crossing = Some((u, hit));
                    }
                }
            }
            if let Some(found) = near_contact(&probe, q, n, interior) {
                if near.is_none_or(|(best, _)| found.beats(&best, false)) {
                    let hit = FaceHit {
                        tri: t,
                        bary,
                        normal: found.normal,
                        depth: found.depth,
                        velocity: vq,
                        outside_by: found.outside_by(h),
                        rim: found.rim,
                    };
                    near = Some((found, hit));
                }
            }
        }
        match crossing {
            Some((_, hit)) => Some((hit, true)),
            None => near.map(|(_, hit)| (hit, false)),
        }
    }

    /// A tiny deterministic generator in [-1, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
        fn vector(&mut self) -> Vector3<f64> {
            Vector3::new(self.next(), self.next(), self.next())
        }
    }

    /// How the scatter hands the candidates to the search.
    #[derive(Clone, Copy, PartialEq)]
    enum Ranking {
        /// In order, no distances known.
        Plain,
        /// Nearest first by a bound taken with the point up to 1 cm away, with that as slack
        /// (a neighbour list built a few steps ago).
        Ranked,
        /// The same without the slack (a list that forgot how far things moved).
        NoSlack,
    }

    /// Points scattered through a shell around a refined box and a UV sphere, in front of
    /// them, just behind them, crossing them in the step, on moving and resting surfaces:
    /// each searched as `ranking` says and by looking at every face. Returns (contacts,
    /// crossings, contacts behind a face, points where the two disagree).
    fn scatter(ranking: Ranking) -> (usize, usize, usize, usize) {
        let (box_points, box_triangles) = box_mesh([-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]);
        let (box_points, box_triangles) = refine(&box_points, &box_triangles, 0.1);
        let (sphere_points, sphere_triangles) = uv_sphere([2.0, 0.0, 0.0], 0.5, 12, 24);
        let mut rng = Lcg(7);
        let (mut found, mut crossings, mut behind_hits, mut wrong) = (0, 0, 0, 0);
        let mut bounds = Vec::new();
        for (points, triangles) in [
            (box_points, box_triangles),
            (sphere_points, sphere_triangles),
        ] {
            let centre =
                points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64;
            for moving in [false, true] {
                let faces = Moving {
                    x: points.iter().map(|p| p.coords).collect(),
                    v: points
                        .iter()
                        .map(|_| {
                            if moving {
                                rng.vector() * 0.5
                            } else {
                                Vector3::zeros()
                            }
                        })
                        .collect(),
                    triangles: triangles.clone(),
                };
                let fastest = faces.v.iter().map(|v| v.norm()).fold(0.0, f64::max);
                let all: Vec<u32> = (0..triangles.len() as u32).collect();
                for _ in 0..2000 {
                    let p =
                        points[(rng.next().abs() * points.len() as f64) as usize % points.len()];
                    let out = (p.coords - centre).normalize();
                    let x = p.coords + out * (0.06 * rng.next()) + rng.vector() * 0.03;
                    let probe = Probe {
                        x,
                        v: rng.vector() * if rng.next() > 0.0 { 40.0 } else { 0.5 },
                        dt: 1e-3,
                        h: 0.05,
                        behind: 0.05,
                        two_sided: false,
                    };
                    let moved = rng.vector() * (0.01 / 3f64.sqrt());
                    let want = exhaustive(probe, &all, &faces);
                    let got = if ranking == Ranking::Plain {
                        best_face(probe, &all, &faces, &mut bounds, None)
                    } else {
                        let then = x + moved;
                        let mut ranked: Vec<(f64, u32)> = all
                            .iter()
                            .map(|&t| (faces.distance_bound(t as usize, &then), t))
                            .collect();
                        ranked.sort_by(|p, q| p.0.total_cmp(&q.0));
                        let order: Vec<u32> = ranked.iter().map(|r| r.1).collect();
                        let lower: Vec<f64> = ranked.iter().map(|r| r.0).collect();
                        let slack = if ranking == Ranking::Ranked {
                            moved.norm()
                        } else {
                            0.0
                        };
                        let ranked = Ranked {
                            lower: &lower,
                            slack,
                            fastest,
                        };
                        best_face(probe, &order, &faces, &mut bounds, Some(ranked))
                    };
                    match (want, got) {
                        (None, None) => {}
                        (Some((w, crossed)), Some(g)) => {
                            found += 1;
                            crossings += usize::from(crossed);
                            behind_hits += usize::from(!crossed && w.depth > probe.h);
                            let same = (w.depth - g.depth).abs() < 1e-9
                                && (w.normal - g.normal).norm() < 1e-9
                                && (w.velocity - g.velocity).norm() < 1e-9;
                            wrong += usize::from(!same);
                        }
                        _ => wrong += 1,
                    }
                }
            }
        }
        (found, crossings, behind_hits, wrong)
    }

    /// The bounded search finds the same contact (depth, normal, velocity) as looking at
    /// every face, and so does the search of a neighbour list's ranked candidates that stops
    /// early; the scatter reaches every kind of contact.
    #[test]
    fn the_bounded_search_finds_what_looking_at_every_face_finds() {
        for ranking in [Ranking::Plain, Ranking::Ranked] {
            let (found, crossings, behind_hits, wrong) = scatter(ranking);
            assert_eq!(wrong, 0, "{wrong} points found another contact");
            assert!(found > 2000, "{found} contacts");
            assert!(behind_hits > 100, "{behind_hits} contacts behind a face");
            assert!(crossings > 100, "{crossings} crossings");
        }
        // The early stop needs the slack: without it the scatter finds wrong contacts.
        let (_, _, _, wrong) = scatter(Ranking::NoSlack);
        assert!(wrong > 10, "only {wrong} points differ without the slack");
    }
}
