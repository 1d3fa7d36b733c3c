//! The pose a glTF renders at its first frame (issue 19 item 4): the first animation's
//! channels sampled at t = 0 ([`start_values`]; any animation at any time: [`values_at`]),
//! written into the nodes as their static transform and morph weights ([`pose_at_start`]),
//! and the geometry of a mesh under that pose ([`posed_primitive`]): its morph targets at the node's weights, then its skin at the
//! joints' world matrices. Bodies start from what the artist sees; the exporter writes the
//! same pose as the output's static one and drops what drove it.

use super::accessor::read_floats;
use super::document::{get_usize, GltfDocument};
use nalgebra::{Matrix3, Matrix4, Point3, Quaternion, UnitQuaternion, Vector3};
use serde_json::{json, Value};
use springbake_core::display::Primitive;
use springbake_core::plugin::PluginError;

/// One animation channel's value at a time.
#[derive(Debug, Clone, PartialEq)]
pub struct StartValue {
    /// Index of the channel in its animation's `channels`.
    pub channel: usize,
    pub node: usize,
    /// `translation`, `rotation`, `scale` or `weights`.
    pub path: String,
    pub value: Vec<f64>,
}

/// The first animation's channels at t = 0 (before its first key: the first key; between
/// keys: interpolated as the sampler says). None without animations.
pub fn start_values(doc: &GltfDocument) -> Result<Vec<StartValue>, PluginError> {
    if doc.array("animations").is_empty() {
        return Ok(Vec::new());
    }
    values_at(
        doc,
        0,
        0.0,
        &["translation", "rotation", "scale", "weights"],
    )
}

/// The node channels of `animations[animation]` whose path is one of `paths` (translation,
/// rotation, scale, weights) at `time` seconds; other channels are not read.
pub fn values_at(
    doc: &GltfDocument,
    animation: usize,
    time: f64,
    paths: &[&str],
) -> Result<Vec<StartValue>, PluginError> {
    let Some(json) = doc.array("animations").get(animation) else {
        return Ok(Vec::new());
    };
    let channels = json["channels"].as_array().cloned().unwrap_or_default();
    let mut out = Vec::new();
    for (c, channel) in channels.iter().enumerate() {
        let location = format!("animations[{animation}].channels[{c}]");
        let target = &channel["target"];
        let (Some(node), Some(path)) = (get_usize(target, "node"), target["path"].as_str()) else {
            continue; // a channel without a node drives nothing here
        };
        if !paths.contains(&path) {
            continue;
        }
        let sampler = get_usize(channel, "sampler")
            .and_then(|s| json["samplers"].get(s))
            .ok_or_else(|| doc.error(&location, "the channel's sampler does not exist"))?;
        let value = sample_at(doc, sampler, path == "rotation", time, &location)?;
        out.push(StartValue {
            channel: c,
            node,
            path: path.to_owned(),
            value,
        });
    }
    Ok(out)
}

/// A sampler's value at `time`.
fn sample_at(
    doc: &GltfDocument,
    sampler: &Value,
    rotation: bool,
    time: f64,
    location: &str,
) -> Result<Vec<f64>, PluginError> {
    let input = get_usize(sampler, "input")
        .ok_or_else(|| doc.error(location, "the sampler has no input"))?;
    let output = get_usize(sampler, "output")
        .ok_or_else(|| doc.error(location, "the sampler has no output"))?;
    let (times, _) = read_floats(doc, input, location)?;
    let (values, _) = read_floats(doc, output, location)?;
    let keys = times.len();
    let interpolation = sampler["interpolation"].as_str().unwrap_or("LINEAR");
    // CUBICSPLINE stores in-tangent, value, out-tangent per key.
    let (per_key_blocks, value_block) = if interpolation == "CUBICSPLINE" {
        (3, 1)
    } else {
        (1, 0)
    };
    if keys == 0 || values.len() % (keys * per_key_blocks) != 0 {
        return Err(doc.error(
            location,
            format!(
                "{} output values do not fit {keys} keys of {interpolation}",
                values.len()
            ),
        ));
    }
    let width = values.len() / (keys * per_key_blocks);
    let value = |k: usize| -> Vec<f64> {
        let start = (k * per_key_blocks + value_block) * width;
        values[start..start + width]
            .iter()
            .map(|&x| f64::from(x))
            .collect()
    };
    let after = times
        .iter()
        .position(|&t| f64::from(t) > time)
        .unwrap_or(keys);
    if after == 0 || after == keys || interpolation != "LINEAR" {
        // before the first key, after the last, or STEP / CUBICSPLINE at a key's value
        return Ok(value(after.saturating_sub(1)));
    }
    let (t0, t1) = (f64::from(times[after - 1]), f64::from(times[after]));
    let s = if t1 > t0 {
        (time - t0) / (t1 - t0)
    } else {
        0.0
    };
    let (a, b) = (value(after - 1), value(after));
    if rotation && width == 4 {
        let q =
            |v: &[f64]| UnitQuaternion::from_quaternion(Quaternion::new(v[3], v[0], v[1], v[2]));
        let r = q(&a).slerp(&q(&b), s).into_inner().coords;
        return Ok(vec![r.x, r.y, r.z, r.w]);
    }
    Ok(a.iter().zip(&b).map(|(x, y)| x + s * (y - x)).collect())
}

