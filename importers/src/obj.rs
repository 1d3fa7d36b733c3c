//! Wavefront OBJ import: `v`/`vt`/`vn`/`f` geometry, `o` objects, `g` groups, `usemtl`
//! material groups and `mtllib` references, into one [`DisplayMesh`] per `o` object.
//!
//! The parser is hand-written rather than taken from a crate because every bad line must be
//! reported with its 1-based line number (`PluginError::location = "line 17"`), and because the
//! point order of each object has to follow Blender's OBJ importer exactly so that point caches
//! (PC2, MDD) written in that order play on the OBJ Blender imports.
//!
//! What Blender 5.0.1's `bpy.ops.wm.obj_import` does, checked with `bpy` (and mirrored here):
//! - each `o` starts a new object; faces before the first `o` belong to an object named after
//!   the file; objects without faces are not created;
//! - `g` does not split objects by default (`use_split_groups=False`), so groups are read and
//!   otherwise ignored;
//! - an object's vertices are the `v` entries its faces use, *in the order of the file's `v`
//!   lines* (not the order faces first refer to them); unused `v` entries are dropped; a face
//!   may use `v` entries written under an earlier object;
//! - `usemtl` state carries across `o` lines;
//! - a face corner naming a texture coordinate or normal the file does not have (`f 1/1/1`
//!   with no `vt` lines: trimesh's test files, hand-edited exports) loses that index and the
//!   face stays; springbake says so in a note.
//!
//! - `l` (polyline) elements add their vertices to the object as loose vertices; `p` elements
//!   are ignored; a face with a repeated corner is dropped but its vertices stay.
//!
//! `DisplayMesh::source_point_of_vertex` maps every display vertex (a unique `v/vt/vn` tuple
//! within one material primitive) to that per-object point index. Lines are not simulated, but
//! their loose points are kept as display vertices no triangle uses (in the first primitive), so
//! every point Blender's object has gets a position in a point cache. Degenerate faces are kept
//! as zero-area triangles.
//!
//! Faces with more than three corners are triangulated by ear clipping in the face's best-fit
//! (Newell) plane, so concave n-gons keep their area; a degenerate or self-intersecting polygon
//! falls back to clipping whatever corner keeps the walk going, and a huge concave face stops
//! searching for ears after a fixed amount of work (so hostile input cannot stall the import). Missing normals are computed per object point
//! with [`vertex_normals`] (smooth, area weighted) so UV seams don't split them.

use springbake_core::display::{
    vertex_normals, DisplayMesh, ImportedScene, Primitive, SourceDocument, UpAxis,
};
use springbake_core::plugin::{ImportSettings, Importer, PluginError};
use springbake_core::polygon::triangulate;
use std::collections::HashMap;
use std::path::Path;

/// The OBJ importer plug-in (`name() == "obj"`).
#[derive(Debug, Clone, Copy, Default)]
pub struct ObjImporter;

impl Importer for ObjImporter {
    fn name(&self) -> &str {
        "obj"
    }

    fn extensions(&self) -> &[&str] {
        &["obj"]
    }

    fn import(
        &self,
        path: &Path,
        bytes: &[u8],
        settings: &ImportSettings,
    ) -> Result<ImportedScene, PluginError> {
        let doc = ObjDocument::parse(path, bytes)?;
        let meshes = doc.display_meshes(path, settings)?;
        let root = settings
            .root
            .clone()
            .unwrap_or_else(|| path.parent().map(Path::to_path_buf).unwrap_or_default());
        let (materials, mtl_notes) = crate::mtl::read_libraries(path, &doc.mtllibs, &root)?;
        let notes = doc.notes.iter().cloned().chain(mtl_notes).collect();
        Ok(ImportedScene {
            materials,
            notes,
            meshes,
            up_axis: UpAxis::Y,
            meters_per_unit: 1.0,
            source: SourceDocument {
                path: path.to_path_buf(),
                importer: "obj".into(),
                read_root: None,
            },
        })
    }
}

