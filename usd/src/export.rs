//! The USD exporter: baked frames as `points` time samples.
//!
//! Time mapping: frame `i` (0-based) is written at time code `i`, with `timeCodesPerSecond` =
//! `framesPerSecond` = the bake's fps, `startTimeCode` 0 and `endTimeCode` = frames − 1, so time
//! code / timeCodesPerSecond equals [`BakedScene::frame_time`].
//!
//! * USD source (`scene.source.importer == "usd"`): the source stage is flattened into the
//!   output (everything it had, composed into one layer); on each baked mesh prim `points` and
//!   `extent` get one time sample per frame in the source's point order. Authored normals are
//!   kept consistent: `vertex`/`varying` normals become per-frame smooth normals of the
//!   deformed points; `faceVarying`, `uniform` and `constant` normals become per-frame
//!   `faceVarying` normals that keep the rest normals' smoothing groups (hard edges stay hard).
//!   A `primvars:normals` primvar is removed and replaced by the `normals` attribute.
//! * Other sources: a new stage with `/root/<mesh>` Xforms carrying `world_from_local` and a
//!   `mesh` child with triangles, time-sampled points, normals (vertex interpolation, when the
//!   source had normals) and `st` (when every primitive had uvs).

use crate::import::read_stage;
use crate::mesh::{extent, face_varying_normals, point_normals, Interpolation, RawMesh};
use crate::particles::particles_spec;
use crate::python::{f32_bytes, i32_bytes, plugin_error, through_temp_file, with_bridge};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::{
    vertex_normals, DisplayMesh, ImportedScene, SurfaceMaterial, TextureImage, UpAxis,
};
use springbake_core::plugin::{ExportSettings, Exporter, IoErrorKind, OutputFile, PluginError};
use std::collections::HashSet;
use std::path::Path;

/// Per mesh, everything the bridge's `_author_frames` needs, as flat little-endian arrays.
struct Frames {
    point_count: usize,
    points: Vec<u8>,
    extents: Vec<u8>,
    normals: Option<(Vec<u8>, usize, &'static str)>,
}

fn check_frames(
    baked: &BakedMesh,
    mesh: &DisplayMesh,
    frame_count: usize,
    out: &Path,
) -> Result<(), PluginError> {
    let n = mesh.vertex_count();
    if baked.frames.len() != frame_count {
        return Err(PluginError::invalid(
            out,
            format!(
                "bake has {} frames for mesh {:?}, the scene says {frame_count}",
                baked.frames.len(),
                mesh.name
            ),
        ));
    }
    if let Some((f, frame)) = baked
        .frames
        .iter()
        .enumerate()
        .find(|(_, fr)| fr.len() != n)
    {
        return Err(PluginError::invalid(
            out,
            format!(
                "frame {f} of mesh {:?} has {} vertices, the mesh has {n}",
                mesh.name,
                frame.len()
            ),
        ));
    }
    if let Some(f) = baked
        .frames
        .iter()
        .position(|fr| fr.iter().any(|p| !p.iter().all(|c| c.is_finite())))
    {
        return Err(PluginError::invalid(
            out,
            format!("frame {f} of mesh {:?} has non-finite positions", mesh.name),
        ));
    }
    Ok(())
}

/// Each baked mesh with its display mesh, after checking the frame rate and every frame's
/// vertex count and finiteness.
pub(crate) fn checked_meshes<'a>(
    scene: &'a ImportedScene,
    baked: &'a BakedScene,
    out: &Path,
) -> Result<Vec<(&'a BakedMesh, &'a DisplayMesh)>, PluginError> {
    if !(baked.fps.is_finite() && baked.fps > 0.0) {
        return Err(PluginError::invalid(
            out,
            format!("fps {} is not positive", baked.fps),
        ));
    }
    let mut items = Vec::new();
    for bm in &baked.meshes {
        let mesh = scene.meshes.get(bm.mesh_index).ok_or_else(|| {
            PluginError::invalid(
                out,
                format!(
                    "baked mesh refers to mesh {} but the scene has {}",
                    bm.mesh_index,
                    scene.meshes.len()
                ),
            )
        })?;
        check_frames(bm, mesh, baked.frame_count, out)?;
        items.push((bm, mesh));
    }
    Ok(items)
}

