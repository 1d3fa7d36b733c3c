//! USD mesh data on the Rust side: the raw arrays the bridge reads from a `UsdGeomMesh`
//! ([`RawMesh`]), their validation, polygon triangulation (fan for convex faces, ear clipping
//! otherwise), primvar expansion by interpolation and the split into display vertices
//! ([`build_display_mesh`]); plus the per-frame normals and extents the exporter writes.

use springbake_core::display::{DisplayMesh, Primitive};
use springbake_core::nalgebra::{Matrix4, Vector3};
use springbake_core::plugin::PluginError;
use std::collections::HashMap;
use std::path::Path;

/// How a primvar's values map onto the mesh (UsdGeom interpolation; `varying` behaves as
/// `vertex` on a polygon mesh).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    Constant,
    Uniform,
    Vertex,
    FaceVarying,
}

impl Interpolation {
    pub fn parse(token: &str) -> Option<Self> {
        match token {
            "constant" => Some(Self::Constant),
            "uniform" => Some(Self::Uniform),
            "vertex" | "varying" => Some(Self::Vertex),
            "faceVarying" => Some(Self::FaceVarying),
            _ => None,
        }
    }
}

/// A flattened (indices resolved) primvar: `values` holds `dims` floats per element.
#[derive(Debug, Clone, PartialEq)]
pub struct RawPrimvar {
    pub interpolation: Interpolation,
    pub values: Vec<f64>,
}

/// One `UsdGeomMesh` as authored.
#[derive(Debug, Clone, PartialEq)]
pub struct RawMesh {
    /// Prim path, e.g. `/root/Body/Cube`.
    pub path: String,
    pub name: String,
    pub points: Vec<[f64; 3]>,
    pub counts: Vec<i32>,
    pub indices: Vec<i32>,
    pub normals: Option<RawPrimvar>,
    /// `"normals"` (the attribute) or `"primvars:normals"`.
    pub normals_source: Option<String>,
    pub st: Option<RawPrimvar>,
    pub left_handed: bool,
    pub material: Option<String>,
    /// Materials bound to faces through GeomSubsets: (material name, face indices).
    pub subsets: Vec<(String, Vec<i32>)>,
    /// `ComputeLocalToWorldTransform` as Gf stores it: row-major, row vectors.
    pub world_gf: [f64; 16],
}

impl RawMesh {
    /// The Gf matrix (row vectors, `p' = p·M`) as a column-vector nalgebra matrix: `Mᵀ`.
    pub fn world_from_local(&self) -> Matrix4<f64> {
        // from_column_slice reads Gf's rows as columns, i.e. transposes.
        Matrix4::from_column_slice(&self.world_gf)
    }

    /// Check counts, indices and points; `Ok` means every later index is in range.
    pub fn validate(&self, file: &Path) -> Result<(), PluginError> {
        for (i, p) in self.points.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(PluginError::invalid(
                    file,
                    format!("point {i} is not finite: ({}, {}, {})", p[0], p[1], p[2]),
                )
                .at(format!("{}.points[{i}]", self.path)));
            }
        }
        let mut total = 0usize;
        for (f, &c) in self.counts.iter().enumerate() {
            if c < 3 {
                return Err(PluginError::invalid(
                    file,
                    format!("face {f} has {c} vertices; a polygon needs at least 3"),
                )
                .at(format!("{}.faceVertexCounts[{f}]", self.path)));
            }
            total += c as usize;
        }
        if total != self.indices.len() {
            return Err(PluginError::invalid(
                file,
                format!(
                    "faceVertexCounts add up to {total} but faceVertexIndices has {} entries",
                    self.indices.len()
                ),
            )
            .at(format!("{}.faceVertexIndices", self.path)));
        }
        for (j, &i) in self.indices.iter().enumerate() {
            if i < 0 || i as usize >= self.points.len() {
                return Err(PluginError::invalid(
                    file,
                    format!("index {i} is outside points (0..{})", self.points.len()),
                )
                .at(format!("{}.faceVertexIndices[{j}]", self.path)));
            }
        }
        if self.counts.is_empty() {
            return Err(PluginError::invalid(file, "mesh has no faces")
                .at(format!("{}.faceVertexCounts", self.path)));
        }
        Ok(())
    }
}