/// One face corner: 0-based indices into the file's `v`, `vt` and `vn` lists.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Corner {
    pub v: u32,
    pub vt: Option<u32>,
    pub vn: Option<u32>,
}

/// One `f` line.
#[derive(Debug, Clone, PartialEq)]
pub struct Face {
    pub corners: Vec<Corner>,
    /// Index into [`ObjDocument::materials`], from the last `usemtl`.
    pub material: Option<usize>,
    /// 1-based line number of the `f` statement.
    pub line: usize,
}

/// One `o` object (or the implicit object before the first `o`).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjObject {
    pub name: String,
    pub faces: Vec<Face>,
    /// 0-based `v` indices used by this object's `l` (polyline) elements, in file order.
    pub line_points: Vec<u32>,
}

/// A parsed OBJ file, before it is turned into display meshes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObjDocument {
    pub positions: Vec<[f64; 3]>,
    pub texcoords: Vec<[f64; 2]>,
    pub normals: Vec<[f64; 3]>,
    /// Objects in file order, including ones without faces.
    pub objects: Vec<ObjObject>,
    /// `usemtl` names in order of first use.
    pub materials: Vec<String>,
    /// `mtllib` references as written (read by [`crate::mtl`]; a missing one is a note).
    pub mtllibs: Vec<String>,
    /// `g` group names seen (groups do not split objects, as in Blender's default import).
    pub groups: Vec<String>,
    /// Number of `l` and `p` elements (not simulated; see the module doc).
    pub skipped_lines_and_points: usize,
    /// What was read leniently and the user should hear about (faces naming texture
    /// coordinates or normals the file does not have).
    pub notes: Vec<String>,
}

fn err_at(path: &Path, line: usize, message: impl Into<String>) -> PluginError {
    PluginError::invalid(path, message).at(format!("line {line}"))
}

/// Parse one coordinate, refusing NaN, infinities and values beyond `f32`.
fn parse_coord(path: &Path, line: usize, token: &str, what: &str) -> Result<f64, PluginError> {
    let value: f64 = token
        .parse()
        .map_err(|_| err_at(path, line, format!("{what}: `{token}` is not a number")))?;
    if !value.is_finite() {
        return Err(err_at(
            path,
            line,
            format!("{what}: `{token}` is not a finite number"),
        ));
    }
    if !(value as f32).is_finite() {
        return Err(err_at(
            path,
            line,
            format!(
                "{what}: `{token}` is beyond the range of the 32-bit floats meshes are stored in \
                 (±3.4e38)"
            ),
        ));
    }
    Ok(value)
}

fn parse_coords<const N: usize>(
    path: &Path,
    line: usize,
    tokens: &[&str],
    min: usize,
    max: usize,
    what: &str,
) -> Result<[f64; N], PluginError> {
    if tokens.len() < min || tokens.len() > max {
        return Err(err_at(
            path,
            line,
            format!(
                "{what} needs {} numbers, found {}",
                if min == max {
                    min.to_string()
                } else {
                    format!("{min} to {max}")
                },
                tokens.len()
            ),
        ));
    }
    let mut out = [0.0; N];
    for (i, t) in tokens.iter().enumerate() {
        let v = parse_coord(path, line, t, what)?;
        if i < N {
            out[i] = v;
        }
    }
    Ok(out)
}

/// Resolve a 1-based or negative (relative) OBJ index against `count` entries seen so far.
/// Positive indices are range-checked later (after the whole file), negative ones now.
fn resolve_index(
    path: &Path,
    line: usize,
    token: &str,
    count: usize,
    what: &str,
) -> Result<i64, PluginError> {
    let n: i64 = token
        .parse()
        .map_err(|_| err_at(path, line, format!("face: `{token}` is not a {what} index")))?;
    if n > 0 {
        Ok(n - 1)
    } else if n < 0 {
        let idx = count as i64 + n;
        if idx < 0 {
            Err(err_at(
                path,
                line,
                format!(
                    "face: relative {what} index {n} reaches before the first {what} ({count} so far)"
                ),
            ))
        } else {
            Ok(idx)
        }
    } else {
        Err(err_at(
            path,
            line,
            format!("face: {what} index 0 (OBJ indices start at 1)"),
        ))
    }
}

