//! PC2 and MDD point caches: one file per simulated mesh, one point per *source* point (the
//! OBJ object's own vertex list as Blender numbers it, USD `points`, glTF vertices), written
//! through [`DisplayMesh::to_source_points`], in the mesh's local frame and source units (baked
//! frames already are). Blender's Mesh Cache modifier with its default axes plays them on the
//! OBJ Blender imported (see `exporters/tests/pointcache_blender.rs`), and on the glTF it
//! imported: Blender turns a glTF's data to Z-up, so glTF sources' points are written as
//! `(x, −z, y)` ([`PointCacheAxes::Blender`], the default; `[output] cache_axes = "source"`
//! keeps the file's Y-up axes for Y-up importers). A scene merged from several files
//! (`importer = "merged"`) tells each mesh's source by its `source_key` (glTF's `node:<i>`).
//!
//! # PC2 (little endian; layout read by Blender's `MOD_meshcache_pc2.cc`)
//! | offset | type | value |
//! |---|---|---|
//! | 0 | 12 bytes | `"POINTCACHE2\0"` |
//! | 12 | i32 | version, 1 |
//! | 16 | i32 | point count |
//! | 20 | f32 | start frame: 0.0 (our frame 0) |
//! | 24 | f32 | sample rate: 1.0 (one sample per frame) |
//! | 28 | i32 | sample count |
//! | 32 | f32 × 3 × points × samples | x, y, z per point, sample after sample |
//!
//! # MDD (big endian; layout read by Blender's `MOD_meshcache_mdd.cc`)
//! | offset | type | value |
//! |---|---|---|
//! | 0 | i32 | frame count |
//! | 4 | i32 | point count |
//! | 8 | f32 × frames | time of each frame in seconds (`i / fps`) |
//! | 8 + 4·frames | f32 × 3 × points × frames | x, y, z per point, frame after frame |
//!
//! There is no extra rest frame: Blender's reader seeks past the time table and indexes frame
//! `i` at `i × points × 12` bytes after it (the old `io_shape_mdd` exporter wrote one; readers
//! that expect it would show our frame 0 as the rest pose).
//!
//! Blender's modifier in its default "Frame" time mode ignores the PC2 start/rate and the MDD
//! times: scene frame `f` shows sample `f - frame_start` (clamped to the first and last).
//!
//! Naming: `out.pc2` with one baked mesh is written as is; with several, each mesh goes to
//! `out_<mesh name>.pc2` (name reduced to `[A-Za-z0-9_-]`, made unique with the mesh index).
//! Source points no display vertex refers to (none, for OBJ) are written at the origin.

use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::{DisplayMesh, ImportedScene};
use springbake_core::plugin::{ExportSettings, Exporter, OutputFile, PluginError, PointCacheAxes};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// PC2 exporter (`.pc2`, little endian).
#[derive(Debug, Clone, Copy, Default)]
pub struct Pc2Exporter;

/// MDD exporter (`.mdd`, big endian).
#[derive(Debug, Clone, Copy, Default)]
pub struct MddExporter;

/// The 12-byte PC2 signature.
pub const PC2_MAGIC: &[u8; 12] = b"POINTCACHE2\0";

impl Exporter for Pc2Exporter {
    fn name(&self) -> &str {
        "pc2"
    }
    fn extensions(&self) -> &[&str] {
        &["pc2"]
    }
    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError> {
        export_each(scene, baked, settings, |frames, _| pc2_bytes(frames))
    }
}

impl Exporter for MddExporter {
    fn name(&self) -> &str {
        "mdd"
    }
    fn extensions(&self) -> &[&str] {
        &["mdd"]
    }
    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError> {
        if !(baked.fps.is_finite() && baked.fps > 0.0) {
            return Err(PluginError::invalid(
                &settings.path,
                format!(
                    "MDD needs a positive frame rate, the bake has {} fps",
                    baked.fps
                ),
            ));
        }
        export_each(scene, baked, settings, mdd_bytes)
    }
}

/// PC2 bytes for `samples` (each one point list of equal length).
pub fn pc2_bytes(samples: &[Vec<[f32; 3]>]) -> Vec<u8> {
    let points = samples.first().map_or(0, Vec::len);
    let mut out = Vec::with_capacity(32 + samples.len() * points * 12);
    out.extend_from_slice(PC2_MAGIC);
    out.extend_from_slice(&1i32.to_le_bytes());
    out.extend_from_slice(&(points as i32).to_le_bytes());
    out.extend_from_slice(&0.0f32.to_le_bytes());
    out.extend_from_slice(&1.0f32.to_le_bytes());
    out.extend_from_slice(&(samples.len() as i32).to_le_bytes());
    for p in samples.iter().flatten().flatten() {
        out.extend_from_slice(&p.to_le_bytes());
    }
    out
}

