//! Writing the compact cache (`cache = "pca"`, issue 23 item 3) of one baked mesh into the
//! document: the rigid part of the motion as its node's translation and rotation keys
//! ([`super::rigid`]), the deformation left as the fewest principal components within the
//! bound ([`super::pca`]), stored as morph targets of normalized 16-bit integers
//! (`KHR_mesh_quantization`) when the reconstruction from those integers still keeps every
//! vertex within the bound, else as floats; one weights key per frame.

use super::builder::{from_snorm16, snorm16, DocBuilder};
use super::pca::{self, UnitCache};
use super::rigid::{NodeTrs, RigidMotion};
use super::{has_normal, mesh_with_extras, Animation};
use serde_json::{json, Value};
use springbake_core::bake::BakedMesh;
use springbake_core::display::{vertex_normals, DisplayMesh};
use springbake_importers::gltf::document::get_usize;

/// The compact cache's settings for one export.
pub(super) struct CompactCache {
    pub max_error_m: f64,
    /// The source's unit, metres.
    pub metres_per_unit: f64,
}

/// Fractions of the bound the components are asked for, in turn, until their 16-bit targets
/// keep the whole bound; float targets after the last.
const QUANTISED_MARGINS: [f64; 3] = [1.0, 0.8, 0.6];

impl CompactCache {
    /// The mesh's cache on `node` (rigid keys where the node can carry them) and `mesh`'s
    /// primitives (POSITION, and NORMAL where the primitive has normals).
    #[allow(clippy::too_many_arguments)]
    pub fn add(
        &self,
        b: &mut DocBuilder,
        node: usize,
        mesh: usize,
        display: &DisplayMesh,
        bm: &BakedMesh,
        times: usize,
        anim: &mut Animation,
    ) -> Result<(), String> {
        let rest: Vec<[f32; 3]> = display
            .primitives
            .iter()
            .flat_map(|p| p.positions.iter().copied())
            .collect();
        let frames = bm.frames.len();
        let node_trs = animatable(b, node);
        let motion = match &node_trs {
            Some(trs) => RigidMotion::fit(&rest, &bm.frames, trs.uniform()),
            None => RigidMotion::still(frames),
        };
        let rows: Vec<Vec<f64>> = (0..frames)
            .map(|f| {
                bm.frames[f]
                    .iter()
                    .zip(&rest)
                    .flat_map(|(&x, r)| {
                        let d = motion.to_rest(f, x);
                        (0..3).map(move |c| d[c] - f64::from(r[c]))
                    })
                    .collect()
            })
            .collect();
        // The smooth normals' change in the moving frame, fitted to the same weights.
        let normal_of = |positions: &[[f32; 3]]| -> Vec<[f32; 3]> {
            let mut out = Vec::with_capacity(positions.len());
            let mut offset = 0;
            for p in &display.primitives {
                let n = p.positions.len();
                out.extend(vertex_normals(&positions[offset..offset + n], &p.indices));
                offset += n;
            }
            out
        };
        let rest_normals = normal_of(&rest);
        let normal_rows: Vec<Vec<f64>> = (0..frames)
            .map(|f| {
                normal_of(&bm.frames[f])
                    .into_iter()
                    .zip(&rest_normals)
                    .flat_map(|(n, r)| {
                        let d = motion.unrotate(f, n);
                        (0..3).map(move |c| d[c] - f64::from(r[c]))
                    })
                    .collect()
            })
            .collect();
        // The bound in the mesh's local units: its node's largest scale times the file's unit.
        let m = display.world_from_local;
        let scale = (0..3)
            .map(|c| m.fixed_view::<3, 1>(0, c).norm())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let metres_per_local = self.metres_per_unit * scale;
        let bound = self.max_error_m / metres_per_local;
        let (cache, quantised) = fit_within(&rows, &normal_rows, bound)?;
        write_targets(b, mesh, display, &cache, quantised);
        let rigid = match &node_trs {
            Some(trs) if trs.uniform() => "rotation and translation",
            Some(_) => "translation",
            None => "none",
        };
        let m = mesh_with_extras(b, mesh);
        m["extras"]["springbake_cache"] = json!({
            "kind": "pca",
            "components": cache.components,
            "max_error_m": cache.max_error * metres_per_local,
            "bound_m": self.max_error_m,
            "rigid": rigid,
            "quantised": quantised,
        });
        if let Some(trs) = node_trs {
            let (translations, rotations) = trs.keys(&motion);
            trs.write(&mut b.array_mut("nodes")[node]);
            let t = b.vec3_keys(&translations);
            anim.add(times, t, node, "translation");
            if trs.uniform() {
                let r = b.vec4_keys(&rotations);
                anim.add(times, r, node, "rotation");
            }
        }
        let k = cache.targets.len();
        if k == 0 {
            return Ok(()); // no deformation beyond the bound
        }
        let m = mesh_with_extras(b, mesh);
        m["weights"] = json!(vec![0.0; k]);
        m["extras"]["targetNames"] = json!(cache.names);
        let weights: Vec<f32> = cache
            .weights
            .iter()
            .flat_map(|w| w.iter().map(|&x| x as f32))
            .collect();
        let output = b.scalars(&weights, false);
        anim.add(times, output, node, "weights");
        Ok(())
    }
}