fn checked_index(
    path: &Path,
    line: usize,
    idx: i64,
    len: usize,
    what: &str,
    keyword: &str,
) -> Result<u32, PluginError> {
    if idx < 0 || idx as u64 >= len as u64 || idx > u32::MAX as i64 {
        return Err(err_at(
            path,
            line,
            format!(
                "face refers to {what} {} but the file has {len} `{keyword}` line(s)",
                idx + 1
            ),
        ));
    }
    Ok(idx as u32)
}

/// Face corners naming a texture coordinate or normal past the file's last (exporters that
/// write `f 1/1/1` with no `vt` lines): Blender's importer drops such an index and keeps
/// the face, and so does this one, with one note for the file.
struct MissingEntries {
    what: &'static str,
    keyword: &'static str,
    len: usize,
    /// The first such corner's line and index (0-based), and how many there are.
    first: Option<(usize, i64)>,
    count: usize,
}

impl MissingEntries {
    fn new(what: &'static str, keyword: &'static str, len: usize) -> Self {
        MissingEntries {
            what,
            keyword,
            len,
            first: None,
            count: 0,
        }
    }

    /// `idx` as an index into the entries, or `None` (counted) when the file has no such entry.
    fn check(&mut self, line: usize, idx: i64) -> Option<u32> {
        if idx >= 0 && (idx as u64) < self.len as u64 && idx <= u32::MAX as i64 {
            return Some(idx as u32);
        }
        self.first.get_or_insert((line, idx));
        self.count += 1;
        None
    }

    /// The note naming the first such corner, if there was one; `fate` says what the
    /// corners get instead.
    fn note(&self, path: &Path, fate: &str) -> Option<String> {
        let (line, idx) = self.first?;
        Some(format!(
            "{}: line {line}: a face refers to {} {} but the file has {} `{}` line(s); \
             {} face corner(s) like it {fate}, as in Blender's importer",
            path.display(),
            self.what,
            idx + 1,
            self.len,
            self.keyword,
            self.count,
        ))
    }
}

/// A face corner before range checks (indices may point forward).
struct RawCorner {
    v: i64,
    vt: Option<i64>,
    vn: Option<i64>,
}

impl ObjDocument {
    /// Parse OBJ text. Unknown keywords (`s`, `curv`, `vp`, …) are skipped; every malformed
    /// statement is an error naming its line, but for a face corner's `vt` or `vn` index past
    /// the file's last, which is dropped with a note ([`ObjDocument::notes`]).
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<ObjDocument, PluginError> {
        // A UTF-8 byte-order mark (Windows editors write one) is not part of the first line:
        // kept, it hid the first `v` and shifted every index after it.
        let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        let text = String::from_utf8_lossy(bytes);
        let mut doc = ObjDocument::default();
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| "obj".into());
        doc.objects.push(ObjObject {
            name: stem,
            faces: Vec::new(),
            line_points: Vec::new(),
        });
        let mut material: Option<usize> = None;
        let mut material_ids: HashMap<String, usize> = HashMap::new();
        // Faces with unresolved indices: (object, face index in object, raw corners).
        let mut raw_faces: Vec<(usize, Vec<RawCorner>, Option<usize>, usize)> = Vec::new();
        // `l` elements: (object, vertex indices, line number).
        let mut raw_lines: Vec<(usize, Vec<i64>, usize)> = Vec::new();

