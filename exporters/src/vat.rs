//! Vertex animation textures (`out.vat` → a folder `out.vat/`): how game engines play a baked
//! soft body, in the SideFX Labs VAT 3.0 **soft-body** layout, so its published shaders (Unreal,
//! Unity) and the ports built on them play it.
//!
//! ```text
//! out.vat/geo/out_mesh.glb     the rest pose (first frame): every baked mesh merged, Y-up metres,
//!                              TEXCOORD_0 the source's UVs, TEXCOORD_1 the texel lookup
//! out.vat/tex/out_pos.exr      RGB offset of each vertex from its rest position, m (float32)
//! out.vat/tex/out_rot.exr      RGBA quaternion (x, y, z, w) taking +Y to the vertex normal
//!                              (float16)
//! out.vat/tex/out_pos.png      8-bit offsets, normalised by the bounds in the JSON ...
//! out.vat/tex/out_pos2.png     ... and what the first one missed, times 100 (Labs "two
//!                              position textures"; decode `t = pos + pos2 · 0.01`)
//! out.vat/tex/out_rot.png      8-bit quaternion, `(q + 1) / 2`
//! out.vat/data/out_data.json   Labs keys (bounds, fps) and springbake's (frames, size, files)
//! ```
//!
//! Layout ([`Layout`]): one texel per vertex per frame. A frame is `rows_per_frame =
//! ceil(vertices / width)` rows (width 1024, doubled while the texture would be taller than
//! 16 384); frame `f` occupies rows `f · rows_per_frame ..` counted from the **top** of the
//! image, vertex `i` row `i / width`, column `i mod width`. TEXCOORD_1 is the centre of the
//! vertex's frame-0 texel in glTF's convention (`v` from the top): a player samples
//! `uv1 + (0, f / frames)`. In Labs' own (FBX, `v` from the bottom) convention that is their
//! `uv2 = ((0.5 + col) / width, 1 − (row + 0.5) / (rows_per_frame · frames))`.
//!
//! Bounds: Labs hides flags in the bounds' fractional digits; springbake writes the true
//! bounds of the offsets (what the PNGs are normalised by) and states the mode in its own keys.
//! Axes: right-handed Y-up metres (Labs' "custom" axis preset, scale 1); engines convert on
//! import as they do for glTF.

mod textures;

use nalgebra::Point3;
use serde_json::json;
use springbake_core::bake::BakedScene;
use springbake_core::display::{vertex_normals, ImportedScene};
use springbake_core::plugin::{ExportSettings, Exporter, OutputFile, PluginError};
use std::path::Path;
use textures::{exr_bytes, png_bytes, Depth, Rgba};
pub use textures::{join_ldr, normal_rotation, split_ldr};

/// Texture width before it grows for long bakes (Labs' default target size).
pub const DEFAULT_WIDTH: usize = 1024;
/// Largest texture side written (what current GPUs sample).
pub const MAX_SIDE: usize = 16_384;

/// Where each vertex's texels are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    pub vertex_count: usize,
    pub frame_count: usize,
    pub width: usize,
    pub rows_per_frame: usize,
}

impl Layout {
    /// The layout of `vertex_count` vertices over `frame_count` frames, or why none fits.
    pub fn new(vertex_count: usize, frame_count: usize) -> Result<Layout, String> {
        if vertex_count == 0 || frame_count == 0 {
            return Err("nothing to write: no vertices or no frames".into());
        }
        let mut width = vertex_count.min(DEFAULT_WIDTH);
        while frame_count * vertex_count.div_ceil(width) > MAX_SIDE && width < MAX_SIDE {
            width = (width * 2).min(MAX_SIDE).min(vertex_count);
        }
        let layout = Layout {
            vertex_count,
            frame_count,
            width,
            rows_per_frame: vertex_count.div_ceil(width),
        };
        if layout.height() > MAX_SIDE {
            return Err(format!(
                "{vertex_count} vertices × {frame_count} frames need a texture taller than \
                 {MAX_SIDE} texels; bake fewer frames or split the mesh"
            ));
        }
        Ok(layout)
    }

    pub fn height(&self) -> usize {
        self.frame_count * self.rows_per_frame
    }

    /// Texel index (row-major from the top) of `vertex` at `frame`.
    pub fn texel(&self, vertex: usize, frame: usize) -> usize {
        let row = frame * self.rows_per_frame + vertex / self.width;
        row * self.width + vertex % self.width
    }

    /// TEXCOORD_1 of `vertex`: the centre of its frame-0 texel, `v` from the top.
    pub fn lookup_uv(&self, vertex: usize) -> [f32; 2] {
        [
            ((vertex % self.width) as f64 + 0.5) as f32 / self.width as f32,
            ((vertex / self.width) as f64 + 0.5) as f32 / self.height() as f32,
        ]
    }
}