/// Which element of a primvar with `interpolation` applies at face `face`, face-vertex `fv`
/// (running index into faceVertexIndices) referring to point `point`.
fn element(interpolation: Interpolation, face: usize, fv: usize, point: usize) -> usize {
    match interpolation {
        Interpolation::Constant => 0,
        Interpolation::Uniform => face,
        Interpolation::Vertex => point,
        Interpolation::FaceVarying => fv,
    }
}

fn expected_len(interpolation: Interpolation, mesh: &RawMesh) -> usize {
    match interpolation {
        Interpolation::Constant => 1,
        Interpolation::Uniform => mesh.counts.len(),
        Interpolation::Vertex => mesh.points.len(),
        Interpolation::FaceVarying => mesh.indices.len(),
    }
}

fn check_primvar(
    pv: &RawPrimvar,
    dims: usize,
    mesh: &RawMesh,
    attr: &str,
    file: &Path,
) -> Result<(), PluginError> {
    let want = expected_len(pv.interpolation, mesh);
    let have = pv.values.len() / dims;
    if have != want || have * dims != pv.values.len() {
        return Err(PluginError::invalid(
            file,
            format!(
                "{attr} has {have} values but {:?} interpolation needs {want}",
                pv.interpolation
            ),
        )
        .at(format!("{}.{attr}", mesh.path)));
    }
    if let Some(i) = pv.values.iter().position(|v| !v.is_finite()) {
        return Err(
            PluginError::invalid(file, format!("{attr} value is not finite")).at(format!(
                "{}.{attr}[{}]",
                mesh.path,
                i / dims
            )),
        );
    }
    Ok(())
}

/// The display mesh of a raw USD mesh: polygons triangulated, vertices split wherever a
/// face-varying (or uniform) normal or uv differs, `source_point_of_vertex` pointing at
/// `points`.
pub fn build_display_mesh(raw: &RawMesh, file: &Path) -> Result<DisplayMesh, PluginError> {
    raw.validate(file)?;
    let normals_attr = raw.normals_source.as_deref().unwrap_or("normals");
    if let Some(n) = &raw.normals {
        check_primvar(n, 3, raw, normals_attr, file)?;
    }
    if let Some(st) = &raw.st {
        check_primvar(st, 2, raw, "primvars:st", file)?;
    }
    // Each face's material group: its GeomSubset's material, else the mesh's own; one
    // primitive per group, in order of the groups' first face.
    let face_count = raw.counts.len();
    let mut group_of_face: Vec<Option<String>> = vec![raw.material.clone(); face_count];
    for (material, faces) in &raw.subsets {
        for &f in faces {
            let f = usize::try_from(f)
                .ok()
                .filter(|&f| f < face_count)
                .ok_or_else(|| {
                    PluginError::invalid(
                        file,
                        format!("a GeomSubset names face {f}, the mesh has {face_count}"),
                    )
                    .at(raw.path.clone())
                })?;
            group_of_face[f] = Some(material.clone());
        }
    }
    let mut groups: Vec<Option<String>> = Vec::new();
    for g in &group_of_face {
        if !groups.contains(g) {
            groups.push(g.clone());
        }
    }
    let mut first_corner = Vec::with_capacity(face_count);
    let mut fv = 0usize;
    for &count in &raw.counts {
        first_corner.push(fv);
        fv += count as usize;
    }
    let mut primitives = Vec::with_capacity(groups.len());
    let mut source: Vec<u32> = Vec::new();
    for group in &groups {
        let faces = (0..face_count).filter(|&f| &group_of_face[f] == group);
        let (primitive, points) = build_primitive(raw, faces, &first_corner, group.clone());
        source.extend(points);
        primitives.push(primitive);
    }
    let point_count = raw.points.len();
    Ok(DisplayMesh {
        name: raw.name.clone(),
        source_key: raw.path.clone(),
        world_from_local: raw.world_from_local(),
        primitives,
        source_point_of_vertex: source,
        source_point_count: point_count,
    })
}