/// Frames of a mesh that came from a USD stage, in the stage's point order.
fn source_frames(
    baked: &BakedMesh,
    mesh: &DisplayMesh,
    raw: &RawMesh,
    out: &Path,
) -> Result<Frames, PluginError> {
    let n = raw.points.len();
    if mesh.source_point_count != n
        || (mesh.source_point_of_vertex.is_empty() && mesh.vertex_count() != n)
    {
        return Err(PluginError::invalid(
            out,
            format!(
                "the source mesh has {n} points but was imported with {}; was the source file \
                 changed since the import?",
                mesh.source_point_count
            ),
        )
        .at(raw.path.clone()));
    }
    let rest: Vec<[f32; 3]> = raw.points.iter().map(|p| p.map(|c| c as f32)).collect();
    let rest_fv: Option<Vec<[f32; 3]>> = raw.normals.as_ref().map(|nv| {
        let mut fv = 0usize;
        let mut out = Vec::with_capacity(raw.indices.len());
        for (face, &c) in raw.counts.iter().enumerate() {
            for _ in 0..c {
                let point = raw.indices[fv] as usize;
                let e = 3 * match nv.interpolation {
                    Interpolation::Constant => 0,
                    Interpolation::Uniform => face,
                    Interpolation::Vertex => point,
                    Interpolation::FaceVarying => fv,
                };
                out.push([
                    nv.values[e] as f32,
                    nv.values[e + 1] as f32,
                    nv.values[e + 2] as f32,
                ]);
                fv += 1;
            }
        }
        out
    });
    let vertex_normals_wanted = raw
        .normals
        .as_ref()
        .is_some_and(|nv| nv.interpolation == Interpolation::Vertex);
    let mut points = Vec::with_capacity(baked.frames.len() * n * 12);
    let mut extents = Vec::new();
    let mut normals_bytes = Vec::new();
    for frame in &baked.frames {
        let mut pts = rest.clone();
        if mesh.source_point_of_vertex.is_empty() {
            pts.copy_from_slice(frame);
        } else {
            for (v, &p) in mesh.source_point_of_vertex.iter().enumerate() {
                if let (Some(slot), Some(&q)) = (pts.get_mut(p as usize), frame.get(v)) {
                    *slot = q;
                }
            }
        }
        points.extend(f32_bytes(pts.iter().flatten().copied()));
        extents.extend(f32_bytes(extent(&pts)));
        if let Some(rest_fv) = &rest_fv {
            let normals = if vertex_normals_wanted {
                point_normals(&pts, &raw.counts, &raw.indices)
            } else {
                face_varying_normals(&pts, &raw.counts, &raw.indices, rest_fv)
            };
            normals_bytes.extend(f32_bytes(normals.iter().flatten().copied()));
        }
    }
    let normals = rest_fv.map(|_| {
        if vertex_normals_wanted {
            (normals_bytes, n, "vertex")
        } else {
            (normals_bytes, raw.indices.len(), "faceVarying")
        }
    });
    Ok(Frames {
        point_count: n,
        points,
        extents,
        normals,
    })
}

fn frames_dict<'py>(py: Python<'py>, f: &Frames) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("point_count", f.point_count)?;
    d.set_item("points", PyBytes::new(py, &f.points))?;
    d.set_item("extents", PyBytes::new(py, &f.extents))?;
    match &f.normals {
        Some((bytes, count, interpolation)) => {
            d.set_item("normals", PyBytes::new(py, bytes))?;
            d.set_item("normal_count", *count)?;
            d.set_item("normals_interpolation", *interpolation)?;
        }
        None => d.set_item("normals", py.None())?,
    }
    Ok(d)
}

/// The materials the exported meshes name, with their looks (the source's description, else
/// the grey a name alone gets), each with a unique prim name.
fn material_looks(
    scene: &ImportedScene,
    items: &[(&BakedMesh, &DisplayMesh)],
) -> Vec<(String, SurfaceMaterial)> {
    let mut taken = HashSet::new();
    let mut out: Vec<(String, SurfaceMaterial)> = Vec::new();
    for (_, mesh) in items {
        for name in mesh.primitives.iter().filter_map(|p| p.material.as_ref()) {
            if out.iter().any(|(_, m)| &m.name == name) {
                continue;
            }
            let look = scene
                .materials
                .iter()
                .find(|m| &m.name == name)
                .cloned()
                .unwrap_or_else(|| SurfaceMaterial {
                    name: name.clone(),
                    ..SurfaceMaterial::default()
                });
            out.push((prim_name(name, &mut taken), look));
        }
    }
    out
}

/// What a texture image is to its material's UsdPreviewSurface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TextureRole {
    BaseColour,
    Normal,
    Opacity,
}

