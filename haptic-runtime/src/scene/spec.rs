//! The scene file's contents: the specs, their defaults, parsing and validation.

use std::path::{Path, PathBuf};

use haptic_core::{Pose, Real, Vec3};
use nalgebra::UnitQuaternion;
use serde::Deserialize;

/// A scene could not be read or is invalid.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// The file could not be read.
    #[error("cannot read scene {path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        message: String,
    },
    /// The TOML is malformed, has an unknown field, or a field of the wrong type; the message
    /// names the field and the line.
    #[error("bad scene file: {0}")]
    Parse(String),
    /// A field has a value out of range.
    #[error("scene field `{field}`: {reason}")]
    Invalid {
        /// The field, as a dotted path (`tool.mass_kg`).
        field: String,
        /// Why it is invalid.
        reason: String,
    },
}

pub(super) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        field: field.into(),
        reason: reason.into(),
    }
}

/// A pose as written in a scene: position (m) and rotation vector (axis × angle, rad).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PoseSpec {
    /// Position, m.
    #[serde(default)]
    pub position_m: [Real; 3],
    /// Rotation vector, rad.
    #[serde(default)]
    pub rotation_axis_angle_rad: [Real; 3],
}

impl PoseSpec {
    /// A pose from position and rotation vector.
    pub fn new(position_m: [Real; 3], rotation_axis_angle_rad: [Real; 3]) -> Self {
        Self {
            position_m,
            rotation_axis_angle_rad,
        }
    }

    /// The pose.
    pub fn pose(&self) -> Pose {
        Pose {
            position: Vec3::from(self.position_m),
            orientation: UnitQuaternion::from_scaled_axis(Vec3::from(self.rotation_axis_angle_rad)),
        }
    }

    fn validate(&self, field: &str) -> Result<(), SceneError> {
        if self
            .position_m
            .iter()
            .chain(&self.rotation_axis_angle_rad)
            .any(|v| !v.is_finite())
        {
            return Err(invalid(field, "must be finite"));
        }
        Ok(())
    }
}

fn one() -> Real {
    1.0
}

/// The tool.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolSpec {
    /// Mesh file (STL, OBJ, PLY), relative to the scene file.
    pub mesh: PathBuf,
    /// Metres per file unit (0.001 for millimetres).
    #[serde(default = "one")]
    pub scale_m_per_unit: Real,
    /// Mass, kg; the inertia is that of a uniform solid of the mesh's shape.
    pub mass_kg: Real,
    /// Initial pose of the tool's centre-of-mass frame (the mesh is recentred on its centre of
    /// mass).
    #[serde(default)]
    pub pose: PoseSpec,
}

/// A static obstacle.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// Mesh file, relative to the scene file.
    pub mesh: PathBuf,
    /// Metres per file unit.
    #[serde(default = "one")]
    pub scale_m_per_unit: Real,
    /// Where the mesh's own frame is placed in the world.
    #[serde(default)]
    pub pose: PoseSpec,
}

/// Virtual coupling parameters (eqs. 13–27).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CouplingSpec {
    /// k, N/m.
    pub stiffness_n_per_m: Real,
    /// b, N s/m; `None` picks the default damping of `haptic-dynamics`.
    pub damping_ns_per_m: Option<Real>,
    /// k_θ, N m/rad.
    pub angular_stiffness_nm_per_rad: Real,
    /// b_θ, N m s/rad; `None` picks the default.
    pub angular_damping_nms_per_rad: Option<Real>,
}

impl Default for CouplingSpec {
    fn default() -> Self {
        Self {
            stiffness_n_per_m: 200.0,
            damping_ns_per_m: None,
            angular_stiffness_nm_per_rad: 0.6,
            angular_damping_nms_per_rad: None,
        }
    }
}

