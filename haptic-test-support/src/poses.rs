//! Pose paths of the benchmarks.

use haptic_core::{Pose, Real, Vec3};
use nalgebra::UnitQuaternion;

/// `count` poses of the upper jaw around its stored place in occlusion (body origin at `com`):
/// along a closed path by up to 0.5 mm sideways, from 0.1 mm down to 0.5 mm up, and tilted by up
/// to 0.3°.
pub fn jaws_poses(com: &Vec3, count: usize) -> Vec<Pose> {
    (0..count)
        .map(|i| {
            let s = i as Real / count as Real * std::f64::consts::TAU;
            let dp = Vec3::new(
                0.5e-3 * s.sin(),
                0.5e-3 * (2.0 * s).cos(),
                0.3e-3 * (3.0 * s).sin() + 0.2e-3,
            );
            let rot = UnitQuaternion::from_scaled_axis(Vec3::new(
                0.005 * s.cos(),
                0.005 * s.sin(),
                0.003 * (2.0 * s).sin(),
            ));
            Pose {
                position: com + dp,
                orientation: rot,
            }
        })
        .collect()
}