impl TextureRole {
    /// The bridge's material key for this role's asset path.
    fn key(self) -> &'static str {
        match self {
            TextureRole::BaseColour => "texture",
            TextureRole::Normal => "normal_texture",
            TextureRole::Opacity => "opacity_texture",
        }
    }
}

/// A texture a stage refers to: its material, role, path relative to the output, image.
type TextureFile<'a> = (String, TextureRole, String, &'a TextureImage);

/// The base-colour, normal and opacity images of the scene's materials, each at
/// `<output stem>_textures/<image file name>`, names made unique.
fn texture_files<'a>(scene: &'a ImportedScene, out: &Path) -> Vec<TextureFile<'a>> {
    let stem = out
        .file_stem()
        .map_or_else(|| "baked".to_owned(), |s| s.to_string_lossy().into_owned());
    let mut taken = HashSet::new();
    scene
        .materials
        .iter()
        .flat_map(|m| {
            [
                (TextureRole::BaseColour, &m.base_colour_texture),
                (TextureRole::Normal, &m.normal_texture),
                (TextureRole::Opacity, &m.opacity_texture),
            ]
            .into_iter()
            .filter_map(move |(role, t)| t.as_ref().map(|t| (&m.name, role, t)))
        })
        .map(|(material, role, image)| {
            let file = Path::new(&image.name).file_name().map_or_else(
                || "texture".to_owned(),
                |f| f.to_string_lossy().into_owned(),
            );
            let (base, ext) = match file.rsplit_once('.') {
                Some((b, e)) => (b.to_owned(), format!(".{e}")),
                None => (file.clone(), String::new()),
            };
            let clean: String = base
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '-' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            let mut name = format!("{clean}{ext}");
            let mut k = 1;
            while !taken.insert(name.clone()) {
                name = format!("{clean}_{k}{ext}");
                k += 1;
            }
            (
                material.clone(),
                role,
                format!("{stem}_textures/{name}"),
                image,
            )
        })
        .collect()
}

/// `(material name, first face, face count)` of each primitive that names a material, faces
/// counted over the mesh's triangles (primitive after primitive, as written).
fn material_faces(mesh: &DisplayMesh) -> Vec<(String, usize, usize)> {
    let mut start = 0;
    let mut out = Vec::new();
    for p in &mesh.primitives {
        let count = p.triangle_count();
        if let Some(name) = &p.material {
            out.push((name.clone(), start, count));
        }
        start += count;
    }
    out
}

/// A prim name from a mesh name: letters, digits and `_`, not starting with a digit, unique.
pub fn prim_name(name: &str, taken: &mut HashSet<String>) -> String {
    let mut base: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if base.is_empty() || base.starts_with(|c: char| c.is_ascii_digit()) {
        base.insert_str(0, "mesh_");
    }
    let mut candidate = base.clone();
    let mut k = 1;
    while !taken.insert(candidate.clone()) {
        candidate = format!("{base}_{k}");
        k += 1;
    }
    candidate
}

/// Frames of a mesh from a non-USD source, in display-vertex order.
fn display_frames(baked: &BakedMesh, mesh: &DisplayMesh) -> Frames {
    let triangles: Vec<u32> = mesh.triangles().into_iter().flatten().collect();
    let had_normals = mesh.primitives.iter().any(|p| p.normals.is_some());
    let n = mesh.vertex_count();
    let mut points = Vec::new();
    let mut extents = Vec::new();
    let mut normals = Vec::new();
    for frame in &baked.frames {
        points.extend(f32_bytes(frame.iter().flatten().copied()));
        extents.extend(f32_bytes(extent(frame)));
        if had_normals {
            normals.extend(f32_bytes(
                vertex_normals(frame, &triangles).into_iter().flatten(),
            ));
        }
    }
    Frames {
        point_count: n,
        points,
        extents,
        normals: had_normals.then_some((normals, n, "vertex")),
    }
}

fn up_axis_token(up: UpAxis) -> &'static str {
    match up {
        UpAxis::Y => "Y",
        UpAxis::Z => "Z",
    }
}

fn output_extension(path: &Path) -> Result<&'static str, PluginError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("usda") => Ok("usda"),
        Some("usdc") => Ok("usdc"),
        Some("usd") => Ok("usd"),
        Some("usdz") => Ok("usdz"),
        _ => Err(PluginError::invalid(
            path,
            "USD export writes .usda, .usdc, .usd or .usdz",
        )),
    }
}