/// Contact parameters.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactSpec {
    /// Penalty stiffness k_c, N/m.
    pub stiffness_n_per_m: Real,
    /// Penalty damping b_c, N s/m; `None` picks the default.
    pub damping_ns_per_m: Option<Real>,
    /// Distance tolerance δ (pre-contact), m.
    pub delta_m: Real,
    /// K, the most clusters: 1 to [`haptic_core::MAX_REPRESENTATIVES`], or to half that with
    /// `torque_pairs`.
    pub clusters: usize,
    /// Write each cluster as a torque pair of two springs that keep its contacts' torque as
    /// well as their force (true, the default), or as one spring (false: the paper's model).
    /// See `haptic_cluster::ClusterParams::torque_pairs`.
    pub torque_pairs: bool,
    /// Error threshold of the multiresolution collision detection (fraction of the radius).
    pub error_threshold: Real,
    /// A contact model that follows the tool between updates (true) or forces held constant
    /// between updates (false: the paper's ablation).
    pub linearized: bool,
    /// With `linearized`: evaluate each representative on its frame held fixed, with the tool's
    /// exact kinematics (true, the default), or on its tangent at the queried state (false:
    /// the paper's eq. 42). See `haptic_core::LinearizationMode`.
    pub fixed_frames: bool,
    /// A time budget per contact update (s): the error threshold is then picked update by
    /// update to fit it, and `error_threshold` is not used (see `haptic_runtime::budget`).
    pub time_budget_s: Option<Real>,
    /// Where the multiresolution back-end may stop at coarse pieces: `"coherence-budget"` (the
    /// default: the pieces' normal coherence held for the regions' sum against the net force),
    /// `"deviation"` (the paper's) or `"coherence"` (that coherence wherever a pair writes a
    /// contact; `haptic_collision::StoppingRule`).
    #[serde(deserialize_with = "stopping_rule")]
    pub stopping_rule: haptic_collision::StoppingRule,
}

/// Reads a stopping rule by its name ([`haptic_collision::StoppingRule::name`]).
fn stopping_rule<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<haptic_collision::StoppingRule, D::Error> {
    let name = String::deserialize(d)?;
    name.parse().map_err(serde::de::Error::custom)
}

impl Default for ContactSpec {
    fn default() -> Self {
        Self {
            stiffness_n_per_m: 2000.0,
            damping_ns_per_m: None,
            delta_m: 1e-3,
            clusters: 5,
            torque_pairs: true,
            error_threshold: 0.0,
            linearized: true,
            fixed_frames: true,
            time_budget_s: None,
            stopping_rule: haptic_collision::StoppingRule::default(),
        }
    }
}

impl ContactSpec {
    /// How the haptic thread uses the contact model between updates: `linearized = false` holds
    /// the forces constant; otherwise fixed frames, or the paper's tangents with
    /// `fixed_frames = false`.
    pub fn linearization(&self) -> haptic_core::LinearizationMode {
        use haptic_core::LinearizationMode::{Constant, FixedFrames, Linearized};
        match (self.linearized, self.fixed_frames) {
            (false, _) => Constant,
            (true, true) => FixedFrames,
            (true, false) => Linearized,
        }
    }
}

/// Rates.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RateSpec {
    /// Haptic rate, Hz.
    pub haptic_hz: Real,
    /// Contact rate in virtual time, Hz; `None` uses the measured cost of each query.
    pub contact_hz: Option<Real>,
}

impl Default for RateSpec {
    fn default() -> Self {
        Self {
            haptic_hz: 1000.0,
            contact_hz: None,
        }
    }
}

/// A waypoint of the simulated hand's target trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaypointSpec {
    /// Time, s.
    pub time_s: Real,
    /// Target handle position, m.
    pub position_m: [Real; 3],
    /// Target handle rotation vector, rad.
    #[serde(default)]
    pub rotation_axis_angle_rad: [Real; 3],
}

/// The simulated user's device.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DeviceSpec {
    /// Target trajectory of the simulated hand (minimum-jerk between waypoints); empty keeps the
    /// handle where the tool starts.
    pub waypoints: Vec<WaypointSpec>,
    /// Largest force the device renders (N); wrenches beyond are clamped and counted.
    pub max_force_n: Real,
    /// Largest torque the device renders (N m).
    pub max_torque_nm: Real,
    /// Half the side of the cubic workspace around the first handle position (m).
    pub workspace_half_m: Real,
}

impl Default for DeviceSpec {
    /// No waypoints; 10 N, 1 N m (a desktop 6-DOF device), a 0.5 m workspace.
    fn default() -> Self {
        Self {
            waypoints: Vec::new(),
            max_force_n: 10.0,
            max_torque_nm: 1.0,
            workspace_half_m: 0.5,
        }
    }
}

/// A whole scene.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Name, for reports.
    #[serde(default)]
    pub name: String,
    /// The tool.
    pub tool: ToolSpec,
    /// Static obstacles.
    #[serde(default)]
    pub obstacles: Vec<ObstacleSpec>,
    /// Virtual coupling.
    #[serde(default)]
    pub coupling: CouplingSpec,
    /// Contacts.
    #[serde(default)]
    pub contact: ContactSpec,
    /// Rates.
    #[serde(default)]
    pub rates: RateSpec,
    /// The device.
    #[serde(default)]
    pub device: DeviceSpec,
}

