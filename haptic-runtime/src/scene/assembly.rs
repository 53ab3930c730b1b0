//! From a [`Scene`] to its parts: meshes loaded, the tool recentred, the parameters checked.

use haptic_core::{Pose, Real, Vec3};

use super::spec::{PoseSpec, Scene, SceneError, invalid};

/// Everything a scene describes, loaded and ready to compose into a pipeline.
#[derive(Debug, Clone)]
pub struct SceneParts {
    /// The tool's mass properties (uniform solid of the given mass).
    pub body: haptic_core::RigidBody,
    /// The tool mesh in its body frame (origin at the centre of mass), m.
    pub tool_mesh: haptic_collision::TriMesh,
    /// The translation from the tool mesh file's frame (scaled to metres) to its body frame:
    /// minus the centre of mass (m).
    pub tool_mesh_offset_m: Vec3,
    /// Initial pose of the tool's centre-of-mass frame.
    pub tool_pose: Pose,
    /// The obstacles, each with its pose.
    pub obstacles: Vec<(haptic_collision::TriMesh, Pose)>,
    /// Coupling parameters.
    pub coupling: haptic_dynamics::CouplingParams,
    /// Penalty parameters.
    pub penalty: haptic_dynamics::PenaltyParams,
    /// Pipeline configuration (rates, δ, K, threshold, linearization).
    pub config: crate::PipelineConfig,
    /// Contact rate in virtual time (Hz), if the scene fixes one.
    pub contact_hz: Option<Real>,
    /// The device's limits.
    pub limits: haptic_core::DeviceLimits,
    /// The simulated hand's target trajectory (handle poses).
    pub waypoints: Vec<haptic_device::Waypoint>,
    /// The stopping rule a multiresolution back-end built for the scene uses
    /// (`LodBackend::with_stopping_rule`; the scene's `contact.stopping_rule`).
    pub stopping_rule: haptic_collision::StoppingRule,
    /// What loading did to each mesh the scene names, by its field (`tool.mesh`,
    /// `obstacles[i].mesh`): degenerate and repeated triangles dropped, triangles wound against
    /// their neighbours turned ([`haptic_collision::LoadReport`]). Empty for meshes given in code.
    pub load_reports: Vec<(String, haptic_collision::LoadReport)>,
}

impl SceneParts {
    /// A [`haptic_device::HandDevice`] following the scene's waypoints with the default hand
    /// impedance.
    ///
    /// # Errors
    /// [`SceneError::Invalid`] (`device.waypoints`) if the trajectory is rejected.
    pub fn hand_device(&self) -> Result<haptic_device::HandDevice, SceneError> {
        let target =
            haptic_device::ScriptedDevice::from_waypoints(self.waypoints.clone(), self.limits)
                .map_err(|e| invalid("device.waypoints", e.to_string()))?;
        haptic_device::HandDevice::new(haptic_device::HandParams::default(), target, self.limits)
            .map_err(|e| invalid("device", e.to_string()))
    }
}

impl Scene {
    /// Loads the meshes and computes what the pipeline needs: the tool recentred on its centre
    /// of mass with the inertia of a uniform solid of `tool.mass_kg`, the obstacles, the
    /// parameters and the device's trajectory.
    ///
    /// # Errors
    /// [`SceneError::Invalid`] naming the field whose mesh or value is bad.
    pub fn assemble(&self) -> Result<SceneParts, SceneError> {
        use haptic_collision::{LoadOptions, TriMesh};
        self.validate()?;
        let options = |scale| LoadOptions {
            scale_m_per_unit: scale,
            ..LoadOptions::default()
        };
        let (mesh, report) = TriMesh::load(&self.tool.mesh, &options(self.tool.scale_m_per_unit))
            .map_err(|e| invalid("tool.mesh", e.to_string()))?;
        let mut load_reports = vec![("tool.mesh".to_owned(), report)];
        let mut obstacles = Vec::with_capacity(self.obstacles.len());
        for (i, o) in self.obstacles.iter().enumerate() {
            let field = format!("obstacles[{i}].mesh");
            let (m, report) = TriMesh::load(&o.mesh, &options(o.scale_m_per_unit))
                .map_err(|e| invalid(field.clone(), e.to_string()))?;
            obstacles.push(m);
            load_reports.push((field, report));
        }
        Ok(SceneParts {
            load_reports,
            ..self.assemble_meshes(mesh, obstacles)?
        })
    }