/// Every baked mesh merged, in Y-up metres.
struct Merged {
    /// Per frame, per vertex.
    positions: Vec<Vec<[f32; 3]>>,
    normals: Vec<Vec<[f32; 3]>>,
    triangles: Vec<u32>,
    uvs: Option<Vec<[f32; 2]>>,
}

fn merge(scene: &ImportedScene, baked: &BakedScene, out: &Path) -> Result<Merged, PluginError> {
    let to_y_up = scene.y_up_metres_from_world();
    let mut merged = Merged {
        positions: vec![Vec::new(); baked.frame_count],
        normals: vec![Vec::new(); baked.frame_count],
        triangles: Vec::new(),
        uvs: Some(Vec::new()),
    };
    for bm in &baked.meshes {
        let mesh = scene.meshes.get(bm.mesh_index).ok_or_else(|| {
            PluginError::invalid(
                out,
                format!("baked mesh {} is not in the scene", bm.mesh_index),
            )
        })?;
        if bm.frames.len() != baked.frame_count
            || bm.frames.iter().any(|f| f.len() != mesh.vertex_count())
        {
            return Err(PluginError::invalid(
                out,
                format!(
                    "the frames of mesh {:?} do not match its vertices",
                    mesh.name
                ),
            ));
        }
        let base = merged.positions[0].len() as u32;
        let local: Vec<u32> = mesh.triangles().into_iter().flatten().collect();
        let m = to_y_up * mesh.world_from_local;
        for (f, frame) in bm.frames.iter().enumerate() {
            let world: Vec<[f32; 3]> = frame
                .iter()
                .map(|p| {
                    let q = m.transform_point(&Point3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                    [q.x as f32, q.y as f32, q.z as f32]
                })
                .collect();
            if world.iter().flatten().any(|c| !c.is_finite()) {
                return Err(PluginError::invalid(
                    out,
                    format!("frame {f} of mesh {:?} has non-finite positions", mesh.name),
                ));
            }
            merged.normals[f].extend(vertex_normals(&world, &local));
            merged.positions[f].extend(world);
        }
        merged.triangles.extend(local.iter().map(|&i| i + base));
        merged.uvs = match (
            merged.uvs.take(),
            mesh.primitives.iter().all(|p| p.uvs.is_some()),
        ) {
            (Some(mut uvs), true) => {
                uvs.extend(mesh.primitives.iter().flat_map(|p| p.uvs.iter().flatten()));
                Some(uvs)
            }
            _ => None,
        };
    }
    Ok(merged)
}

/// Bounds of every offset from the rest pose, per axis (for the 8-bit textures).
fn offset_bounds(merged: &Merged) -> ([f32; 3], [f32; 3]) {
    let rest = &merged.positions[0];
    let mut lo = [0.0f32; 3];
    let mut hi = [0.0f32; 3];
    for frame in &merged.positions {
        for (p, r) in frame.iter().zip(rest) {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c] - r[c]);
                hi[c] = hi[c].max(p[c] - r[c]);
            }
        }
    }
    (lo, hi)
}

fn rest_mesh(merged: &Merged, layout: &Layout, name: &str) -> Vec<u8> {
    let lookup: Vec<[f32; 2]> = (0..layout.vertex_count)
        .map(|v| layout.lookup_uv(v))
        .collect();
    crate::gltf::static_glb(&crate::gltf::StaticMesh {
        name,
        positions: &merged.positions[0],
        normals: &merged.normals[0],
        uv0: merged.uvs.as_deref(),
        uv1: Some(&lookup),
        indices: &merged.triangles,
    })
}

/// Writes the bake as vertex animation textures.
#[derive(Debug, Default, Clone, Copy)]
pub struct VatExporter;

impl Exporter for VatExporter {
    fn name(&self) -> &str {
        "vat"
    }