impl Scene {
    /// Parses a scene from TOML text; relative mesh paths are resolved against `base_dir`.
    ///
    /// # Errors
    /// [`SceneError::Parse`] (the message names the field and line) or
    /// [`SceneError::Invalid`] naming the field.
    pub fn from_toml_str(text: &str, base_dir: &Path) -> Result<Self, SceneError> {
        let mut scene: Scene =
            toml::from_str(text).map_err(|e| SceneError::Parse(e.to_string()))?;
        let resolve = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = base_dir.join(&*p);
            }
        };
        resolve(&mut scene.tool.mesh);
        for o in &mut scene.obstacles {
            resolve(&mut o.mesh);
        }
        scene.validate()?;
        Ok(scene)
    }

    /// Reads a scene file.
    ///
    /// # Errors
    /// [`SceneError::Io`], and as [`Scene::from_toml_str`].
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let base = path.parent().unwrap_or_else(|| Path::new("."));
        Self::from_toml_str(&text, base)
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`SceneError::Invalid`] naming the first bad field.
    pub fn validate(&self) -> Result<(), SceneError> {
        let positive = |field: &str, v: Real| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(invalid(
                    field,
                    format!("must be positive and finite, got {v}"),
                ))
            }
        };
        let non_negative_opt = |field: &str, v: Option<Real>| match v {
            Some(v) if !(v.is_finite() && v >= 0.0) => Err(invalid(
                field,
                format!("must be non-negative and finite, got {v}"),
            )),
            _ => Ok(()),
        };
        positive("tool.scale_m_per_unit", self.tool.scale_m_per_unit)?;
        positive("tool.mass_kg", self.tool.mass_kg)?;
        self.tool.pose.validate("tool.pose")?;
        for (i, o) in self.obstacles.iter().enumerate() {
            positive(
                &format!("obstacles[{i}].scale_m_per_unit"),
                o.scale_m_per_unit,
            )?;
            o.pose.validate(&format!("obstacles[{i}].pose"))?;
        }
        positive(
            "coupling.stiffness_n_per_m",
            self.coupling.stiffness_n_per_m,
        )?;
        positive(
            "coupling.angular_stiffness_nm_per_rad",
            self.coupling.angular_stiffness_nm_per_rad,
        )?;
        non_negative_opt("coupling.damping_ns_per_m", self.coupling.damping_ns_per_m)?;
        non_negative_opt(
            "coupling.angular_damping_nms_per_rad",
            self.coupling.angular_damping_nms_per_rad,
        )?;
        positive("contact.stiffness_n_per_m", self.contact.stiffness_n_per_m)?;
        non_negative_opt("contact.damping_ns_per_m", self.contact.damping_ns_per_m)?;
        positive("contact.delta_m", self.contact.delta_m)?;
        let springs = if self.contact.torque_pairs { 2 } else { 1 };
        let most = haptic_core::MAX_REPRESENTATIVES / springs;
        if !(1..=most).contains(&self.contact.clusters) {
            return Err(invalid(
                "contact.clusters",
                format!(
                    "must be 1 to {most} (the representatives a linearized contact model holds, \
                     {springs} per cluster), got {}",
                    self.contact.clusters
                ),
            ));
        }
        if !(self.contact.error_threshold.is_finite() && self.contact.error_threshold >= 0.0) {
            return Err(invalid(
                "contact.error_threshold",
                "must be non-negative and finite",
            ));
        }
        positive("rates.haptic_hz", self.rates.haptic_hz)?;
        if !(1.0..=20_000.0).contains(&self.rates.haptic_hz) {
            return Err(invalid(
                "rates.haptic_hz",
                "must be between 1 Hz and 20 kHz",
            ));
        }
        if let Some(b) = self.contact.time_budget_s {
            positive("contact.time_budget_s", b)?;
        }
        if let Some(c) = self.rates.contact_hz {
            positive("rates.contact_hz", c)?;
        }
        let mut last = Real::NEG_INFINITY;
        for (i, w) in self.device.waypoints.iter().enumerate() {
            let field = format!("device.waypoints[{i}]");
            if !(w.time_s.is_finite() && w.time_s > last) {
                return Err(invalid(
                    format!("{field}.time_s"),
                    "times must be finite and increasing",
                ));
            }
            last = w.time_s;
            if w.position_m
                .iter()
                .chain(&w.rotation_axis_angle_rad)
                .any(|v| !v.is_finite())
            {
                return Err(invalid(field, "must be finite"));
            }
        }
        Ok(())
    }
}