/// The faces `faces` of `raw` as one primitive (display vertices unique per point, normal and
/// UV), and the source point of each of its vertices.
fn build_primitive(
    raw: &RawMesh,
    faces: impl Iterator<Item = usize>,
    first_corner: &[usize],
    material: Option<String>,
) -> (Primitive, Vec<u32>) {
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut normals: Vec<[f32; 3]> = Vec::new();
    let mut uvs: Vec<[f32; 2]> = Vec::new();
    let mut source: Vec<u32> = Vec::new();
    let mut triangles: Vec<u32> = Vec::new();
    // (point, normal bits, uv bits) → display vertex
    let mut seen: HashMap<(u32, [u32; 3], [u32; 2]), u32> = HashMap::new();
    let mut corner_vertices: Vec<u32> = Vec::new();
    let mut corner_positions: Vec<[f64; 3]> = Vec::new();
    for face in faces {
        corner_vertices.clear();
        corner_positions.clear();
        let start = first_corner[face];
        for fv in start..start + raw.counts[face] as usize {
            let point = raw.indices[fv] as usize;
            let normal = raw.normals.as_ref().map(|n| {
                let e = element(n.interpolation, face, fv, point) * 3;
                [
                    n.values[e] as f32,
                    n.values[e + 1] as f32,
                    n.values[e + 2] as f32,
                ]
            });
            let uv = raw.st.as_ref().map(|s| {
                let e = element(s.interpolation, face, fv, point) * 2;
                [s.values[e] as f32, s.values[e + 1] as f32]
            });
            let key = (
                point as u32,
                normal.map_or([0; 3], |n| n.map(f32::to_bits)),
                uv.map_or([0; 2], |t| t.map(f32::to_bits)),
            );
            let vertex = *seen.entry(key).or_insert_with(|| {
                let p = raw.points[point];
                positions.push([p[0] as f32, p[1] as f32, p[2] as f32]);
                if let Some(n) = normal {
                    normals.push(n);
                }
                if let Some(t) = uv {
                    uvs.push(t);
                }
                source.push(point as u32);
                (positions.len() - 1) as u32
            });
            corner_vertices.push(vertex);
            corner_positions.push(raw.points[point]);
        }
        for t in triangulate(&corner_positions) {
            let [a, b, c] = t.map(|i| corner_vertices[i]);
            if raw.left_handed {
                triangles.extend([a, c, b]);
            } else {
                triangles.extend([a, b, c]);
            }
        }
    }
    let primitive = Primitive {
        positions,
        normals: raw.normals.as_ref().map(|_| normals),
        uvs: raw.st.as_ref().map(|_| uvs),
        indices: triangles,
        material,
    };
    (primitive, source)
}

fn v3(p: [f64; 3]) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

/// Newell's normal of a polygon (length = twice the area).
pub fn newell_normal(poly: &[[f64; 3]]) -> Vector3<f64> {
    let mut n = Vector3::zeros();
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        n += v3(a).cross(&v3(b));
    }
    n
}

pub use springbake_core::polygon::triangulate;

/// Area-weighted face normals of polygon faces accumulated per point, normalized: smooth
/// `vertex`-interpolated normals of deformed `points`.
pub fn point_normals(points: &[[f32; 3]], counts: &[i32], indices: &[i32]) -> Vec<[f32; 3]> {
    let mut acc = vec![Vector3::<f64>::zeros(); points.len()];
    for_each_face(points, counts, indices, |corners, n| {
        for &p in corners {
            acc[p] += n;
        }
    });
    acc.into_iter().map(unit).collect()
}

/// Face-varying normals of deformed `points` that keep the rest normals' smoothing: at each
/// point, the faces whose rest normal there is the same (an unbroken smoothing group) share the
/// area-weighted average of their deformed face normals; a face with its own normal (a hard
/// edge) keeps its deformed face normal.
pub fn face_varying_normals(
    points: &[[f32; 3]],
    counts: &[i32],
    indices: &[i32],
    rest_face_varying: &[[f32; 3]],
) -> Vec<[f32; 3]> {
    let quant = |n: [f32; 3]| n.map(|c| (c * 1024.0).round() as i32);
    let mut groups: HashMap<(usize, [i32; 3]), Vector3<f64>> = HashMap::new();
    let mut keys = Vec::with_capacity(indices.len());
    let mut fv = 0usize;
    for_each_face(points, counts, indices, |corners, n| {
        for &p in corners {
            let rest = rest_face_varying.get(fv).copied().unwrap_or([0.0; 3]);
            let key = (p, quant(rest));
            *groups.entry(key).or_insert_with(Vector3::zeros) += n;
            keys.push(key);
            fv += 1;
        }
    });
    keys.iter()
        .map(|k| unit(groups.get(k).copied().unwrap_or_else(Vector3::zeros)))
        .collect()
}