/// The node's transform when keys may replace it: no animation of the source drives its
/// translation, rotation or scale, it has no children (they would move with it), and it is
/// a TRS or a matrix that is one.
fn animatable(b: &mut DocBuilder, node: usize) -> Option<NodeTrs> {
    let driven = b
        .root
        .get("animations")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .filter_map(|a| a["channels"].as_array())
        .flatten()
        .any(|c| {
            get_usize(&c["target"], "node") == Some(node)
                && matches!(
                    c["target"]["path"].as_str(),
                    Some("translation" | "rotation" | "scale")
                )
        });
    let json = b.array_mut("nodes").get(node)?;
    let parent = json["children"].as_array().is_some_and(|c| !c.is_empty());
    if driven || parent {
        return None;
    }
    NodeTrs::of(json)
}

/// The components within `bound`, with 16-bit targets when their reconstruction keeps it
/// (asking the components for a little less in turn), else with float targets.
fn fit_within(
    rows: &[Vec<f64>],
    normal_rows: &[Vec<f64>],
    bound: f64,
) -> Result<(UnitCache, bool), String> {
    let cache_for = |bound: f64| -> Result<UnitCache, String> {
        let components = pca::principal_components(rows, bound)?;
        let normal_targets = components.fit(normal_rows);
        // Players clamp morph weights to [0, 1] (Blender's shape-key sliders do): each
        // component's weights are mapped onto [0, 1] and its low end moved into one "offset"
        // target held at weight 1.
        Ok(pca::unit_weights(components, normal_targets))
    };
    let mut float = None;
    for margin in QUANTISED_MARGINS {
        let mut cache = cache_for(bound * margin)?;
        let fits = cache
            .targets
            .iter()
            .flatten()
            .all(|x| x.abs() <= 1.0 && x.is_finite());
        if fits {
            let error = playback_error(&cache, rows);
            if error <= bound {
                cache.max_error = error;
                return Ok((cache, true));
            }
        }
        if float.is_none() {
            float = Some(cache);
        }
    }
    float
        .ok_or_else(|| "no components were fitted".to_owned())
        .map(|c| (c, false))
}

/// Largest vertex distance between `rows` and what a player rebuilds from the 16-bit
/// targets and the f32 weights.
fn playback_error(cache: &UnitCache, rows: &[Vec<f64>]) -> f64 {
    let decoded: Vec<Vec<f64>> = cache
        .targets
        .iter()
        .map(|t| {
            t.iter()
                .map(|&x| f64::from(from_snorm16(snorm16(x as f32))))
                .collect()
        })
        .collect();
    let mut worst: f64 = 0.0;
    for (row, weights) in rows.iter().zip(&cache.weights) {
        let mut rebuilt = vec![0.0; row.len()];
        for (target, &w) in decoded.iter().zip(weights) {
            let w = f64::from(w as f32);
            for (r, &t) in rebuilt.iter_mut().zip(target) {
                *r += w * t;
            }
        }
        for (got, want) in rebuilt.chunks_exact(3).zip(row.chunks_exact(3)) {
            let d = (0..3).map(|c| (got[c] - want[c]).powi(2)).sum::<f64>();
            worst = worst.max(d.sqrt());
        }
    }
    worst
}

/// The cache's targets on every primitive of `mesh`: when `quantised`, positions as 16-bit
/// and normals' changes as 8-bit integers (each where it fits in [−1, 1]), else f32.
fn write_targets(
    b: &mut DocBuilder,
    mesh: usize,
    display: &DisplayMesh,
    cache: &UnitCache,
    quantised: bool,
) {
    if cache.targets.is_empty() {
        return;
    }
    let vec3s = |t: &[f64], range: std::ops::Range<usize>| -> Vec<[f32; 3]> {
        t[range.start * 3..range.end * 3]
            .chunks_exact(3)
            .map(|v| [v[0] as f32, v[1] as f32, v[2] as f32])
            .collect()
    };
    let attribute = |b: &mut DocBuilder, data: &[[f32; 3]], position: bool| {
        let small = match (quantised, position) {
            (false, _) => None,
            (true, true) => b.vec3_snorm16(data, true),
            (true, false) => b.vec3_snorm8(data),
        };
        small.unwrap_or_else(|| b.vec3(data, position))
    };
    let mut offset = 0;
    for (p, dp) in display.primitives.iter().enumerate() {
        let range = offset..offset + dp.positions.len();
        let has_normal = has_normal(b, mesh, p);
        let mut targets = Vec::with_capacity(cache.targets.len());
        for (t, nt) in cache.targets.iter().zip(&cache.normal_targets) {
            let position = attribute(b, &vec3s(t, range.clone()), true);
            let mut target = json!({ "POSITION": position });
            if has_normal {
                target["NORMAL"] = json!(attribute(b, &vec3s(nt, range.clone()), false));
            }
            targets.push(target);
        }
        b.array_mut("meshes")[mesh]["primitives"][p]["targets"] = Value::Array(targets);
        offset = range.end;
    }
}