    fn extensions(&self) -> &[&str] {
        &["vat"]
    }

    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError> {
        let out = settings.path.as_path();
        let stem = out
            .file_stem()
            .map_or_else(|| "baked".to_owned(), |s| s.to_string_lossy().into_owned());
        let merged = merge(scene, baked, out)?;
        let layout = Layout::new(merged.positions[0].len(), baked.frame_count)
            .map_err(|e| PluginError::invalid(out, e))?;
        let (lo, hi) = offset_bounds(&merged);
        let size = layout.width * layout.height();
        let mut pos = vec![[0.0f32; 4]; size];
        let mut rot = vec![[0.0f32, 0.0, 0.0, 1.0]; size];
        let rest = &merged.positions[0];
        for (f, (frame, normals)) in merged.positions.iter().zip(&merged.normals).enumerate() {
            for (v, (p, n)) in frame.iter().zip(normals).enumerate() {
                let t = layout.texel(v, f);
                let r = rest[v];
                pos[t] = [p[0] - r[0], p[1] - r[1], p[2] - r[2], 1.0];
                rot[t] = normal_rotation(*n);
            }
        }
        let (mut pos8, mut pos8_low, mut rot8) = (
            vec![[0u8; 4]; size],
            vec![[0u8; 4]; size],
            vec![[0u8; 4]; size],
        );
        for t in 0..size {
            for c in 0..3 {
                let range = hi[c] - lo[c];
                let unit = if range > 0.0 {
                    (pos[t][c] - lo[c]) / range
                } else {
                    0.0
                };
                (pos8[t][c], pos8_low[t][c]) = split_ldr(unit);
            }
            (pos8[t][3], pos8_low[t][3]) = (255, 255);
            for c in 0..4 {
                rot8[t][c] = (((rot[t][c] + 1.0) * 0.5).clamp(0.0, 1.0) * 255.0).round() as u8;
            }
        }
        let encode = |e: String| PluginError::invalid(out, e);
        let (w, h) = (layout.width, layout.height());
        let exr = |texels, depth| {
            let image = Rgba {
                width: w,
                height: h,
                texels,
            };
            exr_bytes(&image, depth).map_err(encode)
        };
        let file = |folder: &str, suffix: &str| out.join(folder).join(format!("{stem}{suffix}"));
        let data = json!([{
            "Axis System": "Right-Handed Y-Up",
            "Bound Max X": hi[0], "Bound Max Y": hi[1], "Bound Max Z": hi[2],
            "Bound Min X": lo[0], "Bound Min Y": lo[1], "Bound Min Z": lo[2],
            "Houdini FPS": baked.fps,
            "Name": stem,
            "Two Position Textures": 1,
            "springbake": {
                "mode": "soft body",
                "frame_count": baked.frame_count,
                "fps": baked.fps,
                "vertex_count": layout.vertex_count,
                "texture_width": w,
                "texture_height": h,
                "rows_per_frame": layout.rows_per_frame,
                "lookup_uv": "TEXCOORD_1: frame-0 texel centre, v from the top; frame f at v + f / frame_count",
                "position": "offset from the rest pose (geo mesh, first frame), metres, Y-up",
                "bounds": "of the offsets; the 8-bit textures hold (offset - min) / (max - min) as pos + pos2 * 0.01",
                "rotation": "quaternion (x, y, z, w) taking +Y to the normal; 8-bit: (q + 1) / 2",
                "mesh": format!("geo/{stem}_mesh.glb"),
                "float": {"position": format!("tex/{stem}_pos.exr"), "rotation": format!("tex/{stem}_rot.exr")},
                "8bit": {
                    "position": format!("tex/{stem}_pos.png"),
                    "position2": format!("tex/{stem}_pos2.png"),
                    "rotation": format!("tex/{stem}_rot.png")
                }
            }
        }]);
        let mut json_text = serde_json::to_vec_pretty(&data).unwrap_or_default();
        json_text.push(b'\n');
        Ok(vec![
            OutputFile {
                path: file("geo", "_mesh.glb"),
                bytes: rest_mesh(&merged, &layout, &stem),
            },
            OutputFile {
                path: file("tex", "_pos.exr"),
                bytes: exr(pos, Depth::Full)?,
            },
            OutputFile {
                path: file("tex", "_rot.exr"),
                bytes: exr(rot, Depth::Half)?,
            },
            OutputFile {
                path: file("tex", "_pos.png"),
                bytes: png_bytes(w, h, &pos8).map_err(encode)?,
            },
            OutputFile {
                path: file("tex", "_pos2.png"),
                bytes: png_bytes(w, h, &pos8_low).map_err(encode)?,
            },
            OutputFile {
                path: file("tex", "_rot.png"),
                bytes: png_bytes(w, h, &rot8).map_err(encode)?,
            },
            OutputFile {
                path: file("data", "_data.json"),
                bytes: json_text,
            },
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texels_and_lookup_uvs_agree() {
        let l = Layout::new(2500, 10).unwrap();
        assert_eq!((l.width, l.rows_per_frame, l.height()), (1024, 3, 30));
        // Vertex 1030 is row 1, column 6 of each frame's block.
        assert_eq!(l.texel(1030, 0), 1024 + 6);
        assert_eq!(l.texel(1030, 2), (2 * 3 + 1) * 1024 + 6);
        let [u, v] = l.lookup_uv(1030);
        assert!((u - 6.5 / 1024.0).abs() < 1e-7 && (v - 1.5 / 30.0).abs() < 1e-7);
        // Frame f: v + f / frames lands on the same texel of frame f's block.
        let row = ((v + 2.0 / 10.0) * 30.0).floor() as usize;
        assert_eq!(row * 1024 + (u * 1024.0).floor() as usize, l.texel(1030, 2));
    }

    #[test]
    fn long_bakes_widen_the_texture_and_impossible_ones_are_refused() {
        let l = Layout::new(20_000, 2_000).unwrap();
        assert!(l.height() <= MAX_SIDE && l.width <= MAX_SIDE, "{l:?}");
        assert!(Layout::new(2_000_000, 2_000).is_err());
        assert!(Layout::new(0, 10).is_err());
    }
}
