//! The typestate builder: each of the four parts set once, `build` only when all are.

use haptic_cluster::Clusterer;
use haptic_core::{CollisionBackend, ContactModel, Device, Integrator, Pose, RigidBody, ToolState};
use haptic_dynamics::coupling::{CouplingParams, Grasp, VirtualCoupling};
use haptic_dynamics::forces::HapticForces;

use crate::error::RuntimeError;
use crate::stages::{ContactStage, HapticStage};
use crate::telemetry::LiveTelemetry;

use super::{Pipeline, PipelineConfig};

/// A typestate builder: each part is set once, and `build` exists only when all four are.
pub struct PipelineBuilder<I, B, C, D> {
    common: Common,
    integrator: I,
    backend: B,
    contact_model: C,
    device: D,
}

/// What the builder holds whatever its parts are.
struct Common {
    body: RigidBody,
    tool_pose: Pose,
    coupling: CouplingParams,
    config: PipelineConfig,
}

impl PipelineBuilder<(), (), (), ()> {
    /// Starts a pipeline for a tool of mass properties `body` whose centre-of-mass frame starts at
    /// `tool_pose`; it is grasped where the device handle is at the first reading.
    pub fn new(body: RigidBody, tool_pose: Pose) -> Self {
        Self {
            common: Common {
                body,
                tool_pose,
                coupling: CouplingParams::default(),
                config: PipelineConfig::default(),
            },
            integrator: (),
            backend: (),
            contact_model: (),
            device: (),
        }
    }
}

impl<I, B, C, D> PipelineBuilder<I, B, C, D> {
    /// The integrator.
    pub fn integrator<I2: Integrator>(self, integrator: I2) -> PipelineBuilder<I2, B, C, D> {
        PipelineBuilder {
            common: self.common,
            integrator,
            backend: self.backend,
            contact_model: self.contact_model,
            device: self.device,
        }
    }

    /// The collision back-end.
    pub fn backend<B2: CollisionBackend>(self, backend: B2) -> PipelineBuilder<I, B2, C, D> {
        PipelineBuilder {
            common: self.common,
            integrator: self.integrator,
            backend,
            contact_model: self.contact_model,
            device: self.device,
        }
    }

    /// The contact model (applied to cluster representatives).
    pub fn contact_model<C2: ContactModel>(
        self,
        contact_model: C2,
    ) -> PipelineBuilder<I, B, C2, D> {
        PipelineBuilder {
            common: self.common,
            integrator: self.integrator,
            backend: self.backend,
            contact_model,
            device: self.device,
        }
    }

    /// The device.
    pub fn device<D2: Device>(self, device: D2) -> PipelineBuilder<I, B, C, D2> {
        PipelineBuilder {
            common: self.common,
            integrator: self.integrator,
            backend: self.backend,
            contact_model: self.contact_model,
            device,
        }
    }

    /// The virtual coupling parameters.
    pub fn coupling(mut self, coupling: CouplingParams) -> Self {
        self.common.coupling = coupling;
        self
    }

    /// Rates, tolerances and switches.
    pub fn config(mut self, config: PipelineConfig) -> Self {
        self.common.config = config;
        self
    }
}

impl<I: Integrator, B: CollisionBackend, C: ContactModel, D: Device> PipelineBuilder<I, B, C, D> {
    /// Reads the device once, grasps the tool, and assembles the pipeline.
    ///
    /// # Errors
    /// [`RuntimeError::Config`] for a bad configuration, [`RuntimeError::Device`] if the first
    /// reading fails, [`RuntimeError::NonFiniteFirstReading`] or [`RuntimeError::Grasp`] if the grasp cannot be
    /// made.
    pub fn build(mut self) -> Result<Pipeline<I, B, C, D>, RuntimeError> {
        let Common {
            body,
            tool_pose,
            coupling,
            config,
        } = self.common;
        config.validate()?;
        let first = self.device.read(0.0).map_err(|e| RuntimeError::Device {
            kind: haptic_core::device::Error::kind(&e),
            message: e.to_string(),
            summary: Box::default(),
        })?;
        if !first.is_finite() {
            return Err(RuntimeError::NonFiniteFirstReading);
        }
        let tool = ToolState::at_rest(&tool_pose);
        let grasp = Grasp::new(&tool, &first.pose)?;
        let coupling = VirtualCoupling::new(coupling, grasp, &first)?;
        let forces = HapticForces {
            coupling,
            contact: haptic_core::LinearizedContact::none(),
            previous_contact: haptic_core::LinearizedContact::none(),
            blend: 1.0,
            mode: config.linearization,
            jacobian_kind: haptic_core::Integrator::jacobian_kind(&self.integrator),
            gravity: config.gravity,
        };
        if config.cluster.max_representatives() > haptic_core::MAX_REPRESENTATIVES {
            return Err(RuntimeError::config(
                "cluster",
                format!(
                    "max_clusters {} gives up to {} representatives (torque pairs: {}), more \
                     than a linearized contact model holds ({})",
                    config.cluster.max_clusters,
                    config.cluster.max_representatives(),
                    config.cluster.torque_pairs,
                    haptic_core::MAX_REPRESENTATIVES
                ),
            ));
        }
        let clusterer = Clusterer::new(config.cluster)
            .map_err(|e| RuntimeError::config("cluster", e.to_string()))?;
        Ok(Pipeline {
            haptic: HapticStage::new(
                self.integrator,
                self.device,
                body,
                forces,
                tool,
                config.safety,
            ),
            contact: ContactStage::new(
                self.backend,
                self.contact_model,
                clusterer,
                body,
                config.query,
            )
            .with_budget(config.query_budget),
            config,
            live: std::sync::Arc::new(LiveTelemetry::default()),
        })
    }
}
