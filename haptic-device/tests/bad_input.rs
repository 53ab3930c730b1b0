//! Bad input to the scaling wrapper's builders gives the right error variant.

use haptic_core::{DeviceLimits, Pose, Vec3};
use haptic_device::{DeviceError, ScaledDevice, ScriptedDevice};

fn scaled() -> ScaledDevice<ScriptedDevice> {
    let limits =
        DeviceLimits::new(10.0, 1.0, Vec3::repeat(-1.0), Vec3::repeat(1.0), 1000.0).unwrap();
    let inner = ScriptedDevice::stationary(Pose::identity(), limits).unwrap();
    ScaledDevice::new(inner, 0.4, 2.5).unwrap()
}

#[test]
fn scaling_rejects_bad_scales_and_origins() {
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(
                scaled().with_torque_scale(bad),
                Err(DeviceError::Parameter(_))
            ),
            "torque scale {bad}"
        );
    }
    assert!(matches!(
        scaled().with_origin(Vec3::new(0.0, f64::NAN, 0.0)),
        Err(DeviceError::Parameter(haptic_core::CoreError::NonFinite {
            what: "scaled.origin_m"
        }))
    ));
    assert!(scaled().with_torque_scale(3.0).is_ok());
    assert!(scaled().with_origin(Vec3::new(0.1, 0.0, 0.0)).is_ok());
}