        let mut lines = text.lines().enumerate().peekable();
        while let Some((i, first)) = lines.next() {
            let line_no = i + 1;
            // Backslash continues a statement on the next line.
            let mut statement = first.to_owned();
            while statement.trim_end().ends_with('\\') {
                let trimmed = statement.trim_end();
                statement = trimmed[..trimmed.len() - 1].to_owned();
                match lines.next() {
                    Some((_, next)) => {
                        statement.push(' ');
                        statement.push_str(next);
                    }
                    None => break,
                }
            }
            let content = match statement.find('#') {
                Some(p) => &statement[..p],
                None => statement.as_str(),
            };
            let content = content.trim();
            if content.is_empty() {
                continue;
            }
            let (keyword, rest) = match content.split_once(char::is_whitespace) {
                Some((k, r)) => (k, r.trim()),
                None => (content, ""),
            };
            let tokens: Vec<&str> = rest.split_whitespace().collect();
            match keyword {
                "v" => {
                    // x y z [w] or x y z r g b (vertex colours).
                    let p = parse_coords::<3>(path, line_no, &tokens, 3, 7, "vertex `v`")?;
                    doc.positions.push(p);
                }
                "vt" => {
                    let t =
                        parse_coords::<2>(path, line_no, &tokens, 1, 3, "texture coordinate `vt`")?;
                    doc.texcoords.push(t);
                }
                "vn" => {
                    let n = parse_coords::<3>(path, line_no, &tokens, 3, 3, "normal `vn`")?;
                    doc.normals.push(n);
                }
                "f" | "fo" => {
                    if tokens.len() < 3 {
                        return Err(err_at(
                            path,
                            line_no,
                            format!("face needs at least 3 corners, found {}", tokens.len()),
                        ));
                    }
                    let mut corners = Vec::with_capacity(tokens.len());
                    for token in &tokens {
                        let mut parts = token.split('/');
                        let v_tok = parts.next().unwrap_or("");
                        let vt_tok = parts.next().filter(|s| !s.is_empty());
                        let vn_tok = parts.next().filter(|s| !s.is_empty());
                        if parts.next().is_some() || v_tok.is_empty() {
                            return Err(err_at(
                                path,
                                line_no,
                                format!("face corner `{token}` is not v, v/vt, v//vn or v/vt/vn"),
                            ));
                        }
                        corners.push(RawCorner {
                            v: resolve_index(path, line_no, v_tok, doc.positions.len(), "vertex")?,
                            vt: vt_tok
                                .map(|t| {
                                    resolve_index(
                                        path,
                                        line_no,
                                        t,
                                        doc.texcoords.len(),
                                        "texture coordinate",
                                    )
                                })
                                .transpose()?,
                            vn: vn_tok
                                .map(|t| {
                                    resolve_index(path, line_no, t, doc.normals.len(), "normal")
                                })
                                .transpose()?,
                        });
                    }
                    raw_faces.push((doc.objects.len() - 1, corners, material, line_no));
                }
                "o" => {
                    let name = if rest.is_empty() {
                        format!("object{}", doc.objects.len())
                    } else {
                        rest.to_owned()
                    };
                    doc.objects.push(ObjObject {
                        name,
                        faces: Vec::new(),
                        line_points: Vec::new(),
                    });
                }
                "g" if !rest.is_empty() => doc.groups.push(rest.to_owned()),
                "usemtl" => {
                    if rest.is_empty() {
                        material = None;
                    } else {
                        let next = doc.materials.len();
                        let id = *material_ids.entry(rest.to_owned()).or_insert(next);
                        if id == next {
                            doc.materials.push(rest.to_owned());
                        }
                        material = Some(id);
                    }
                }
                "mtllib" if !rest.is_empty() => doc.mtllibs.push(rest.to_owned()),
                "l" => {
                    doc.skipped_lines_and_points += 1;
                    if tokens.len() < 2 {
                        return Err(err_at(
                            path,
                            line_no,
                            format!(
                                "line element needs at least 2 vertices, found {}",
                                tokens.len()
                            ),
                        ));
                    }
                    let points = tokens
                        .iter()
                        .map(|t| {
                            let v = t.split('/').next().unwrap_or("");
                            resolve_index(path, line_no, v, doc.positions.len(), "vertex")
                        })
                        .collect::<Result<Vec<_>, _>>()?;
                    raw_lines.push((doc.objects.len() - 1, points, line_no));
                }
                // Blender ignores `p` too ("OBJ element not recognized").
                "p" => doc.skipped_lines_and_points += 1,
                // s, vp, cstype, curv, surf, mg, usemap, lod, … carry nothing we simulate.
                _ => {}
            }
        }

