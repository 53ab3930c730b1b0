//! Scenes: what is simulated, described in code or in a TOML file.
//!
//! ```toml
//! name = "spoon in cup"
//!
//! [tool]
//! mesh = "../../assets/meshes/newell_teaspoon.stl"   # relative to the scene file
//! scale_m_per_unit = 1.0
//! mass_kg = 0.01
//! pose = { position_m = [0.0, 0.12, 0.0], rotation_axis_angle_rad = [0.0, 0.0, 0.0] }
//!
//! [[obstacles]]
//! mesh = "../../assets/meshes/newell_teacup.stl"
//!
//! [coupling]
//! stiffness_n_per_m = 200.0
//! angular_stiffness_nm_per_rad = 0.6
//!
//! [contact]
//! stiffness_n_per_m = 2000.0
//! delta_m = 0.001
//! clusters = 5
//! torque_pairs = true        # two springs per cluster that keep its torque (false: one)
//! error_threshold = 0.0
//! linearized = true
//! fixed_frames = true
//! stopping_rule = "coherence-budget"   # or "deviation" (the paper's), "coherence" (haptic_collision::StoppingRule)
//!
//! [rates]
//! haptic_hz = 1000.0
//!
//! [[device.waypoints]]
//! time_s = 0.0
//! position_m = [0.0, 0.12, 0.0]
//! ```
//!
//! Every field but `tool.mesh` and `tool.mass_kg` has a default. Unknown fields are rejected, and
//! every error names the field it is about.

mod assembly;
mod spec;
#[cfg(test)]
mod tests;

pub use assembly::SceneParts;
pub use spec::{
    ContactSpec, CouplingSpec, DeviceSpec, ObstacleSpec, PoseSpec, RateSpec, Scene, SceneError,
    ToolSpec, WaypointSpec,
};