/// Writes `values` into the nodes of `json` as their static transform (a `matrix` node
/// animated in TRS becomes TRS, when its matrix is one) and morph weights.
pub fn pose_at_start(doc_json: &mut Value, values: &[StartValue]) {
    for v in values {
        let Some(node) = doc_json["nodes"].get_mut(v.node) else {
            continue;
        };
        if v.path != "weights" {
            if let Some(m) = node.get("matrix").cloned() {
                // glTF animates TRS nodes only; a matrix that is no TRS is left unposed.
                let Some(trs) = trs_of_matrix(&m) else {
                    continue;
                };
                if let Some(o) = node.as_object_mut() {
                    o.remove("matrix");
                }
                for (key, value) in trs {
                    node[key] = value;
                }
            }
        }
        node[v.path.as_str()] = json!(v.value);
    }
}

/// A node matrix as glTF's translation, rotation and scale, when it is one (affine, no shear,
/// no mirror); `None` otherwise.
pub fn decompose(m: &Matrix4<f64>) -> Option<(Vector3<f64>, UnitQuaternion<f64>, Vector3<f64>)> {
    let linear = m.fixed_view::<3, 3>(0, 0).into_owned();
    let scale = Vector3::from_fn(|c, _| linear.column(c).norm());
    if scale.min() <= 0.0 || m.row(3).transpose() != nalgebra::Vector4::w() {
        return None;
    }
    let rotation = Matrix3::from_fn(|r, c| linear[(r, c)] / scale[c]);
    let orthonormal = (rotation.transpose() * rotation - Matrix3::identity())
        .abs()
        .max();
    if orthonormal > 1e-6 || rotation.determinant() < 0.0 {
        return None;
    }
    let translation = m.fixed_view::<3, 1>(0, 3).into_owned();
    Some((translation, UnitQuaternion::from_matrix(&rotation), scale))
}

/// A node's column-major `matrix` as TRS JSON values, when it is a TRS ([`decompose`]).
fn trs_of_matrix(m: &Value) -> Option<Vec<(&'static str, Value)>> {
    let c: Vec<f64> = m.as_array()?.iter().filter_map(Value::as_f64).collect();
    if c.len() != 16 {
        return None;
    }
    let (t, r, s) = decompose(&Matrix4::from_column_slice(&c))?;
    let q = r.coords;
    Some(vec![
        ("translation", json!([t.x, t.y, t.z])),
        ("rotation", json!([q.x, q.y, q.z, q.w])),
        ("scale", json!([s.x, s.y, s.z])),
    ])
}

/// The morph targets' and skin's part of a posed primitive.
pub struct Deformers<'a> {
    /// The node's morph weights (its own, else the mesh's).
    pub weights: &'a [f64],
    /// Per joint, `joint world × inverse bind`, and the world-from-local the posed vertices
    /// are expressed in; `None` without a skin.
    pub skin: Option<(Vec<Matrix4<f64>>, Matrix4<f64>)>,
}