        let mut missing_uvs = MissingEntries::new("texture coordinate", "vt", doc.texcoords.len());
        let mut missing_normals = MissingEntries::new("normal", "vn", doc.normals.len());
        for (object, raw, material, line) in raw_faces {
            let corners = raw
                .into_iter()
                .map(|c| {
                    Ok(Corner {
                        v: checked_index(path, line, c.v, doc.positions.len(), "vertex", "v")?,
                        vt: c.vt.and_then(|t| missing_uvs.check(line, t)),
                        vn: c.vn.and_then(|n| missing_normals.check(line, n)),
                    })
                })
                .collect::<Result<Vec<_>, PluginError>>()?;
            if let Some(obj) = doc.objects.get_mut(object) {
                obj.faces.push(Face {
                    corners,
                    material,
                    line,
                });
            }
        }

        doc.notes
            .extend(missing_uvs.note(path, "get no texture coordinates"));
        doc.notes
            .extend(missing_normals.note(path, "take normals computed from the surface"));

        for (object, raw, line) in raw_lines {
            let points = raw
                .into_iter()
                .map(|v| checked_index(path, line, v, doc.positions.len(), "vertex", "v"))
                .collect::<Result<Vec<_>, _>>()?;
            if let Some(obj) = doc.objects.get_mut(object) {
                obj.line_points.extend(points);
            }
        }