/// MDD bytes for `frames` at `fps` frames per second.
pub fn mdd_bytes(frames: &[Vec<[f32; 3]>], fps: f64) -> Vec<u8> {
    let points = frames.first().map_or(0, Vec::len);
    let mut out = Vec::with_capacity(8 + frames.len() * (4 + points * 12));
    out.extend_from_slice(&(frames.len() as i32).to_be_bytes());
    out.extend_from_slice(&(points as i32).to_be_bytes());
    for i in 0..frames.len() {
        out.extend_from_slice(&((i as f64 / fps) as f32).to_be_bytes());
    }
    for p in frames.iter().flatten().flatten() {
        out.extend_from_slice(&p.to_be_bytes());
    }
    out
}

/// Checks every baked mesh, reorders its frames into source points and hands them to `encode`.
fn export_each(
    scene: &ImportedScene,
    baked: &BakedScene,
    settings: &ExportSettings,
    encode: impl Fn(&[Vec<[f32; 3]>], f64) -> Vec<u8>,
) -> Result<Vec<OutputFile>, PluginError> {
    let out_path = &settings.path;
    if baked.meshes.is_empty() {
        return Err(PluginError::invalid(
            out_path,
            "the bake has no meshes to write",
        ));
    }
    let mut entries = Vec::with_capacity(baked.meshes.len());
    for (k, bm) in baked.meshes.iter().enumerate() {
        let mesh = scene.meshes.get(bm.mesh_index).ok_or_else(|| {
            PluginError::invalid(
                out_path,
                format!(
                    "baked mesh {k} refers to mesh {} but the scene has {}",
                    bm.mesh_index,
                    scene.meshes.len()
                ),
            )
            .at(format!("baked.meshes[{k}]"))
        })?;
        let mut frames = source_point_frames(mesh, bm, k, out_path)?;
        if settings.axes == PointCacheAxes::Blender && from_gltf(scene, mesh) {
            // Blender's glTF importer turns the data Y-up → Z-up: (x, y, z) → (x, −z, y).
            for p in frames.iter_mut().flatten() {
                *p = [p[0], -p[2], p[1]];
            }
        }
        entries.push((mesh, frames));
    }
    let names = file_names(out_path, entries.iter().map(|(m, _)| *m).collect());
    Ok(entries
        .into_iter()
        .zip(names)
        .map(|((_, frames), path)| OutputFile {
            bytes: encode(&frames, baked.fps),
            path,
        })
        .collect())
}

/// Every frame of `bm` as positions of the mesh's source points.
fn source_point_frames(
    mesh: &DisplayMesh,
    bm: &BakedMesh,
    k: usize,
    out_path: &Path,
) -> Result<Vec<Vec<[f32; 3]>>, PluginError> {
    let where_ = |f: usize| format!("baked.meshes[{k}].frames[{f}]");
    if bm.frames.is_empty() {
        return Err(PluginError::invalid(
            out_path,
            format!(
                "mesh '{}' has no baked frames; a point cache needs at least one",
                mesh.name
            ),
        )
        .at(format!("baked.meshes[{k}]")));
    }
    if i32::try_from(bm.frames.len()).is_err() || i32::try_from(mesh.source_point_count).is_err() {
        return Err(PluginError::invalid(
            out_path,
            "too many frames or points for a 32-bit header",
        )
        .at(format!("baked.meshes[{k}]")));
    }
    let vertices = mesh.vertex_count();
    bm.frames
        .iter()
        .enumerate()
        .map(|(f, frame)| {
            if frame.len() != vertices {
                return Err(PluginError::invalid(
                    out_path,
                    format!(
                        "frame has {} vertices but mesh '{}' has {vertices}",
                        frame.len(),
                        mesh.name
                    ),
                )
                .at(where_(f)));
            }
            if let Some(v) = frame.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
                return Err(PluginError::invalid(
                    out_path,
                    format!(
                        "vertex {v} of mesh '{}' is not finite: {:?}",
                        mesh.name, frame[v]
                    ),
                )
                .at(where_(f)));
            }
            Ok(mesh.to_source_points(frame, [0.0; 3]))
        })
        .collect()
}

/// `out.ext` for one mesh, `out_<name>.ext` for several (sanitized and unique).
fn file_names(out: &Path, meshes: Vec<&DisplayMesh>) -> Vec<PathBuf> {
    if meshes.len() == 1 {
        return vec![out.to_path_buf()];
    }
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bake".into());
    let ext = out
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    let mut taken = HashSet::new();
    meshes
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let mut name: String = m
                .name
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            if name.is_empty() {
                name = format!("mesh{i}");
            }
            let base = name.clone();
            let mut n = i;
            while !taken.insert(name.to_ascii_lowercase()) {
                name = format!("{base}_{n}");
                n += 1;
            }
            out.with_file_name(format!("{stem}_{name}{ext}"))
        })
        .collect()
}

/// Whether `mesh` came from a glTF file: the scene's importer, or in a scene merged from
/// several files the mesh's own key (`node:<index>`, see [`DisplayMesh::source_key`]).
fn from_gltf(scene: &ImportedScene, mesh: &DisplayMesh) -> bool {
    match scene.source.importer.as_str() {
        "gltf" => true,
        "merged" => mesh.source_key.starts_with("node:"),
        _ => false,
    }
}
