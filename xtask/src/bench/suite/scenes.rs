//! The generalization suite's scenes (`suite.rs` measures them): the repository's mesh pairs
//! with their pose paths, the remeshed peg, and the generated pairs at two tessellations.

use haptic_collision::{DegeneratePolicy, LoadOptions, TriMesh};
use haptic_core::{Pose, Real, Vec3};
use nalgebra::UnitQuaternion;

use super::super::collision::{self, Scene};
use super::super::shapes;
use crate::common;

/// A suite scene, and which tessellation of which generated shape it is.
pub(super) struct Entry {
    pub(super) scene: Scene,
    /// The generated shape's name and this tessellation's density; `None` for file meshes.
    pub(super) family: Option<(&'static str, usize)>,
}

/// A mesh moved by `pose` (its vertices rewritten).
fn posed(mesh: &TriMesh, pose: &Pose) -> anyhow::Result<TriMesh> {
    let vertices = mesh
        .vertices()
        .iter()
        .map(|v| pose.orientation * v + pose.position)
        .collect();
    Ok(TriMesh::new(
        vertices,
        mesh.triangles().to_vec(),
        DegeneratePolicy::Reject,
    )?
    .0)
}

/// A tool mesh moved to its body frame (origin at its centre of mass), and that centre in the
/// mesh's frame (m).
fn body_frame(mesh: TriMesh) -> anyhow::Result<(TriMesh, Vec3)> {
    let com = mesh.mass_properties(1000.0)?.centre_of_mass_m;
    Ok((mesh.translated(&-com)?, com))
}

/// `poses` of a tool whose body frame is at `com` (in its mesh's frame), as poses of a copy of
/// it whose body frame is at `copy_com`: the same placements of the shape, each moved by the
/// difference turned with the tool.
fn same_placements(poses: &[Pose], com: Vec3, copy_com: Vec3) -> Vec<Pose> {
    let shift = copy_com - com;
    poses
        .iter()
        .map(|pose| Pose {
            position: pose.position + pose.orientation * shift,
            orientation: pose.orientation,
        })
        .collect()
}

/// `n` poses around `centre` (the tool's centre of mass at rest): orientation `turn(s)` and
/// offset `offset(s)` for `s` once around the circle.
fn path(
    n: usize,
    centre: Vec3,
    offset: impl Fn(Real) -> Vec3,
    turn: impl Fn(Real) -> UnitQuaternion<Real>,
) -> Vec<Pose> {
    (0..n)
        .map(|i| {
            let s = i as Real / n as Real * std::f64::consts::TAU;
            Pose {
                position: centre + offset(s),
                orientation: turn(s),
            }
        })
        .collect()
}

/// `n` poses of a round peg along z in its hole around `centre`: sliding ±1 mm along its axis
/// and ±0.03 mm sideways, rocking by 0.1°.
fn peg_path(n: usize, centre: Vec3) -> Vec<Pose> {
    path(
        n,
        centre,
        |s| {
            Vec3::new(
                3e-5 * s.cos(),
                3e-5 * (2.0 * s).sin(),
                1e-3 * (3.0 * s).sin(),
            )
        },
        |s| {
            UnitQuaternion::from_scaled_axis(Vec3::new(s.cos(), s.sin(), 0.0) * 0.1f64.to_radians())
        },
    )
}

pub(super) fn file_scene(name: &str, n: usize) -> anyhow::Result<Entry> {
    let args = super::super::CollisionArgs {
        scene: name.to_owned(),
        scale: None,
        delta_mm: None,
        suite: false,
        only: None,
        stopping_rule: haptic_collision::StoppingRule::default(),
    };
    Ok(Entry {
        scene: collision::load_scene(&args, n)?,
        family: None,
    })
}

/// The round peg 4 mm into its hole, rocking by 0.1°, sliding ±1 mm along its axis and ±0.03 mm
/// sideways (the radial clearance is 0.05 mm): as in the repository (`peg-in-hole`), and
/// remeshed on the same poses (`peg-in-hole-remeshed`: the peg's triangles split at their
/// edges' midpoints, the hole's at their centroids), the repository's mesh against the same
/// surface tessellated otherwise.
pub(super) fn peg_in_hole(n: usize) -> anyhow::Result<Vec<Entry>> {
    let meshes = common::meshes_dir();
    let (peg, _) = TriMesh::load(
        meshes.join("factory_round_peg_8mm_tight.stl"),
        &LoadOptions::with_scale(1.0),
    )?;
    let (hole, _) = TriMesh::load(
        meshes.join("factory_round_hole_8mm.stl"),
        &LoadOptions::with_scale(1.0),
    )?;
    let (tool, com) = body_frame(peg.clone())?;
    let (lo, hi) = hole.bounding_box();
    let (plo, _) = tool.bounding_box();
    let centre = Vec3::new(
        0.5 * (lo.x + hi.x),
        0.5 * (lo.y + hi.y),
        hi.z - 4e-3 - plo.z,
    );
    let poses = peg_path(n, centre);
    let words = "NVIDIA Factory round peg (8 mm, tool) 4 mm into its 8.1 mm hole, rocking 0.1°, sliding ±1 mm axially and ±0.03 mm sideways";
    let (fine_tool, fine_com) = body_frame(shapes::split_at_midpoints(&peg)?)?;
    let fine_hole = shapes::split_at_centroids(&hole)?;
    let fine_poses = same_placements(&poses, com, fine_com);
    let scene = |name: &str, description: String, tool, obstacle, poses| Scene {
        name: name.into(),
        description,
        tool,
        obstacle,
        poses,
        delta_m: 5e-4,
        k_c: 2000.0,
    };
    let fine_words = format!(
        "{words}; remeshed: the peg's triangles split at their edges' midpoints, the hole's at their centroids ({} + {} triangles)",
        fine_tool.triangles().len(),
        fine_hole.triangles().len()
    );
    Ok(vec![
        Entry {
            scene: scene("peg-in-hole", words.into(), tool, hole, poses),
            family: Some(("peg-in-hole", 1)),
        },
        Entry {
            scene: scene(
                "peg-in-hole-remeshed",
                fine_words,
                fine_tool,
                fine_hole,
                fine_poses,
            ),
            family: Some(("peg-in-hole", 2)),
        },
    ])
}

/// A basemesh utensil lowered into the mug (axis +y), tilted 20°, until it touches.
pub(super) fn utensil_in_mug(utensil: &str, n: usize) -> anyhow::Result<Entry> {
    let meshes = common::meshes_dir();
    let (tool, _) = collision::load_tool(&meshes.join(format!("basemesh_{utensil}.stl")), 1.0)?;
    let (mug, _) = TriMesh::load(
        meshes.join("basemesh_mug.stl"),
        &LoadOptions::with_scale(1.0),
    )?;
    let tilt = UnitQuaternion::from_scaled_axis(Vec3::z() * 0.35);
    let delta = 1e-3;
    let poses = collision::approach_poses(&tool, &mug, tilt, Vec3::y(), delta, n)?;
    Ok(Entry {
        scene: Scene {
            name: format!("{utensil}-in-mug"),
            description: format!(
                "basemesh {utensil} (tool) lowered tilted 20° into the basemesh mug until it touches, then moved around that pose"
            ),
            tool,
            obstacle: mug,
            poses,
            delta_m: delta,
            k_c: 2000.0,
        },
        family: None,
    })
}

/// The basemesh fork lowered flat onto the outside of the Newell teacup's wall (the cup's axis
/// along y), until it touches: a few small contacts where the tines and the handle cross a
/// curved wall, at coarse levels fewer contacts than the clusters (the clustered force must not
/// count them).
pub(super) fn fork_on_cup(n: usize) -> anyhow::Result<Entry> {
    fork_lowered_onto(
        "fork-on-cup",
        "newell_teacup.stl",
        1.0,
        1e-3,
        "basemesh fork (tool) lowered flat onto the outside of the Newell teacup's wall until it touches, then moved around that pose",
        n,
    )
}

/// The basemesh fork lowered flat onto the back of Keenan Crane's cow "Spot", scaled to
/// 8.5 cm, with `δ` = 2 mm (about 1 % of the fork's diagonal, as `bench collision --scene A,B`
/// takes it): a smooth organic obstacle smaller than the tool, whose triangles (about 1.5 mm)
/// are smaller than `δ` and whose back is curved on that scale, crossed steeply by the tines
/// as the tool goes in by up to `δ`. (At `δ` = 1 mm the same poses hold every goal.)
pub(super) fn fork_on_spot(n: usize) -> anyhow::Result<Entry> {
    fork_lowered_onto(
        "fork-on-spot",
        "spot_keenan_5856.stl",
        0.05,
        2e-3,
        "basemesh fork (tool, 18 cm) lowered flat onto the back of Keenan Crane's Spot scaled to 8.5 cm until it touches, then moved around that pose",
        n,
    )
}

/// Keenan Crane's cow "Spot" (tool), scaled to 8.5 cm, lowered upright onto a bowl it cannot
/// enter (hemispherical shells of 30 and 26 mm with a flat rim between them, 48 segments:
/// `shapes::socket`) until its feet touch the rim, then moved around that pose, `δ` = 1.3 mm
/// (1 % of the cow's diagonal): the rim is flat but not convex, and its coarse pieces (convex
/// hulls of a few of its segments) overhang the bowl's opening, where the feet lie in part
/// (`lod/overhang.rs`; 0.097 / 0.332 at 2.5 % on 64 segments before the overhang was measured,
/// probes 39 and 40).
pub(super) fn spot_on_bowl(n: usize) -> anyhow::Result<Entry> {
    let delta = 1.3e-3;
    let meshes = common::meshes_dir();
    let (tool, _) = collision::load_tool(&meshes.join("spot_keenan_5856.stl"), 0.05)?;
    let bowl = shapes::socket(0.026, 0.03, 1)?;
    let poses = collision::approach_poses(
        &tool,
        &bowl,
        UnitQuaternion::identity(),
        Vec3::z(),
        delta,
        n,
    )?;
    Ok(Entry {
        scene: Scene {
            name: "spot-on-bowl".into(),
            description: "Keenan Crane's Spot (tool, 8.5 cm) lowered upright onto a bowl it cannot enter (shells of 30 and 26 mm, a flat rim between them, 48 segments) until its feet touch the rim, then moved around that pose".into(),
            tool,
            obstacle: bowl,
            poses,
            delta_m: delta,
            k_c: 2000.0,
        },
        family: None,
    })
}

/// The basemesh fork lowered flat (along −z, unturned) onto the repository mesh `obstacle`
/// loaded at `scale` (metres per file unit) until it touches, then moved around that pose
/// (`collision::approach_poses`), with the penalty reaching `delta_m`.
fn fork_lowered_onto(
    name: &str,
    obstacle: &str,
    scale: Real,
    delta_m: Real,
    description: &str,
    n: usize,
) -> anyhow::Result<Entry> {
    let meshes = common::meshes_dir();
    let (tool, _) = collision::load_tool(&meshes.join("basemesh_fork.stl"), 1.0)?;
    let (obstacle, _) = TriMesh::load(meshes.join(obstacle), &LoadOptions::with_scale(scale))?;
    let poses = collision::approach_poses(
        &tool,
        &obstacle,
        UnitQuaternion::identity(),
        Vec3::z(),
        delta_m,
        n,
    )?;
    Ok(Entry {
        scene: Scene {
            name: name.into(),
            description: description.into(),
            tool,
            obstacle,
            poses,
            delta_m,
            k_c: 2000.0,
        },
        family: None,
    })
}

/// A generated pair at two densities on the same poses: `make(density)` gives the tool (in its
/// own frame), the obstacle (placed) and the scene's words; `poses(tool in its body frame,
/// obstacle, centre of mass, n)` the poses, taken from the coarse tessellation.
fn generated(
    name: &'static str,
    n: usize,
    delta_m: Real,
    make: impl Fn(usize) -> anyhow::Result<(TriMesh, TriMesh, String)>,
    poses: impl Fn(&TriMesh, &TriMesh, Vec3, usize) -> anyhow::Result<Vec<Pose>>,
) -> anyhow::Result<Vec<Entry>> {
    let mut out = Vec::new();
    let mut shared: Option<(Vec<Pose>, Vec3)> = None;
    for density in [1, 2] {
        let (tool, obstacle, words) = make(density)?;
        let (tool, com) = body_frame(tool)?;
        let poses = match &shared {
            // The fine tool's body frame differs from the coarse one's by its centre of mass:
            // the same placements of the shape, moved by that difference.
            Some((p, coarse_com)) => same_placements(p, *coarse_com, com),
            None => {
                let p = poses(&tool, &obstacle, com, n)?;
                shared = Some((p.clone(), com));
                p
            }
        };
        out.push(Entry {
            scene: Scene {
                name: format!("{name}-{}", if density == 1 { "coarse" } else { "fine" }),
                description: format!(
                    "{words}; density {density} ({} + {} triangles)",
                    tool.triangles().len(),
                    obstacle.triangles().len()
                ),
                tool,
                obstacle,
                poses,
                delta_m,
                k_c: 2000.0,
            },
            family: Some((name, density)),
        });
    }
    Ok(out)
}

pub(super) fn boxes(n: usize) -> anyhow::Result<Vec<Entry>> {
    generated(
        "boxes",
        n,
        5e-4,
        |d| {
            Ok((
                shapes::box_mesh(Vec3::repeat(0.01), d)?,
                shapes::box_mesh(Vec3::new(0.03, 0.03, 0.005), d)?,
                "a 2 cm cube (tool) face-on-face on a 6 × 6 × 1 cm slab, lowered until it touches, then moved around that pose".into(),
            ))
        },
        |tool, obstacle, _, n| {
            collision::approach_poses(
                tool,
                obstacle,
                UnitQuaternion::identity(),
                Vec3::z(),
                5e-4,
                n,
            )
        },
    )
}

pub(super) fn gears(n: usize) -> anyhow::Result<Vec<Entry>> {
    generated(
        "gears",
        n,
        1e-3,
        |d| {
            let (a, b, centre, angle) = shapes::gear_pair(20, 35, 1e-3, 0.01, 1.9e-4, d)?;
            let place = Pose {
                position: centre,
                orientation: UnitQuaternion::from_scaled_axis(Vec3::z() * angle),
            };
            Ok((
                a,
                posed(&b, &place)?,
                "spur gears in mesh (20 teeth, tool, and 35 teeth; module 1 mm, 10 mm wide, 0.19 mm extra centre distance), the small gear rocking ±0.15° within its backlash, sliding ±1 mm along its axis and ±0.03 mm in its plane".into(),
            ))
        },
        |_, _, com, n| {
            Ok(path(
                n,
                com,
                |s| {
                    Vec3::new(
                        3e-5 * (2.0 * s).sin(),
                        3e-5 * s.cos(),
                        1e-3 * (3.0 * s).sin(),
                    )
                },
                |s| UnitQuaternion::from_scaled_axis(Vec3::z() * 0.15f64.to_radians() * s.sin()),
            ))
        },
    )
}

pub(super) fn bolt_and_nut(n: usize) -> anyhow::Result<Vec<Entry>> {
    const PITCH: Real = 1.25e-3;
    generated(
        "bolt-nut",
        n,
        5e-4,
        |d| {
            let rod = shapes::threaded_rod(4e-3, 3.2e-3, PITCH, 0.02, d)?;
            let nut = shapes::threaded_nut(4e-3, 3.2e-3, PITCH, 8e-3, 7e-3, 1e-4, d)?;
            // Five pitches up the rod: its thread still meets the nut's.
            let nut = nut.translated(&Vec3::new(0.0, 0.0, 5.0 * PITCH))?;
            Ok((
                rod,
                nut,
                "an M8-like threaded rod (tool; pitch 1.25 mm, 20 mm) turned one full turn in its nut (8 mm, 0.1 mm radial clearance), advancing a pitch, ±0.05 mm off its axis".into(),
            ))
        },
        |_, _, com, n| {
            Ok(path(
                n,
                com,
                |s| {
                    Vec3::new(
                        5e-5 * (3.0 * s).cos(),
                        5e-5 * (2.0 * s).sin(),
                        PITCH * s / std::f64::consts::TAU,
                    )
                },
                |s| UnitQuaternion::from_scaled_axis(Vec3::z() * s),
            ))
        },
    )
}

/// A round peg (8 mm) in a bushing 0.1 mm wider, their walls tessellated so that they line up
/// nowhere: sliding ±1 mm along the axis, ±0.03 mm sideways, rocking by 0.1°.
pub(super) fn peg_in_bushing(n: usize) -> anyhow::Result<Vec<Entry>> {
    const LENGTH: Real = 0.01;
    generated(
        "peg-bushing",
        n,
        5e-4,
        |d| {
            Ok((
                shapes::round_peg(4e-3, 0.6 * LENGTH, d)?,
                shapes::bushing(4.05e-3, 7e-3, LENGTH, d)?,
                "a round peg (tool; 8 mm, 6 mm long, 40 sides) in a bushing 0.1 mm wider (33 sides, 10 mm long), sliding ±1 mm along its axis, ±0.03 mm sideways, rocking by 0.1°".into(),
            ))
        },
        |_, _, _, n| Ok(peg_path(n, Vec3::new(0.0, 0.0, 0.5 * LENGTH))),
    )
}

/// A ball (20 mm) in a spherical socket 0.2 mm wider (a ball joint): pressed into the bottom
/// of the socket by up to 0.25 mm and lifted 0.05 mm off it, ±0.05 mm sideways, swivelling
/// about a tilted axis by up to 30°, so that its facets slide over the socket's.
pub(super) fn ball_in_socket(n: usize) -> anyhow::Result<Vec<Entry>> {
    const RADIUS: Real = 0.01;
    const CLEARANCE: Real = 2e-4;
    generated(
        "ball-socket",
        n,
        5e-4,
        |d| {
            Ok((
                shapes::ball(RADIUS, d)?,
                shapes::socket(RADIUS + CLEARANCE, 0.013, d)?,
                "a ball (tool; 20 mm) in a hemispherical socket 0.2 mm wider, pressed into its bottom by up to 0.25 mm, ±0.05 mm sideways, swivelling by up to 30°".into(),
            ))
        },
        |_, _, com, n| {
            Ok(path(
                n,
                com - Vec3::z() * CLEARANCE,
                |s| {
                    Vec3::new(
                        5e-5 * s.cos(),
                        5e-5 * (2.0 * s).sin(),
                        -1e-4 - 1.5e-4 * (3.0 * s).sin(),
                    )
                },
                |s| {
                    UnitQuaternion::from_scaled_axis(
                        Vec3::new(s.cos(), s.sin(), 0.5) * 0.5 * s.sin(),
                    )
                },
            ))
        },
    )
}

/// A ring (24 mm across its tube's centre line, tube 6 mm) seated on a cone (40 mm across its
/// base, 40 mm tall), a valve on its seat: a line contact all around, whose sideways pushes
/// cancel. Lowered by up to 0.3 mm past the smooth surfaces' seat and lifted 0.1 mm off it,
/// ±0.1 mm sideways, rocking by 1°.
pub(super) fn ring_on_cone(n: usize) -> anyhow::Result<Vec<Entry>> {
    const RING: Real = 0.012;
    const TUBE: Real = 0.003;
    const BASE: Real = 0.02;
    const HEIGHT: Real = 0.04;
    // Where the smooth tube touches the smooth cone's side `r = BASE (1 − z / HEIGHT)`: its
    // centre circle `TUBE` from that line.
    let seat = HEIGHT / BASE * (BASE - RING - TUBE * (1.0 + (BASE / HEIGHT).powi(2)).sqrt());
    generated(
        "ring-cone",
        n,
        5e-4,
        |d| {
            Ok((
                shapes::ring(RING, TUBE, d)?,
                shapes::cone(BASE, HEIGHT, d)?,
                "a ring (tool; 24 mm, tube 6 mm) seated on a cone (40 mm base, 40 mm tall), lowered by up to 0.3 mm past its seat, ±0.1 mm sideways, rocking by 1°".into(),
            ))
        },
        move |_, _, com, n| {
            Ok(path(
                n,
                com + Vec3::z() * seat,
                |s| {
                    Vec3::new(
                        1e-4 * (2.0 * s).cos(),
                        1e-4 * s.sin(),
                        1e-4 - 2e-4 * (1.0 + (3.0 * s).sin()),
                    )
                },
                |s| {
                    UnitQuaternion::from_scaled_axis(
                        Vec3::new(s.sin(), s.cos(), 0.0) * 1f64.to_radians(),
                    )
                },
            ))
        },
    )
}
