//! The pipeline assembled in code from its four parts, without a scene file: the spoon and the
//! cup from `assets/meshes`, the native multiresolution back-end, the penalty model on clustered
//! contacts, full-Newton backward Euler, and a simulated hand that lowers the spoon into the cup
//! and presses it against the wall. What `xtask/scenes/spoon-cup.toml` describes, written out.
//!
//! Run it with `cargo run -p haptic-runtime --example pipeline_from_parts`.

use std::f64::consts::PI;
use std::path::PathBuf;

use haptic_cluster::ClusterParams;
use haptic_collision::{LoadOptions, LodBackend, TriMesh};
use haptic_core::{DeviceLimits, Pose, QueryParams, RigidBody, Vec3};
use haptic_device::{HandDevice, HandParams, ScriptedDevice, Waypoint};
use haptic_dynamics::{CouplingParams, NewtonBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::{ContactLatency, PipelineBuilder, PipelineConfig};
use nalgebra::UnitQuaternion;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let meshes = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/meshes");

    // 1. The tool: its mesh recentred on its centre of mass, with the inertia of a uniform 20 g
    //    solid (inertia is linear in density: compute at 1 kg/m³, then scale).
    let (spoon, _) = TriMesh::load(meshes.join("newell_teaspoon.stl"), &LoadOptions::default())?;
    let unit = spoon.mass_properties(1.0)?;
    let mass_kg = 0.02;
    let body = RigidBody::new(mass_kg, unit.inertia_about_com * (mass_kg / unit.volume_m3))?;
    let spoon = spoon.translated(&-unit.centre_of_mass_m)?;
    let (cup, _) = TriMesh::load(meshes.join("newell_teacup.stl"), &LoadOptions::default())?;

    // 2. The collision back-end: the tool against the cup standing at the origin.
    let backend = LodBackend::new(&spoon, &[(cup, Pose::identity())])?;

    // 3. The device: a simulated hand following waypoints (bowl down, into the cup, sideways).
    let bowl_down = UnitQuaternion::from_axis_angle(&Vec3::x_axis(), PI);
    let at = |x: f64, y: f64| Pose {
        position: Vec3::new(x, y, 0.0),
        orientation: bowl_down,
    };
    let limits = DeviceLimits::new(10.0, 1.0, Vec3::repeat(-0.3), Vec3::repeat(0.3), 1000.0)?;
    let target = ScriptedDevice::from_waypoints(
        vec![
            Waypoint::new(0.0, at(0.0, 0.185)),
            Waypoint::new(1.0, at(0.0, 0.115)),
            Waypoint::new(2.0, at(0.035, 0.115)),
        ],
        limits,
    )?;
    let hand = HandDevice::new(HandParams::default(), target, limits)?;

    // 4. The integrator and the contact model, and the pipeline's settings.
    let delta_m = 1e-3;
    let config = PipelineConfig {
        query: QueryParams::new(delta_m, 0.0)?,
        cluster: ClusterParams {
            max_clusters: 5,
            ..ClusterParams::default()
        },
        ..PipelineConfig::default()
    };
    let mut pipeline = PipelineBuilder::new(body, at(0.0, 0.185))
        .integrator(NewtonBackwardEuler::default())
        .backend(backend)
        .contact_model(PenaltyModel::new(PenaltyParams::new(
            2000.0, 2.0, delta_m,
        )?)?)
        .device(hand)
        .coupling(CouplingParams::default())
        .config(config)
        .build()?;

    let summary =
        pipeline.run_virtual(2.5, ContactLatency::FixedRate { rate_hz: 250.0 }, |_, _| {})?;
    println!(
        "spoon into cup, {:.1} s in virtual time: {} contact updates, up to {} raw contacts in {} \
         clusters, deepest {:.3} mm, largest force {:.2} N, {} zero-force steps",
        summary.duration_s,
        summary.contact_updates,
        summary.raw_contact_count_max,
        summary.cluster_count_max,
        summary.max_penetration_m * 1e3,
        summary.max_force_n,
        summary.zero_force_steps
    );
    assert!(
        summary.cluster_count_max > 0,
        "the spoon should have touched the cup"
    );
    Ok(())
}