/// `prim` (the mesh's `primitives[p]` JSON, already read into `base`) under `deformers`:
/// positions and normals with the targets at their weights, then skinned into the node's
/// local frame. Vertices no joint weighs keep their morphed rest position.
pub fn posed_primitive(
    doc: &GltfDocument,
    prim: &Value,
    location: &str,
    base: Primitive,
    deformers: &Deformers,
) -> Result<Primitive, PluginError> {
    let mut out = base;
    let targets = prim["targets"].as_array().cloned().unwrap_or_default();
    let mut morphed = false;
    for (t, target) in targets.iter().enumerate() {
        let w = deformers.weights.get(t).copied().unwrap_or(0.0);
        if w == 0.0 {
            continue;
        }
        let loc = format!("{location}.targets[{t}]");
        morphed = true;
        if let Some(i) = get_usize(target, "POSITION") {
            add_scaled(&mut out.positions, &read_floats(doc, i, &loc)?.0, w);
        }
        if let (Some(i), Some(normals)) = (get_usize(target, "NORMAL"), out.normals.as_mut()) {
            add_scaled(normals, &read_floats(doc, i, &loc)?.0, w);
        }
    }
    if let (true, Some(normals)) = (morphed, out.normals.as_mut()) {
        for n in normals.iter_mut() {
            let v = Vector3::new(n[0], n[1], n[2]);
            if let Some(u) = v.try_normalize(1e-12) {
                *n = [u.x, u.y, u.z];
            }
        }
    }
    let Some((joints, world_from_local)) = &deformers.skin else {
        return Ok(out);
    };
    let local_from_world = world_from_local
        .try_inverse()
        .unwrap_or_else(Matrix4::identity);
    let attributes = &prim["attributes"];
    let n = out.positions.len();
    let mut blend = vec![Matrix4::<f64>::zeros(); n];
    let mut weighed = vec![false; n];
    for set in 0.. {
        let (Some(ji), Some(wi)) = (
            get_usize(attributes, &format!("JOINTS_{set}")),
            get_usize(attributes, &format!("WEIGHTS_{set}")),
        ) else {
            break;
        };
        let loc = format!("{location}.attributes.JOINTS_{set}");
        let (js, _) = read_floats(doc, ji, &loc)?;
        let (ws, _) = read_floats(doc, wi, &loc)?;
        if js.len() < 4 * n || ws.len() < 4 * n {
            return Err(doc.error(loc, format!("fewer than {n} joint sets of 4")));
        }
        for v in 0..n {
            for c in 0..4 {
                let w = f64::from(ws[4 * v + c]);
                if w == 0.0 {
                    continue;
                }
                let j = js[4 * v + c] as usize;
                let m = joints.get(j).ok_or_else(|| {
                    doc.error(
                        &loc,
                        format!("joint {j} is beyond the skin's {} joints", joints.len()),
                    )
                })?;
                blend[v] += m * w;
                weighed[v] = true;
            }
        }
    }
    for v in 0..n {
        if !weighed[v] {
            continue;
        }
        let to_local = local_from_world * blend[v];
        let p = out.positions[v];
        let q = to_local.transform_point(&Point3::new(
            f64::from(p[0]),
            f64::from(p[1]),
            f64::from(p[2]),
        ));
        out.positions[v] = [q.x as f32, q.y as f32, q.z as f32];
        if let Some(normals) = out.normals.as_mut() {
            let linear = to_local.fixed_view::<3, 3>(0, 0).into_owned();
            let normal_matrix = linear.try_inverse().map_or(linear, |i| i.transpose());
            let m = normals[v];
            let d = normal_matrix * Vector3::new(f64::from(m[0]), f64::from(m[1]), f64::from(m[2]));
            let d = d.try_normalize(1e-12).unwrap_or(d);
            normals[v] = [d.x as f32, d.y as f32, d.z as f32];
        }
    }
    Ok(out)
}

/// `x += w · delta`, delta flat triples.
fn add_scaled(x: &mut [[f32; 3]], delta: &[f32], w: f64) {
    for (p, d) in x.iter_mut().zip(delta.chunks_exact(3)) {
        for c in 0..3 {
            p[c] = (f64::from(p[c]) + w * f64::from(d[c])) as f32;
        }
    }
}
