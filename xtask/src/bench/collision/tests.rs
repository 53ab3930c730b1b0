//! The scenes `bench collision` loads from its arguments.

use super::load_scene;
use crate::bench::CollisionArgs;
use crate::common;

fn args(scene: &str, delta_mm: Option<f64>) -> CollisionArgs {
    CollisionArgs {
        scene: scene.to_owned(),
        scale: Some(1.0),
        delta_mm,
        suite: false,
        only: None,
        stopping_rule: haptic_collision::StoppingRule::default(),
    }
}

/// A pair of files takes `δ` from `--delta-mm` where it is given (1 % of the tool's diagonal
/// otherwise), and refuses a reach that is not a positive length; the built-in scenes keep the
/// paper's `δ` and refuse it.
#[test]
fn a_file_pairs_reach_is_the_one_given() -> anyhow::Result<()> {
    let meshes = common::meshes_dir();
    let pair = format!(
        "{},{}",
        meshes.join("basemesh_fork.stl").display(),
        meshes.join("basemesh_mug.stl").display()
    );
    let given = load_scene(&args(&pair, Some(0.5)), 4)?;
    assert_eq!(given.delta_m, 0.5e-3);
    let (lo, hi) = given.tool.bounding_box();
    let default = load_scene(&args(&pair, None), 4)?;
    assert!((default.delta_m - 0.01 * (hi - lo).norm()).abs() < 1e-15);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let err = load_scene(&args(&pair, Some(bad)), 4).err();
        assert!(
            err.is_some_and(|e| e.to_string().contains("positive length")),
            "{bad}"
        );
    }
    assert!(load_scene(&args("jaws", Some(1.0)), 4).is_err());
    Ok(())
}