        if doc.positions.is_empty() {
            return Err(PluginError::invalid(
                path,
                "no geometry: the file has no `v` (vertex) lines",
            ));
        }
        if doc.objects.iter().all(|o| o.faces.is_empty()) {
            let what = if doc.skipped_lines_and_points > 0 {
                "only lines/points (`l`/`p`), which cannot be simulated"
            } else {
                "vertices but no `f` lines"
            };
            return Err(PluginError::invalid(
                path,
                format!("no faces: the file has {what}"),
            ));
        }
        Ok(doc)
    }

    /// One display mesh per object with faces (or one for everything with `merge_objects`).
    pub fn display_meshes(
        &self,
        path: &Path,
        settings: &ImportSettings,
    ) -> Result<Vec<DisplayMesh>, PluginError> {
        let objects: Vec<&ObjObject> = self
            .objects
            .iter()
            .filter(|o| !o.faces.is_empty())
            .collect();
        if settings.merge_objects {
            let name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "merged".into());
            let faces: Vec<&Face> = objects.iter().flat_map(|o| o.faces.iter()).collect();
            let loose: Vec<u32> = self
                .objects
                .iter()
                .flat_map(|o| o.line_points.iter().copied())
                .collect();
            Ok(vec![self.build_mesh(
                name,
                "object:0".into(),
                &faces,
                &loose,
            )])
        } else {
            Ok(objects
                .iter()
                .enumerate()
                .map(|(i, o)| {
                    let faces: Vec<&Face> = o.faces.iter().collect();
                    self.build_mesh(
                        o.name.clone(),
                        format!("object:{i}"),
                        &faces,
                        &o.line_points,
                    )
                })
                .collect())
        }
    }

    /// One display mesh from `faces`; `line_points` (the object's `l` vertices) join the point
    /// numbering as Blender's loose vertices do, and those no face uses become display
    /// vertices of the first primitive that no triangle refers to, so a point cache still has
    /// a position for every point Blender's object has.
    fn build_mesh(
        &self,
        name: String,
        source_key: String,
        faces: &[&Face],
        line_points: &[u32],
    ) -> DisplayMesh {
        // Points: the used `v` entries in file order (Blender's numbering).
        let mut used: Vec<u32> = faces
            .iter()
            .flat_map(|f| f.corners.iter().map(|c| c.v))
            .chain(line_points.iter().copied())
            .collect();
        used.sort_unstable();
        used.dedup();
        let local_of = |v: u32| used.binary_search(&v).unwrap_or(0) as u32;
        let point_positions: Vec<[f32; 3]> = used
            .iter()
            .map(|&v| {
                let p = self.positions[v as usize];
                [p[0] as f32, p[1] as f32, p[2] as f32]
            })
            .collect();

        // Triangulate every face once; compute smooth normals over points.
        let triangulated: Vec<Vec<[usize; 3]>> = faces
            .iter()
            .map(|f| {
                let pts: Vec<[f64; 3]> = f
                    .corners
                    .iter()
                    .map(|c| self.positions[c.v as usize])
                    .collect();
                triangulate(&pts)
            })
            .collect();
        let point_indices: Vec<u32> = faces
            .iter()
            .zip(&triangulated)
            .flat_map(|(f, tris)| {
                tris.iter()
                    .flat_map(move |t| t.iter().map(move |&k| local_of(f.corners[k].v)))
            })
            .collect();
        let point_normals = vertex_normals(&point_positions, &point_indices);

        // One primitive per material, in order of first use within this object.
        let mut order: Vec<Option<usize>> = Vec::new();
        for f in faces {
            if !order.contains(&f.material) {
                order.push(f.material);
            }
        }
        let mut primitives = Vec::with_capacity(order.len());
        let mut source_point_of_vertex = Vec::new();
        for material in order {
            let mut vertex_of: HashMap<Corner, u32> = HashMap::new();
            let mut corners: Vec<Corner> = Vec::new();
            let mut indices = Vec::new();
            for (f, tris) in faces.iter().zip(&triangulated) {
                if f.material != material {
                    continue;
                }
                for t in tris {
                    for &k in t {
                        let c = f.corners[k];
                        let next = corners.len() as u32;
                        let idx = *vertex_of.entry(c).or_insert(next);
                        if idx == next {
                            corners.push(c);
                        }
                        indices.push(idx);
                    }
                }
            }
            let positions: Vec<[f32; 3]> = corners
                .iter()
                .map(|c| point_positions[local_of(c.v) as usize])
                .collect();
            let normals: Vec<[f32; 3]> = corners
                .iter()
                .map(|c| {
                    let computed = point_normals[local_of(c.v) as usize];
                    match c.vn.map(|n| self.normals[n as usize]) {
                        Some(n) => {
                            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                            if len > 1e-12 {
                                [
                                    (n[0] / len) as f32,
                                    (n[1] / len) as f32,
                                    (n[2] / len) as f32,
                                ]
                            } else {
                                computed
                            }
                        }
                        None => computed,
                    }
                })
                .collect();
            let uvs = corners.iter().any(|c| c.vt.is_some()).then(|| {
                corners
                    .iter()
                    .map(|c| match c.vt {
                        Some(t) => {
                            let t = self.texcoords[t as usize];
                            [t[0] as f32, t[1] as f32]
                        }
                        None => [0.0, 0.0],
                    })
                    .collect()
            });
            source_point_of_vertex.extend(corners.iter().map(|c| local_of(c.v)));
            primitives.push(Primitive {
                positions,
                normals: Some(normals),
                uvs,
                indices,
                material: material.and_then(|m| self.materials.get(m).cloned()),
            });
        }

        // Loose points (only `l` elements use them): unreferenced vertices of the first
        // primitive. The solver's embedding carries them along with the nearest cell.
        let mut on_face = vec![false; used.len()];
        for f in faces {
            for c in &f.corners {
                on_face[local_of(c.v) as usize] = true;
            }
        }
        let loose: Vec<u32> = (0..used.len() as u32)
            .filter(|&q| !on_face[q as usize])
            .collect();
        if let Some(first) = primitives.first_mut() {
            let at = first.positions.len();
            for &q in &loose {
                first.positions.push(point_positions[q as usize]);
                if let Some(n) = first.normals.as_mut() {
                    n.push(point_normals[q as usize]);
                }
                if let Some(t) = first.uvs.as_mut() {
                    t.push([0.0, 0.0]);
                }
            }
            source_point_of_vertex.splice(at..at, loose.iter().copied());
        }

        DisplayMesh {
            name,
            source_key,
            world_from_local: nalgebra::Matrix4::identity(),
            primitives,
            source_point_of_vertex,
            source_point_count: used.len(),
        }
    }
}