/// Writes baked frames as USD `points` time samples.
#[derive(Debug, Default, Clone, Copy)]
pub struct UsdExporter;

impl UsdExporter {
    fn write(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        out: &Path,
        temp: &Path,
    ) -> Result<(), PluginError> {
        let items = checked_meshes(scene, baked, out)?;
        if scene.source.importer == "usd" {
            let source = &scene.source.path;
            let own_folder = source.parent().unwrap_or(Path::new("")).to_path_buf();
            let root = scene.source.read_root.clone().unwrap_or(own_folder);
            // Every mesh, hidden ones too: the baked ones are found by path below.
            let stage = read_stage(source, &root, true)?;
            let mut prepared = Vec::new();
            for (bm, mesh) in &items {
                let raw = stage
                    .meshes
                    .iter()
                    .find(|m| m.path == mesh.source_key)
                    .ok_or_else(|| {
                        PluginError::invalid(source, "the source stage has no mesh at this path")
                            .at(mesh.source_key.clone())
                    })?;
                let frames = source_frames(bm, mesh, raw, out)?;
                let drop_primvar = raw.normals_source.as_deref() == Some("primvars:normals");
                prepared.push((raw.path.clone(), frames, drop_primvar));
            }
            with_bridge(out, |py, bridge| {
                let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Io, out);
                let spec = PyDict::new(py);
                let list = PyList::empty(py);
                for (prim_path, frames, drop_primvar) in &prepared {
                    let d = frames_dict(py, frames).map_err(to_err)?;
                    d.set_item("prim_path", prim_path).map_err(to_err)?;
                    d.set_item("drop_primvar_normals", *drop_primvar)
                        .map_err(to_err)?;
                    list.append(d).map_err(to_err)?;
                }
                spec.set_item("meshes", list).map_err(to_err)?;
                // The folder the output will be in (it is written to a temporary file first).
                let folder =
                    std::path::absolute(out.parent().unwrap_or(Path::new("."))).unwrap_or_default();
                spec.set_item("output_folder", folder.to_string_lossy().into_owned())
                    .map_err(to_err)?;
                spec.set_item("fps", baked.fps).map_err(to_err)?;
                spec.set_item("frame_count", baked.frame_count)
                    .map_err(to_err)?;
                spec.set_item("up_axis", up_axis_token(scene.up_axis))
                    .map_err(to_err)?;
                spec.set_item("meters_per_unit", scene.meters_per_unit)
                    .map_err(to_err)?;
                let particles = particles_spec(py, scene, baked).map_err(to_err)?;
                spec.set_item("particles", particles).map_err(to_err)?;
                bridge
                    .call_method1(
                        "write_source_stage",
                        (
                            source.to_string_lossy().into_owned(),
                            temp.to_string_lossy().into_owned(),
                            spec,
                        ),
                    )
                    .map_err(to_err)?;
                Ok(())
            })
        } else {
            let mut taken = HashSet::new();
            let looks = material_looks(scene, &items);
            let textures = texture_files(scene, out);
            let usdz = output_extension(out)? == "usdz";
            with_bridge(out, |py, bridge| {
                let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Io, out);
                let list = PyList::empty(py);
                for (bm, mesh) in &items {
                    let frames = display_frames(bm, mesh);
                    let d = frames_dict(py, &frames).map_err(to_err)?;
                    let subsets = PyList::empty(py);
                    for (name, start, count) in material_faces(mesh) {
                        subsets.append((name, start, count)).map_err(to_err)?;
                    }
                    d.set_item("material_faces", subsets).map_err(to_err)?;
                    d.set_item("name", prim_name(&mesh.name, &mut taken))
                        .map_err(to_err)?;
                    // nalgebra stores column-major: M's columns are Gf's rows (Mᵀ row-major).
                    let world: Vec<u8> = mesh
                        .world_from_local
                        .as_slice()
                        .iter()
                        .flat_map(|v| v.to_le_bytes())
                        .collect();
                    d.set_item("world", PyBytes::new(py, &world))
                        .map_err(to_err)?;
                    let tris = mesh.triangles();
                    d.set_item(
                        "counts",
                        PyBytes::new(py, &i32_bytes(tris.iter().map(|_| 3))),
                    )
                    .map_err(to_err)?;
                    d.set_item(
                        "indices",
                        PyBytes::new(py, &i32_bytes(tris.iter().flatten().map(|&i| i as i32))),
                    )
                    .map_err(to_err)?;
                    let rest = mesh.primitives.iter().flat_map(|p| p.positions.iter());
                    d.set_item(
                        "rest_points",
                        PyBytes::new(py, &f32_bytes(rest.flatten().copied())),
                    )
                    .map_err(to_err)?;
                    if mesh.primitives.iter().all(|p| p.uvs.is_some()) {
                        let uvs = mesh
                            .primitives
                            .iter()
                            .flat_map(|p| p.uvs.iter().flatten().flat_map(|t| t.iter().copied()));
                        d.set_item("uvs", PyBytes::new(py, &f32_bytes(uvs)))
                            .map_err(to_err)?;
                    } else {
                        d.set_item("uvs", py.None()).map_err(to_err)?;
                    }
                    list.append(d).map_err(to_err)?;
                }
                let materials = PyList::empty(py);
                for (prim, look) in &looks {
                    let m = PyDict::new(py);
                    m.set_item("name", &look.name).map_err(to_err)?;
                    m.set_item("prim", prim).map_err(to_err)?;
                    m.set_item("base_colour", look.base_colour.to_vec())
                        .map_err(to_err)?;
                    m.set_item("roughness", look.roughness).map_err(to_err)?;
                    for (material, role, rel, _) in &textures {
                        if material == &look.name {
                            m.set_item(role.key(), format!("./{rel}")).map_err(to_err)?;
                        }
                    }
                    materials.append(m).map_err(to_err)?;
                }
                let spec = PyDict::new(py);
                spec.set_item("meshes", list).map_err(to_err)?;
                spec.set_item("materials", materials).map_err(to_err)?;
                if usdz {
                    // A package holds its images: the bridge packs them with the layer.
                    let files = PyList::empty(py);
                    for (_, _, rel, image) in &textures {
                        files
                            .append((rel, PyBytes::new(py, &image.bytes)))
                            .map_err(to_err)?;
                    }
                    spec.set_item("texture_files", files).map_err(to_err)?;
                }
                spec.set_item("fps", baked.fps).map_err(to_err)?;
                spec.set_item("frame_count", baked.frame_count)
                    .map_err(to_err)?;
                spec.set_item("up_axis", up_axis_token(scene.up_axis))
                    .map_err(to_err)?;
                spec.set_item("meters_per_unit", scene.meters_per_unit)
                    .map_err(to_err)?;
                let particles = particles_spec(py, scene, baked).map_err(to_err)?;
                spec.set_item("particles", particles).map_err(to_err)?;
                bridge
                    .call_method1(
                        "write_new_stage",
                        (temp.to_string_lossy().into_owned(), spec),
                    )
                    .map_err(to_err)?;
                Ok(())
            })
        }
    }
}

