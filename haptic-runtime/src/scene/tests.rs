//! Scene parsing, validation and assembly.

use std::path::Path;

use super::*;

const MINIMAL: &str = r#"
    [tool]
    mesh = "tool.stl"
    mass_kg = 0.01
"#;

#[test]
fn minimal_scene_takes_defaults_and_resolves_paths() {
    let base = Path::new("my").join("scenes");
    let s = Scene::from_toml_str(MINIMAL, &base).unwrap();
    assert_eq!(s.tool.mesh, base.join("tool.stl"));
    assert_eq!(s.contact.clusters, 5);
    assert!(s.contact.torque_pairs);
    assert_eq!(s.rates.haptic_hz, 1000.0);
}

#[test]
fn the_contact_model_between_updates_is_fixed_frames_unless_asked() {
    use haptic_core::LinearizationMode::{Constant, FixedFrames, Linearized};
    let with = |contact: &str| {
        let text = format!("{MINIMAL}\n[contact]\n{contact}\n");
        Scene::from_toml_str(&text, Path::new("."))
            .unwrap()
            .contact
            .linearization()
    };
    assert_eq!(with(""), FixedFrames);
    assert_eq!(with("fixed_frames = false"), Linearized);
    assert_eq!(with("linearized = false"), Constant);
    assert_eq!(with("linearized = false\nfixed_frames = false"), Constant);
    assert_eq!(crate::PipelineConfig::default().linearization, FixedFrames);
}

#[test]
fn the_stopping_rule_is_the_budgeted_one_unless_asked() {
    use haptic_collision::StoppingRule::{CoherenceBudget, Deviation, DeviationAndCoherence};
    let with = |contact: &str| {
        let text = format!("{MINIMAL}\n[contact]\n{contact}\n");
        Scene::from_toml_str(&text, Path::new(".")).map(|s| s.contact.stopping_rule)
    };
    assert_eq!(with("").unwrap(), CoherenceBudget);
    assert_eq!(
        with("stopping_rule = \"coherence-budget\"").unwrap(),
        CoherenceBudget
    );
    assert_eq!(with("stopping_rule = \"deviation\"").unwrap(), Deviation);
    assert_eq!(
        with("stopping_rule = \"coherence\"").unwrap(),
        DeviationAndCoherence
    );
    match with("stopping_rule = \"normals\"") {
        Err(SceneError::Parse(m)) => assert!(m.contains("stopping_rule"), "{m}"),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn unknown_field_is_named() {
    let text = "[tool]\nmesh = \"a.stl\"\nmass_kg = 0.01\nmass_g = 3\n";
    match Scene::from_toml_str(text, Path::new(".")) {
        Err(SceneError::Parse(m)) => assert!(m.contains("mass_g"), "{m}"),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn wrong_type_is_named() {
    let text = "[tool]\nmesh = \"a.stl\"\nmass_kg = \"heavy\"\n";
    match Scene::from_toml_str(text, Path::new(".")) {
        Err(SceneError::Parse(m)) => assert!(m.contains("mass_kg"), "{m}"),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn missing_field_is_named() {
    match Scene::from_toml_str("[tool]\nmesh = \"a.stl\"\n", Path::new(".")) {
        Err(SceneError::Parse(m)) => assert!(m.contains("mass_kg"), "{m}"),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn out_of_range_values_name_their_field() {
    let cases = [
        ("[tool]\nmesh = \"a\"\nmass_kg = -1.0\n", "tool.mass_kg"),
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[contact]\nclusters = 0\n",
            "contact.clusters",
        ),
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[contact]\nclusters = 17\n",
            "contact.clusters",
        ),
        // Torque pairs (the default) write two springs per cluster: at most 8 clusters.
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[contact]\nclusters = 9\n",
            "contact.clusters",
        ),
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[contact]\nclusters = 17\ntorque_pairs = false\n",
            "contact.clusters",
        ),
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[contact]\ndelta_m = 0.0\n",
            "contact.delta_m",
        ),
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[rates]\nhaptic_hz = 50000.0\n",
            "rates.haptic_hz",
        ),
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[[obstacles]]\nmesh = \"b\"\nscale_m_per_unit = 0.0\n",
            "obstacles[0].scale_m_per_unit",
        ),
        (
            "[tool]\nmesh = \"a\"\nmass_kg = 1.0\n[[device.waypoints]]\ntime_s = 1.0\nposition_m = [0,0,0]\n[[device.waypoints]]\ntime_s = 0.5\nposition_m = [0,0,0]\n",
            "device.waypoints[1].time_s",
        ),
    ];
    for (text, field) in cases {
        match Scene::from_toml_str(text, Path::new(".")) {
            Err(SceneError::Invalid { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: expected Invalid, got {other:?}"),
        }
    }
}

#[test]
fn unreadable_file_is_an_io_error() {
    assert!(matches!(
        Scene::load(&std::env::temp_dir().join("haptic-no-such-folder/scene.toml")),
        Err(SceneError::Io { .. })
    ));
}
