//! The rigid part of a mesh's baked motion, for the compact cache (issue 23 item 3): per
//! frame, the rotation and translation that carry the rest pose closest to the frame (Kabsch,
//! least squares over the vertices), played as the node's own translation and rotation keys.
//! The principal components then carry only the deformation: a body that falls, bounces and
//! tumbles is mostly rigid motion, which a handful of linear morph targets cannot play.
//!
//! A node's keys replace its static transform, so the motion is composed with it: with the
//! node `N = T·R·S` and the frame's motion `M(v) = Q·v + u` in the mesh's local frame,
//! `N·M = T' · R·Q · S` where `T' = t + R·(S ⊙ u)`. That holds when `S` is uniform (it
//! commutes with `Q`); a node with a non-uniform scale gets the translation only (`Q = 1`).

use serde_json::{json, Value};
use springbake_core::nalgebra::{Matrix3, Matrix4, Quaternion, UnitQuaternion, Vector3};
use springbake_importers::gltf::pose::decompose;

/// Per frame, the rigid motion `x ≈ Q·r + u` of the mesh's vertices from their rest pose `r`
/// (the mesh's local frame).
pub struct RigidMotion {
    pub rotations: Vec<UnitQuaternion<f64>>,
    pub translations: Vec<Vector3<f64>>,
}

impl RigidMotion {
    /// The best rigid motion of every frame (rotation too when `rotate`).
    pub fn fit(rest: &[[f32; 3]], frames: &[Vec<[f32; 3]>], rotate: bool) -> RigidMotion {
        let r: Vec<Vector3<f64>> = rest.iter().map(vector).collect();
        let r_mean = mean(&r);
        let mut motion = RigidMotion {
            rotations: Vec::with_capacity(frames.len()),
            translations: Vec::with_capacity(frames.len()),
        };
        let mut previous = UnitQuaternion::identity();
        for frame in frames {
            let x: Vec<Vector3<f64>> = frame.iter().map(vector).collect();
            let x_mean = mean(&x);
            let q = if rotate {
                let mut covariance = Matrix3::zeros();
                for (a, b) in r.iter().zip(&x) {
                    covariance += (b - x_mean) * (a - r_mean).transpose();
                }
                let q = best_rotation(&covariance);
                // Keys on one side of the quaternion sphere: players that interpolate the
                // components (Blender's f-curves) take the short way between frames.
                if q.coords.dot(&previous.coords) < 0.0 {
                    UnitQuaternion::new_unchecked(-q.into_inner())
                } else {
                    q
                }
            } else {
                UnitQuaternion::identity()
            };
            previous = q;
            motion.translations.push(x_mean - q * r_mean);
            motion.rotations.push(q);
        }
        motion
    }

    /// No motion in any of `frames` frames.
    pub fn still(frames: usize) -> RigidMotion {
        RigidMotion {
            rotations: vec![UnitQuaternion::identity(); frames],
            translations: vec![Vector3::zeros(); frames],
        }
    }

    /// A frame's point `x` carried back by the inverse motion: `Qᵀ·(x − u)`.
    pub fn to_rest(&self, frame: usize, x: [f32; 3]) -> Vector3<f64> {
        self.rotations[frame].inverse_transform_vector(&(vector(&x) - self.translations[frame]))
    }

    /// A frame's direction (a normal) carried back by the inverse rotation.
    pub fn unrotate(&self, frame: usize, n: [f32; 3]) -> Vector3<f64> {
        self.rotations[frame].inverse_transform_vector(&vector(&n))
    }
}

/// The rotation `Q` maximising `tr(Qᵀ·H)` for `H = Σ (x − x̄)(r − r̄)ᵀ` (Kabsch: from the SVD,
/// with the reflection taken out).
fn best_rotation(covariance: &Matrix3<f64>) -> UnitQuaternion<f64> {
    let svd = covariance.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return UnitQuaternion::identity();
    };
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    UnitQuaternion::from_matrix(&(u * d * v_t))
}

fn vector(p: &[f32; 3]) -> Vector3<f64> {
    Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
}

fn mean(points: &[Vector3<f64>]) -> Vector3<f64> {
    points.iter().sum::<Vector3<f64>>() / points.len().max(1) as f64
}

/// A node's local transform as glTF's translation, rotation and scale.
pub struct NodeTrs {
    translation: Vector3<f64>,
    rotation: UnitQuaternion<f64>,
    scale: Vector3<f64>,
}

impl NodeTrs {
    /// The node's transform, from its TRS or from a `matrix` that is one (no shear, no
    /// mirror); `None` otherwise.
    pub fn of(node: &Value) -> Option<NodeTrs> {
        let numbers = |key: &str, n: usize| -> Option<Vec<f64>> {
            let a = node.get(key)?.as_array()?;
            let v: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
            (v.len() == n).then_some(v)
        };
        if node.get("matrix").is_some() {
            return Self::of_matrix(&Matrix4::from_column_slice(&numbers("matrix", 16)?));
        }
        let t = numbers("translation", 3).unwrap_or_else(|| vec![0.0; 3]);
        let r = numbers("rotation", 4).unwrap_or_else(|| vec![0.0, 0.0, 0.0, 1.0]);
        let s = numbers("scale", 3).unwrap_or_else(|| vec![1.0; 3]);
        Some(NodeTrs {
            translation: Vector3::new(t[0], t[1], t[2]),
            rotation: UnitQuaternion::from_quaternion(Quaternion::new(r[3], r[0], r[1], r[2])),
            scale: Vector3::new(s[0], s[1], s[2]),
        })
    }

