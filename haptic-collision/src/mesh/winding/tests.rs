use haptic_core::{CollisionBackend, ContactSet, Pose, QueryParams, Real, Vec3};
use haptic_test_support::rng::Lcg;
use proptest::prelude::*;

use crate::lod::testmesh::{cuboid, icosphere_raw, mesh};
use crate::mesh::{DegeneratePolicy, LoadOptions, MeshError, MeshFormat, TriMesh, WindingPolicy};
use crate::{LodBackend, lod::LodError, reference::ReferenceBackend};

/// `m` with the triangles `turn` wound the other way.
fn turned(m: &TriMesh, turn: &[usize]) -> TriMesh {
    let triangles = m
        .triangles()
        .iter()
        .enumerate()
        .map(|(t, &[a, b, c])| {
            if turn.contains(&t) {
                [a, c, b]
            } else {
                [a, b, c]
            }
        })
        .collect();
    mesh(m.vertices().to_vec(), triangles)
}

/// A sphere of 320 triangles, wound outward.
fn sphere() -> TriMesh {
    let (v, t) = icosphere_raw(2);
    mesh(v.iter().map(|p| p * 0.01).collect(), t)
}

#[test]
fn a_turned_triangle_conflicts_along_its_three_edges() {
    let s = sphere();
    assert_eq!(s.winding_conflicts(), 0);
    assert_eq!(turned(&s, &[7]).winding_conflicts(), 3);
    // Two neighbours turned together agree along the edge they share.
    let t0 = s.triangles()[0];
    let neighbour = (1..s.triangles().len())
        .find(|&t| s.triangles()[t].iter().filter(|v| t0.contains(v)).count() == 2)
        .unwrap();
    assert_eq!(turned(&s, &[0, neighbour]).winding_conflicts(), 4);
    // The whole mesh inside out is consistent: a choice of its author, not a conflict.
    let all: Vec<usize> = (0..s.triangles().len()).collect();
    let inside_out = turned(&s, &all);
    assert_eq!(inside_out.winding_conflicts(), 0);
    let (same, count) = inside_out.with_consistent_winding().unwrap();
    assert_eq!((same, count), (inside_out, 0));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any minority of a sphere's triangles turned, and a box beside it with another minority
    /// turned: the repair turns exactly those back, each part on its own.
    #[test]
    fn the_repair_turns_back_what_was_turned(seed in 0u64..1_000_000, share in 0.0..0.4f64) {
        let (s, b) = (sphere(), cuboid(Vec3::new(0.01, 0.02, 0.03)));
        let offset = s.vertices().len() as u32;
        let mut vertices = s.vertices().to_vec();
        vertices.extend(b.vertices().iter().map(|v| v + Vec3::new(0.1, 0.0, 0.0)));
        let mut triangles = s.triangles().to_vec();
        triangles.extend(b.triangles().iter().map(|t| t.map(|i| i + offset)));
        let both = mesh(vertices, triangles);
        let mut rng = Lcg(seed);
        // Triangles of equal area on the sphere (nearly) and on each face pair of the box:
        // a minority by count is one by area on the sphere; on the box, one triangle of twelve.
        let mut turn: Vec<usize> = (0..s.triangles().len()).filter(|_| rng.next() < share).collect();
        turn.push(s.triangles().len() + (rng.next() * 12.0) as usize);
        let broken = turned(&both, &turn);
        prop_assert!(broken.winding_conflicts() > 0);
        let (repaired, count) = broken.with_consistent_winding().unwrap();
        prop_assert_eq!(count, turn.len());
        prop_assert_eq!(repaired.winding_conflicts(), 0);
        prop_assert_eq!(repaired, both);
    }
}

#[test]
fn a_moebius_band_cannot_be_wound() {
    // A strip of 12 quads around a circle, its two ends joined with a half twist.
    let n = 12;
    let mut v = Vec::new();
    for i in 0..n {
        let a = i as Real / n as Real * std::f64::consts::TAU;
        let twist = 0.5 * a;
        let radial = Vec3::new(a.cos(), a.sin(), 0.0);
        let across = radial * twist.cos() + Vec3::z() * twist.sin();
        v.push(radial + across * 0.2);
        v.push(radial - across * 0.2);
    }
    let mut t = Vec::new();
    for i in 0..n as u32 {
        let (a, b) = (2 * i, 2 * i + 1);
        let (c, d) = if i + 1 < n as u32 {
            (2 * i + 2, 2 * i + 3)
        } else {
            (1, 0)
        };
        t.push([a, b, d]);
        t.push([a, d, c]);
    }
    let (band, _) = TriMesh::new(v, t, DegeneratePolicy::Reject).unwrap();
    assert!(matches!(
        band.with_consistent_winding(),
        Err(MeshError::NonOrientable { .. })
    ));
}

const OBJ_BOX_ONE_TURNED: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 8 5\n";

#[test]
fn loading_turns_a_turned_triangle_back_or_refuses_it() {
    let bytes = OBJ_BOX_ONE_TURNED.as_bytes();
    let (m, report) = TriMesh::from_bytes(bytes, MeshFormat::Obj, &LoadOptions::default()).unwrap();
    assert_eq!(report.triangles_rewound, 1);
    assert_eq!(m.winding_conflicts(), 0);
    assert_eq!(m.triangles()[11], [3, 4, 7]);
    assert!((m.mass_properties(1000.0).unwrap().volume_m3 - 1.0).abs() < 1e-12);
    let reject = LoadOptions {
        winding: WindingPolicy::Reject,
        ..LoadOptions::default()
    };
    assert_eq!(
        TriMesh::from_bytes(bytes, MeshFormat::Obj, &reject).unwrap_err(),
        MeshError::InconsistentWinding { conflicts: 3 }
    );
}

/// A box resting 0.2 mm above a plate of two triangles, one of them turned: its inside and
/// outside swapped, the box over it is taken for one 0.2 mm inside and pulled down into it.
/// The back-ends refuse the plate, and take it repaired.
#[test]
fn the_back_ends_refuse_a_mesh_wound_against_itself() {
    let v = [
        [-1.0, -1.0, 0.0],
        [1.0, -1.0, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
    ];
    let v: Vec<Vec3> = v
        .iter()
        .map(|p| Vec3::new(p[0], p[1], p[2]) * 0.02)
        .collect();
    let plate = mesh(v, vec![[0, 1, 2], [0, 2, 3]]);
    let broken = turned(&plate, &[1]);
    let tool = cuboid(Vec3::new(0.005, 0.005, 0.005));
    let obstacles = [(broken.clone(), Pose::identity())];
    assert_eq!(
        LodBackend::new(&tool, &obstacles).unwrap_err(),
        LodError::InconsistentWinding {
            obstacle: Some(0),
            conflicts: 1
        }
    );
    assert!(matches!(
        ReferenceBackend::new(&broken, &[]),
        Err(LodError::InconsistentWinding { obstacle: None, .. })
    ));
    let (repaired, count) = broken.with_consistent_winding().unwrap();
    assert_eq!(count, 1);
    let mut lod = LodBackend::new(&tool, &[(repaired, Pose::identity())]).unwrap();
    let pose = Pose::from_position(Vec3::new(-0.005, 0.004, 0.0052));
    let mut out = ContactSet::new();
    lod.query(&pose, &QueryParams::new(0.001, 0.0).unwrap(), &mut out)
        .unwrap();
    assert!(!out.is_empty());
    // Over both triangles, 0.2 mm above: outside, pushed up (the normal points out of the tool,
    // down).
    for c in out.iter() {
        assert!(c.depth_m < 0.0 && c.n.z < -0.99, "{c:?}");
    }
}
