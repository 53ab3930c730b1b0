//! A collision back-end of your own: an analytic sphere against the floor `z = 0`, no meshes.
//!
//! It implements [`CollisionBackend`] from its contract alone (contacts within `δ`, normals out
//! of the tool, an error rather than a panic for a bad pose) and is driven through the whole
//! pipeline in virtual time: a simulated hand lowers the sphere onto the floor and presses it
//! 5 mm further; the penalty contact holds it.
//!
//! Run it with `cargo run -p haptic-runtime --example custom_backend`.

use haptic_core::{
    CollisionBackend, Contact, ContactSet, CoreError, DeviceLimits, Pose, QueryParams, QueryStats,
    Real, RigidBody, Vec3,
};
use haptic_device::{HandDevice, HandParams, ScriptedDevice, Waypoint};
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::{ContactLatency, PipelineBuilder};

/// A sphere of radius `radius_m` (the tool, centred on its centre of mass) over the floor `z = 0`.
struct SphereOnFloor {
    radius_m: Real,
}

impl CollisionBackend for SphereOnFloor {
    type Error = CoreError;

    fn name(&self) -> &str {
        "sphere-on-floor"
    }

    fn tool_bounding_radius_m(&self) -> Real {
        self.radius_m
    }

    fn query(
        &mut self,
        tool_pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, CoreError> {
        out.clear(); // reuse the caller's allocation
        if !tool_pose.is_finite() {
            return Err(CoreError::NonFinite { what: "tool pose" });
        }
        // Broad phase: the lowest point of the sphere, against δ.
        let depth_m = self.radius_m - tool_pose.position.z;
        if depth_m < -params.delta_m {
            return Ok(QueryStats::default());
        }
        // One contact: the sphere's lowest point, the floor point under it, the normal −z (out
        // of the tool, into the floor), the depth (positive inside, down to −δ outside).
        let n = -Vec3::z();
        let p_a = tool_pose.position + self.radius_m * n;
        let r_a = tool_pose.orientation.inverse() * (p_a - tool_pose.position);
        let p_b = Vec3::new(p_a.x, p_a.y, 0.0);
        out.push(Contact::new(p_a, r_a, p_b, n, depth_m)?);
        Ok(QueryStats {
            broad_phase_hit: true,
            node_pairs_tested: 1,
            primitive_pairs_tested: 1,
            ..QueryStats::default()
        })
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let radius_m = 0.02;
    let body = RigidBody::sphere(0.05, radius_m)?; // 50 g
    let above = Pose::from_position(Vec3::new(0.0, 0.0, radius_m + 0.01));
    let pressed = Pose::from_position(Vec3::new(0.0, 0.0, radius_m - 0.005));
    let limits = DeviceLimits::new(10.0, 1.0, Vec3::repeat(-0.5), Vec3::repeat(0.5), 1000.0)?;
    let target = ScriptedDevice::from_waypoints(
        vec![Waypoint::new(0.0, above), Waypoint::new(0.3, pressed)],
        limits,
    )?;
    let hand = HandDevice::new(HandParams::default(), target, limits)?;

    let mut pipeline = PipelineBuilder::new(body, above)
        .integrator(LinearizedBackwardEuler)
        .backend(SphereOnFloor { radius_m })
        .contact_model(PenaltyModel::new(PenaltyParams::default())?)
        .device(hand)
        .build()?;
    let summary =
        pipeline.run_virtual(1.0, ContactLatency::FixedRate { rate_hz: 500.0 }, |_, _| {})?;

    let height_m = pipeline.haptic().tool().x.z;
    println!(
        "sphere on the floor: centre {:.2} mm above it (radius {:.0} mm), deepest {:.3} mm, \
         largest force {:.2} N over {} contact updates",
        height_m * 1e3,
        radius_m * 1e3,
        summary.max_penetration_m * 1e3,
        summary.max_force_n,
        summary.contact_updates
    );
    // The hand presses 5 mm into the floor; the contact holds the sphere within a millimetre.
    assert!(summary.max_penetration_m < 1e-3 && height_m > radius_m - 1e-3);
    Ok(())
}