    fn of_matrix(m: &Matrix4<f64>) -> Option<NodeTrs> {
        let (translation, rotation, scale) = decompose(m)?;
        Some(NodeTrs {
            translation,
            rotation,
            scale,
        })
    }

    /// Whether the scale is the same along every axis (the rotation can go on the node).
    pub fn uniform(&self) -> bool {
        let s = self.scale;
        (s.x - s.y).abs() <= 1e-9 * s.x.abs() && (s.x - s.z).abs() <= 1e-9 * s.x.abs()
    }

    /// The node's translation and rotation keys (glTF's `[x, y, z, w]`) playing `motion`.
    pub fn keys(&self, motion: &RigidMotion) -> (Vec<[f32; 3]>, Vec<[f32; 4]>) {
        let translations = motion
            .translations
            .iter()
            .map(|u| {
                let t = self.translation + self.rotation * self.scale.component_mul(u);
                [t.x as f32, t.y as f32, t.z as f32]
            })
            .collect();
        let rotations = motion
            .rotations
            .iter()
            .map(|q| {
                let c = (self.rotation * q).into_inner().coords;
                [c.x as f32, c.y as f32, c.z as f32, c.w as f32]
            })
            .collect();
        (translations, rotations)
    }

    /// The node's JSON with this transform as TRS (a `matrix` can not be animated).
    pub fn write(&self, node: &mut Value) {
        if let Some(o) = node.as_object_mut() {
            o.remove("matrix");
        }
        let (t, q, s) = (self.translation, self.rotation.coords, self.scale);
        node["translation"] = json!([t.x, t.y, t.z]);
        node["rotation"] = json!([q.x, q.y, q.z, q.w]);
        node["scale"] = json!([s.x, s.y, s.z]);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_turned_and_moved_copy_is_found_exactly() {
        let rest: Vec<[f32; 3]> = vec![[0., 0., 0.], [1., 0., 0.], [0., 2., 0.], [0., 0., 3.]];
        let q = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0);
        let u = Vector3::new(0.5, -2.0, 7.0);
        let moved: Vec<[f32; 3]> = rest
            .iter()
            .map(|r| {
                let x = q * vector(r) + u;
                [x.x as f32, x.y as f32, x.z as f32]
            })
            .collect();
        let m = RigidMotion::fit(&rest, &[rest.clone(), moved.clone()], true);
        assert!(m.rotations[1].angle_to(&q) < 1e-6);
        for (r, x) in rest.iter().zip(&moved) {
            assert!((m.to_rest(1, *x) - vector(r)).norm() < 1e-5);
        }
        // translation only: the centroid's move
        let t = RigidMotion::fit(&rest, &[moved], false);
        assert_eq!(t.rotations[0], UnitQuaternion::identity());
    }

    #[test]
    fn node_keys_compose_with_the_node_transform() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let node = json!({"translation": [1.0, 2.0, 3.0], "rotation": [0.0, 0.0, h, h],
                          "scale": [2.0, 2.0, 2.0]});
        let trs = NodeTrs::of(&node).unwrap();
        assert!(trs.uniform());
        let motion = RigidMotion {
            rotations: vec![UnitQuaternion::from_euler_angles(0.2, 0.0, 0.0)],
            translations: vec![Vector3::new(0.1, 0.0, 0.0)],
        };
        let (t, r) = trs.keys(&motion);
        let keyed =
            NodeTrs::of(&json!({"translation": t[0], "rotation": r[0], "scale": [2.0, 2.0, 2.0]}))
                .unwrap();
        // N·M·v against the keyed node's transform of v
        let v = Vector3::new(0.3, -0.4, 0.5);
        let expect = trs.translation
            + trs.rotation
                * (trs
                    .scale
                    .component_mul(&(motion.rotations[0] * v + motion.translations[0])));
        let got = keyed.translation + keyed.rotation * keyed.scale.component_mul(&v);
        assert!((expect - got).norm() < 1e-6, "{expect} vs {got}");
        // a matrix node decomposes; a mirrored one does not
        let m = Matrix4::new_translation(&Vector3::new(1.0, 0.0, 0.0)) * Matrix4::new_scaling(3.0);
        let from_matrix = NodeTrs::of(&json!({"matrix": m.as_slice()})).unwrap();
        assert!((from_matrix.scale - Vector3::repeat(3.0)).norm() < 1e-12);
        let mirror = Matrix4::new_nonuniform_scaling(&Vector3::new(-1.0, 1.0, 1.0));
        assert!(NodeTrs::of(&json!({"matrix": mirror.as_slice()})).is_none());
    }
}
