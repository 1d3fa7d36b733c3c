//! The simulation frame: metres, with the scene's up axis. Sources come in their own units and
//! up axis (glTF/OBJ Y-up metres, Blender's USD Z-up) and go back out the same way.

use springbake_core::display::UpAxis;
use springbake_core::nalgebra::{Matrix4, Vector3};

/// Converts between a source's world frame and the simulation frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimFrame {
    pub up: UpAxis,
}

impl SimFrame {
    /// Unit up vector in simulation coordinates.
    pub fn up_vector(&self) -> Vector3<f64> {
        self.up.vector()
    }

    /// Maps source world coordinates (source units, `source_up`) into simulation metres.
    /// Y-up to Z-up is Blender's convention `(x, y, z) → (x, −z, y)`.
    pub fn sim_from_source(&self, source_up: UpAxis, meters_per_unit: f64) -> Matrix4<f64> {
        let rotate = match (source_up, self.up) {
            (UpAxis::Y, UpAxis::Z) => Matrix4::new(
                1.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, -1.0, 0.0, //
                0.0, 1.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0,
            ),
            (UpAxis::Z, UpAxis::Y) => Matrix4::new(
                1.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, 1.0, 0.0, //
                0.0, -1.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0,
            ),
            _ => Matrix4::identity(),
        };
        rotate * Matrix4::new_scaling(meters_per_unit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use springbake_core::nalgebra::Point3;

    #[test]
    fn y_up_source_into_z_up_sim_keeps_up_up_and_handedness() {
        let m = SimFrame { up: UpAxis::Z }.sim_from_source(UpAxis::Y, 1.0);
        assert_eq!(
            m.transform_point(&Point3::new(0.0, 1.0, 0.0)),
            Point3::new(0.0, 0.0, 1.0)
        );
        assert!(m.fixed_view::<3, 3>(0, 0).determinant() > 0.0);
        let back = SimFrame { up: UpAxis::Y }.sim_from_source(UpAxis::Z, 1.0);
        assert_eq!(back * m, Matrix4::identity());
    }

    #[test]
    fn units_scale_to_metres() {
        let m = SimFrame { up: UpAxis::Y }.sim_from_source(UpAxis::Y, 0.01);
        assert_eq!(
            m.transform_point(&Point3::new(100.0, 0.0, 0.0)),
            Point3::new(1.0, 0.0, 0.0)
        );
    }
}