impl Exporter for UsdExporter {
    fn name(&self) -> &str {
        "usd"
    }

    fn extensions(&self) -> &[&str] {
        &["usda", "usdc", "usd", "usdz"]
    }

    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError> {
        let out = settings.path.as_path();
        let ext = output_extension(out)?;
        let bytes = through_temp_file(out, &format!("baked.{ext}"), "usd-core", |temp| {
            self.write(scene, baked, out, temp)
        })?;
        let mut files = vec![OutputFile {
            path: out.to_path_buf(),
            bytes,
        }];
        // Texture images beside a new stage, where its materials' asset paths point.
        if scene.source.importer != "usd" && ext != "usdz" {
            let folder = out.parent().unwrap_or(Path::new(""));
            for (_, _, rel, image) in texture_files(scene, out) {
                files.push(OutputFile {
                    path: folder.join(rel),
                    bytes: image.bytes.clone(),
                });
            }
        }
        Ok(files)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prim_names_are_valid_and_unique() {
        let mut taken = HashSet::new();
        assert_eq!(prim_name("Suzanne.001", &mut taken), "Suzanne_001");
        assert_eq!(prim_name("Suzanne.001", &mut taken), "Suzanne_001_1");
        assert_eq!(prim_name("3d", &mut taken), "mesh_3d");
        assert_eq!(prim_name("", &mut taken), "mesh_");
    }

    #[test]
    fn output_extension_picks_the_format() {
        assert_eq!(output_extension(Path::new("a.USDA")).unwrap(), "usda");
        assert_eq!(output_extension(Path::new("a.usdc")).unwrap(), "usdc");
        assert_eq!(output_extension(Path::new("a.usdz")).unwrap(), "usdz");
        assert!(output_extension(Path::new("a.usdx")).is_err());
    }
}
