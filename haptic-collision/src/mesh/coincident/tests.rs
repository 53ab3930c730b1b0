use haptic_core::{Pose, Vec3};
use proptest::prelude::*;

use crate::lod::testmesh::{cuboid, mesh};
use crate::mesh::{CoincidentTriangles, LoadOptions, MeshFormat, TriMesh};
use crate::{LodBackend, lod::LodError, reference::ReferenceBackend};

/// `m` with the triangles `extra` appended (as given).
fn with(m: &TriMesh, extra: &[[u32; 3]]) -> TriMesh {
    let mut t = m.triangles().to_vec();
    t.extend_from_slice(extra);
    mesh(m.vertices().to_vec(), t)
}

#[test]
fn repeats_and_opposites_on_the_same_vertices_are_told_apart() {
    let b = cuboid(Vec3::new(0.01, 0.02, 0.03));
    assert!(b.coincident_triangles().is_none());
    let [x, y, z] = b.triangles()[3];
    // The same triangle again, rotated; again turned; and a third time as first given.
    let m = with(&b, &[[y, z, x], [x, z, y], [x, y, z]]);
    assert_eq!(
        m.coincident_triangles(),
        CoincidentTriangles {
            duplicates: 2,
            two_sided: 1
        }
    );
    let (fewer, dropped) = m.without_duplicates();
    assert_eq!(dropped, 2);
    // The first of each kept, in order: the box, then the turned one.
    assert_eq!(fewer.triangles()[..12], b.triangles()[..]);
    assert_eq!(fewer.triangles()[12], [x, z, y]);
    assert_eq!(
        fewer.coincident_triangles(),
        CoincidentTriangles {
            duplicates: 0,
            two_sided: 1
        }
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any of a box's triangles repeated, in any rotation: each repeat is counted and dropped,
    /// and what is left is the box.
    #[test]
    fn every_repeat_is_dropped(picks in proptest::collection::vec((0usize..12, 0usize..3), 0..20)) {
        let b = cuboid(Vec3::new(0.01, 0.02, 0.03));
        let extra: Vec<[u32; 3]> = picks
            .iter()
            .map(|&(t, r)| {
                let [x, y, z] = b.triangles()[t];
                [[x, y, z], [y, z, x], [z, x, y]][r]
            })
            .collect();
        let m = with(&b, &extra);
        prop_assert_eq!(m.coincident_triangles().duplicates, extra.len());
        let (fewer, dropped) = m.without_duplicates();
        prop_assert_eq!(dropped, extra.len());
        prop_assert_eq!(fewer, b);
    }
}

#[test]
fn loading_drops_repeats_and_the_back_ends_refuse_what_has_no_inside() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
               f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\nf 3 4 2\n";
    let (tet, report) =
        TriMesh::from_bytes(obj.as_bytes(), MeshFormat::Obj, &LoadOptions::default()).unwrap();
    assert_eq!((report.duplicates_dropped, tet.triangles().len()), (1, 4));
    assert!((tet.mass_properties(1.0).unwrap().volume_m3 - 1.0 / 6.0).abs() < 1e-12);

    let tool = cuboid(Vec3::new(0.005, 0.005, 0.005));
    let b = cuboid(Vec3::new(0.02, 0.02, 0.01));
    let repeated = with(&b, &[b.triangles()[0]]);
    assert_eq!(
        LodBackend::new(&tool, &[(repeated, Pose::identity())]).unwrap_err(),
        LodError::CoincidentTriangles {
            obstacle: Some(0),
            duplicates: 1,
            two_sided: 0
        }
    );
    // A square sheet with both sides out.
    let v = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let v = v
        .iter()
        .map(|p| Vec3::new(p[0], p[1], 0.0) * 0.02)
        .collect();
    let sheet = mesh(v, vec![[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]]);
    assert_eq!(
        ReferenceBackend::new(&tool, &[(sheet, Pose::identity())]).unwrap_err(),
        LodError::CoincidentTriangles {
            obstacle: Some(0),
            duplicates: 0,
            two_sided: 2
        }
    );
}
