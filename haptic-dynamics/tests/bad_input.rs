//! Bad input to the grasp and coupling constructors gives the right error variant.

use haptic_core::{DeviceState, Pose, ToolState, Vec3};
use haptic_dynamics::{CouplingParams, DynamicsError, Grasp, VirtualCoupling};
use nalgebra::UnitQuaternion;

#[test]
fn grasp_and_coupling_reject_bad_input() {
    let tool = ToolState::at_rest(&Pose::identity());
    let mut nan_tool = tool;
    nan_tool.x.y = f64::NAN;
    assert!(matches!(
        Grasp::new(&nan_tool, &Pose::identity()),
        Err(DynamicsError::Core(
            haptic_core::CoreError::NonFinite { .. }
        ))
    ));
    let nan_handle = Pose::from_position(Vec3::new(f64::INFINITY, 0.0, 0.0));
    assert!(matches!(
        Grasp::new(&tool, &nan_handle),
        Err(DynamicsError::Core(
            haptic_core::CoreError::NonFinite { .. }
        ))
    ));
    assert!(matches!(
        Grasp::from_parts(Vec3::new(f64::NAN, 0.0, 0.0), UnitQuaternion::identity()),
        Err(DynamicsError::Core(
            haptic_core::CoreError::NonFinite { .. }
        ))
    ));
    let grasp = Grasp::new(&tool, &Pose::identity()).unwrap();
    let device = DeviceState::at_rest(Pose::identity(), 0.0);
    let bad_params = CouplingParams {
        stiffness_n_per_m: -1.0,
        ..CouplingParams::default()
    };
    assert!(matches!(
        VirtualCoupling::new(bad_params, grasp, &device),
        Err(DynamicsError::Core(
            haptic_core::CoreError::OutOfRange { .. }
        ))
    ));
    let mut nan_device = device;
    nan_device.twist.linear.x = f64::NAN;
    assert!(matches!(
        VirtualCoupling::new(CouplingParams::default(), grasp, &nan_device),
        Err(DynamicsError::Core(
            haptic_core::CoreError::NonFinite { .. }
        ))
    ));
}