fn for_each_face(
    points: &[[f32; 3]],
    counts: &[i32],
    indices: &[i32],
    mut f: impl FnMut(&[usize], Vector3<f64>),
) {
    let mut start = 0usize;
    let mut corners: Vec<usize> = Vec::new();
    let mut poly: Vec<[f64; 3]> = Vec::new();
    for &c in counts {
        let end = start + c.max(0) as usize;
        corners.clear();
        poly.clear();
        for &i in indices.get(start..end).unwrap_or(&[]) {
            let i = i.max(0) as usize;
            corners.push(i);
            let p = points.get(i).copied().unwrap_or([0.0; 3]);
            poly.push([p[0] as f64, p[1] as f64, p[2] as f64]);
        }
        f(&corners, newell_normal(&poly));
        start = end;
    }
}

fn unit(n: Vector3<f64>) -> [f32; 3] {
    let len = n.norm();
    if len > 0.0 {
        [(n.x / len) as f32, (n.y / len) as f32, (n.z / len) as f32]
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// `[min x, min y, min z, max x, max y, max z]` of `points`.
pub fn extent(points: &[[f32; 3]]) -> [f32; 6] {
    let mut e = [
        f32::INFINITY,
        f32::INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NEG_INFINITY,
        f32::NEG_INFINITY,
    ];
    for p in points {
        for k in 0..3 {
            e[k] = e[k].min(p[k]);
            e[k + 3] = e[k + 3].max(p[k]);
        }
    }
    if points.is_empty() {
        e = [0.0; 6];
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(poly: &[[f64; 3]], tris: &[[usize; 3]]) -> f64 {
        tris.iter()
            .map(|t| newell_normal(&[poly[t[0]], poly[t[1]], poly[t[2]]]).norm() / 2.0)
            .sum()
    }

    #[test]
    fn concave_polygon_is_ear_clipped_without_overlap() {
        // An L shape (concave at corner 3) in the XZ plane: area 3.
        let poly = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, 2.0],
            [0.0, 0.0, 2.0],
        ];
        let tris = triangulate(&poly);
        assert_eq!(tris.len(), 4);
        assert!((area(&poly, &tris) - 3.0).abs() < 1e-12);
        // Every triangle faces the polygon's own normal (no flipped ears).
        let n = newell_normal(&poly);
        for t in &tris {
            let tn = newell_normal(&[poly[t[0]], poly[t[1]], poly[t[2]]]);
            assert!(tn.dot(&n) > 0.0, "{t:?}");
        }
        // A fan from corner 0 would cover area outside the L; ear clipping must not.
        assert!(tris
            .iter()
            .all(|t| !(t.contains(&0) && t.contains(&2) && t.contains(&4))));
    }

    #[test]
    fn convex_24_gon_fans_into_22_triangles() {
        let poly: Vec<[f64; 3]> = (0..24)
            .map(|i| {
                let a = i as f64 / 24.0 * std::f64::consts::TAU;
                [a.cos(), a.sin(), 0.5]
            })
            .collect();
        let tris = triangulate(&poly);
        assert_eq!(tris.len(), 22);
        let expected = 0.5 * 24.0 * (std::f64::consts::TAU / 24.0).sin();
        assert!((area(&poly, &tris) - expected).abs() < 1e-12);
    }

    fn quad_mesh() -> RawMesh {
        // Two quads sharing an edge (points 1, 4), with faceVarying uvs split on that edge.
        RawMesh {
            path: "/m".into(),
            name: "m".into(),
            points: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
                [2.0, 1.0, 0.0],
            ],
            counts: vec![4, 4],
            indices: vec![0, 1, 4, 3, 1, 2, 5, 4],
            normals: Some(RawPrimvar {
                interpolation: Interpolation::Constant,
                values: vec![0.0, 0.0, 1.0],
            }),
            normals_source: Some("normals".into()),
            st: Some(RawPrimvar {
                interpolation: Interpolation::FaceVarying,
                values: vec![
                    0.0, 0.0, 0.5, 0.0, 0.5, 1.0, 0.0, 1.0, // face 0
                    0.6, 0.0, 1.0, 0.0, 1.0, 1.0, 0.6, 1.0, // face 1: seam at x=1
                ],
            }),
            left_handed: false,
            material: Some("Red".into()),
            subsets: Vec::new(),
            world_gf: [
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 10.0, 20.0, 30.0, 1.0,
            ],
        }
    }

    #[test]
    fn face_varying_uvs_split_vertices_and_map_back_to_points() {
        let raw = quad_mesh();
        let m = build_display_mesh(&raw, Path::new("x.usda")).unwrap();
        let p = &m.primitives[0];
        // 6 points, the two on the seam doubled.
        assert_eq!(p.positions.len(), 8);
        assert_eq!(m.source_point_count, 6);
        assert_eq!(m.source_point_of_vertex, vec![0, 1, 4, 3, 1, 2, 5, 4]);
        assert_eq!(p.uvs.as_ref().unwrap()[4], [0.6, 0.0]);
        assert_eq!(p.normals.as_ref().unwrap()[7], [0.0, 0.0, 1.0]);
        assert_eq!(p.indices.len(), 12);
        assert_eq!(p.material.as_deref(), Some("Red"));
        // Triangles wind like the quads (+Z normal).
        for t in p.indices.chunks(3) {
            let q = |i: u32| p.positions[i as usize].map(|c| c as f64);
            assert!(newell_normal(&[q(t[0]), q(t[1]), q(t[2])]).z > 0.0);
        }
        // Gf's translation row becomes nalgebra's translation column.
        let w = m.world_from_local;
        assert_eq!((w[(0, 3)], w[(1, 3)], w[(2, 3)]), (10.0, 20.0, 30.0));
        // Scatter back: every point gets its own position.
        let back = m.to_source_points(&p.positions, [f32::NAN; 3]);
        for (i, q) in back.iter().enumerate() {
            assert_eq!(q.map(|c| c as f64), raw.points[i]);
        }
    }

    #[test]
    fn left_handed_meshes_flip_winding() {
        let mut raw = quad_mesh();
        raw.left_handed = true;
        let m = build_display_mesh(&raw, Path::new("x.usda")).unwrap();
        let p = &m.primitives[0];
        for t in p.indices.chunks(3) {
            let q = |i: u32| p.positions[i as usize].map(|c| c as f64);
            assert!(newell_normal(&[q(t[0]), q(t[1]), q(t[2])]).z < 0.0);
        }
    }

    #[test]
    fn bad_arrays_are_reported_at_their_attribute() {
        let file = Path::new("x.usda");
        let mut raw = quad_mesh();
        raw.points[3][1] = f64::NAN;
        let e = build_display_mesh(&raw, file).unwrap_err();
        assert_eq!(e.location.as_deref(), Some("/m.points[3]"));

        let mut raw = quad_mesh();
        raw.indices[5] = 9;
        let e = build_display_mesh(&raw, file).unwrap_err();
        assert_eq!(e.location.as_deref(), Some("/m.faceVertexIndices[5]"));

        let mut raw = quad_mesh();
        raw.counts = vec![4, 2, 2];
        let e = build_display_mesh(&raw, file).unwrap_err();
        assert_eq!(e.location.as_deref(), Some("/m.faceVertexCounts[1]"));

        let mut raw = quad_mesh();
        raw.st.as_mut().unwrap().values.truncate(10);
        let e = build_display_mesh(&raw, file).unwrap_err();
        assert_eq!(e.location.as_deref(), Some("/m.primvars:st"));
        assert!(e.message.contains("needs 8"), "{}", e.message);
    }

    #[test]
    fn face_varying_normals_keep_hard_and_smooth_edges() {
        // A folded strip: two quads meeting at a 90° edge (points 1, 4).
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, -1.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 1.0, -1.0],
        ];
        let counts = [4, 4];
        let indices = [0, 1, 4, 3, 1, 2, 5, 4];
        let a = [0.0, 0.0, 1.0];
        let b = [1.0, 0.0, 0.0];
        // Hard edge: each face its own normal.
        let hard = face_varying_normals(&points, &counts, &indices, &[a, a, a, a, b, b, b, b]);
        assert_eq!(hard[1], [0.0, 0.0, 1.0]);
        assert_eq!(hard[4], [1.0, 0.0, 0.0]);
        // Smooth edge: the shared points average both faces.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let m = [s, 0.0, s];
        let smooth = face_varying_normals(&points, &counts, &indices, &[a, m, m, a, m, b, b, m]);
        assert!((smooth[1][0] - s).abs() < 1e-6 && (smooth[1][2] - s).abs() < 1e-6);
        assert_eq!(smooth[1], smooth[4]);
        assert_eq!(smooth[0], [0.0, 0.0, 1.0]);
        let pn = point_normals(&points, &counts, &indices);
        assert_eq!(pn[1], smooth[1]);
        assert_eq!(extent(&points), [0.0, 0.0, -1.0, 1.0, 1.0, 0.0]);
    }
}