    /// [`Scene::assemble`] with the meshes given (in metres, already scaled) instead of read from
    /// the files the scene names: the tool mesh in its file's frame, one mesh per obstacle in the
    /// scene's order (posed by the scene). For scenes built in code.
    ///
    /// # Errors
    /// As [`Scene::assemble`]; [`SceneError::Invalid`] (`obstacles`) when the number of meshes
    /// is not the number of obstacles.
    pub fn assemble_meshes(
        &self,
        mesh: haptic_collision::TriMesh,
        obstacle_meshes: Vec<haptic_collision::TriMesh>,
    ) -> Result<SceneParts, SceneError> {
        self.validate()?;
        if obstacle_meshes.len() != self.obstacles.len() {
            return Err(invalid(
                "obstacles",
                format!(
                    "{} meshes given for {} obstacles",
                    obstacle_meshes.len(),
                    self.obstacles.len()
                ),
            ));
        }
        // Inertia is linear in density: compute at 1 kg/m³, then scale to the mass.
        let unit = mesh
            .mass_properties(1.0)
            .map_err(|e| invalid("tool.mesh", format!("no mass properties: {e}")))?;
        let density = self.tool.mass_kg / unit.volume_m3;
        let body = haptic_core::RigidBody::new(self.tool.mass_kg, unit.inertia_about_com * density)
            .map_err(|e| invalid("tool.mass_kg", e.to_string()))?;
        let tool_mesh = mesh
            .translated(&-unit.centre_of_mass_m)
            .map_err(|e| invalid("tool.mesh", e.to_string()))?;
        let obstacles: Vec<_> = obstacle_meshes
            .into_iter()
            .zip(&self.obstacles)
            .map(|(m, o)| (m, o.pose.pose()))
            .collect();
        let defaults = haptic_dynamics::CouplingParams::default();
        let coupling = haptic_dynamics::CouplingParams {
            stiffness_n_per_m: self.coupling.stiffness_n_per_m,
            damping_ns_per_m: self
                .coupling
                .damping_ns_per_m
                .unwrap_or(defaults.damping_ns_per_m),
            angular_stiffness_nm_per_rad: self.coupling.angular_stiffness_nm_per_rad,
            angular_damping_nms_per_rad: self
                .coupling
                .angular_damping_nms_per_rad
                .unwrap_or(defaults.angular_damping_nms_per_rad),
            saturation: None,
        };
        let penalty = haptic_dynamics::PenaltyParams::new(
            self.contact.stiffness_n_per_m,
            self.contact
                .damping_ns_per_m
                .unwrap_or(haptic_dynamics::PenaltyParams::default().damping_ns_per_m),
            self.contact.delta_m,
        )
        .map_err(|e| invalid("contact", e.to_string()))?;
        let query =
            haptic_core::QueryParams::new(self.contact.delta_m, self.contact.error_threshold)
                .map_err(|e| invalid("contact", e.to_string()))?;
        let config = crate::PipelineConfig {
            haptic_rate_hz: self.rates.haptic_hz,
            query,
            cluster: haptic_cluster::ClusterParams {
                max_clusters: self.contact.clusters,
                torque_pairs: self.contact.torque_pairs,
                ..Default::default()
            },
            linearization: self.contact.linearization(),
            query_budget: match self.contact.time_budget_s {
                Some(b) => Some(
                    crate::QueryBudget::new(b)
                        .map_err(|e| invalid("contact.time_budget_s", e.to_string()))?,
                ),
                None => None,
            },
            ..crate::PipelineConfig::default()
        };
        let tool_pose = self.tool.pose.pose();
        let mut waypoints: Vec<haptic_device::Waypoint> = self
            .device
            .waypoints
            .iter()
            .map(|w| {
                haptic_device::Waypoint::new(
                    w.time_s,
                    PoseSpec::new(w.position_m, w.rotation_axis_angle_rad).pose(),
                )
            })
            .collect();
        if waypoints.is_empty() {
            waypoints.push(haptic_device::Waypoint::new(0.0, tool_pose));
        }
        let centre = waypoints[0].pose.position;
        let half = Vec3::repeat(self.device.workspace_half_m);
        let limits = haptic_core::DeviceLimits::new(
            self.device.max_force_n,
            self.device.max_torque_nm,
            centre - half,
            centre + half,
            self.rates.haptic_hz,
        )
        .map_err(|e| invalid("device", e.to_string()))?;
        Ok(SceneParts {
            body,
            tool_mesh,
            tool_mesh_offset_m: -unit.centre_of_mass_m,
            tool_pose,
            obstacles,
            coupling,
            penalty,
            config,
            contact_hz: self.rates.contact_hz,
            limits,
            waypoints,
            stopping_rule: self.contact.stopping_rule,
            load_reports: Vec::new(),
        })
    }
}
