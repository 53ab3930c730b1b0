//! Saved hierarchies: read back, refused, edited, cached.

use super::*;
use crate::lod::testmesh;
use haptic_core::{CollisionBackend, ContactSet, QueryParams};

fn sphere() -> TriMesh {
    testmesh::bumpy_sphere(2, 0.05, 0.0, 1)
}

fn saved(h: &Hierarchy, key: u64) -> Vec<u8> {
    let mut bytes = Vec::new();
    h.write_to(&mut bytes, key).unwrap();
    bytes
}

#[test]
fn a_saved_hierarchy_reads_back_the_same() {
    let mesh = sphere();
    let h = Hierarchy::build(&mesh);
    let key = hierarchy_key(&mesh);
    let back = Hierarchy::read_from(&saved(&h, key)[..], &mesh).unwrap();
    assert_eq!(back.nodes, h.nodes);
    assert_eq!(back.piece, h.piece);
    assert_eq!(back.height(), h.height());
    assert_eq!(back.triangle_count(), h.triangle_count());
    assert_eq!(back.radius_about_origin_m(), h.radius_about_origin_m());
}

/// A washer's pieces are planar and their overhang measured (`overhang.rs`): it reads back the
/// same, and a file whose overhang does not hold (a negative width or area, an entry for a leaf
/// or out of order) is refused, its hash re-sealed so that only the values can tell.
#[test]
fn a_planar_meshs_overhang_reads_back_the_same_and_forged_ones_are_refused() {
    let mesh = testmesh::annulus(0.027, 0.03, 64);
    let h = Hierarchy::build(&mesh);
    let key = hierarchy_key(&mesh);
    let bytes = saved(&h, key);
    let back = Hierarchy::read_from(&bytes[..], &mesh).unwrap();
    assert_eq!(back.overhang, h.overhang);
    assert!(h.overhang.iter().any(|o| o.width_m > 0.0));
    let inner = h.nodes.iter().position(|n| !n.is_leaf()).unwrap();
    let at = h.nodes[inner].piece_start as usize;
    for edit in [
        &|o: &mut Overhang| o.width_m = -1e-3 as Real,
        &|o: &mut Overhang| o.area_m2 = -1e-9 as Real,
    ] as [&dyn Fn(&mut Overhang); 2]
    {
        let mut f = h.clone();
        edit(&mut f.overhang[at]);
        assert!(matches!(
            Hierarchy::read_from(&saved(&f, key)[..], &mesh),
            Err(HierarchyFileError::Corrupt("an overhang width"))
        ));
    }
    // The first entry's node index (after the nodes and the piece vertices) made a leaf's, or
    // the second's made the first's (out of order).
    let entries = HEADER_BYTES + h.nodes.len() * NODE_BYTES + h.piece.len() * VERTEX_BYTES;
    let leaf = h.nodes.iter().position(Node::is_leaf).unwrap() as u32;
    let first = u32_at(&bytes, entries);
    let second_at =
        entries + MEASURED_BYTES + h.nodes[first as usize].piece_len as usize * OVERHANG_BYTES;
    for (offset, index) in [(entries, leaf), (second_at, first)] {
        let mut bad = bytes.clone();
        bad[offset..offset + 4].copy_from_slice(&index.to_le_bytes());
        let body = bad.len() - CHECKSUM_BYTES;
        let hash = checksum(&bad[..body]);
        bad[body..].copy_from_slice(&hash.to_le_bytes());
        assert!(matches!(
            Hierarchy::read_from(&bad[..], &mesh),
            Err(HierarchyFileError::Corrupt(_))
        ));
    }
}

#[test]
fn truncated_foreign_other_and_corrupt_files_are_refused() {
    let mesh = sphere();
    let h = Hierarchy::build(&mesh);
    let key = hierarchy_key(&mesh);
    let bytes = saved(&h, key);
    let cut = &bytes[..bytes.len() / 2];
    assert!(matches!(
        Hierarchy::read_from(cut, &mesh),
        Err(HierarchyFileError::Truncated)
    ));
    // Cut anywhere: refused, never read past its end (the header's counts ask for more).
    for len in (0..bytes.len()).step_by(37).chain([bytes.len() - 1]) {
        assert!(
            matches!(
                Hierarchy::read_from(&bytes[..len], &mesh),
                Err(HierarchyFileError::Truncated | HierarchyFileError::NotAHierarchy)
            ),
            "a file cut to {len} of {} bytes was not refused as cut short",
            bytes.len()
        );
    }
    assert!(matches!(
        Hierarchy::read_from(&b"solid cube\nfacet normal"[..], &mesh),
        Err(HierarchyFileError::NotAHierarchy)
    ));
    assert!(matches!(
        Hierarchy::read_from(&b""[..], &mesh),
        Err(HierarchyFileError::NotAHierarchy)
    ));
    // Another mesh: the key differs.
    let other = testmesh::bumpy_sphere(1, 0.05, 0.0, 1);
    assert_ne!(hierarchy_key(&other), key);
    assert!(matches!(
        Hierarchy::read_from(&bytes[..], &other),
        Err(HierarchyFileError::OtherMesh { .. })
    ));
    // Another version.
    let mut v2 = bytes.clone();
    v2[10..14].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    assert!(matches!(
        Hierarchy::read_from(&v2[..], &mesh),
        Err(HierarchyFileError::Version { found }) if found == FORMAT_VERSION + 1
    ));
    // One flipped bit anywhere in the body: refused (hash, indices or values).
    for at in [60, bytes.len() / 3, bytes.len() - 20] {
        let mut bad = bytes.clone();
        bad[at] ^= 0x10;
        assert!(
            matches!(
                Hierarchy::read_from(&bad[..], &mesh),
                Err(HierarchyFileError::Corrupt(_) | HierarchyFileError::OtherMesh { .. })
            ),
            "a flipped bit at {at} was accepted"
        );
    }
}

/// Files whose hash holds (a forger can compute it) but whose tree would mislead the walk.
#[test]
fn forged_trees_are_refused() {
    let mesh = sphere();
    let h = Hierarchy::build(&mesh);
    let key = hierarchy_key(&mesh);
    let forged = |edit: &dyn Fn(&mut Hierarchy)| {
        let mut f = h.clone();
        edit(&mut f);
        Hierarchy::read_from(&saved(&f, key)[..], &mesh)
    };
    let inner = h.nodes.iter().position(|n| !n.is_leaf()).unwrap();
    let leaf = h.nodes.iter().position(Node::is_leaf).unwrap();
    type Edit<'a> = &'a dyn Fn(&mut Hierarchy);
    let cases: [(&str, Edit<'_>); 6] = [
        // Two parents sharing a child: an exponential walk.
        ("shared child", &|f: &mut Hierarchy| {
            f.nodes[inner].right = inner as u32 + 1
        }),
        // A piece longer than the walk's buffers.
        ("long piece", &|f: &mut Hierarchy| {
            f.nodes[inner].piece_len = 7
        }),
        ("leaf triangle", &|f: &mut Hierarchy| {
            f.nodes[leaf].triangle = u32::MAX - 1
        }),
        ("leaf count", &|f: &mut Hierarchy| f.nodes[0].triangles += 1),
        ("normal", &|f: &mut Hierarchy| f.nodes[inner].normal *= 2.0),
        ("nan", &|f: &mut Hierarchy| f.nodes[leaf].radius = Real::NAN),
    ];
    for (what, edit) in cases {
        assert!(
            matches!(forged(edit), Err(HierarchyFileError::Corrupt(_))),
            "{what} was accepted"
        );
    }
    // Bytes after the end.
    let mut long = saved(&h, key);
    long.push(0);
    assert!(matches!(
        Hierarchy::read_from(&long[..], &mesh),
        Err(HierarchyFileError::Corrupt(_))
    ));
    // An inner node without a usable piece (infinite deviation) is a valid tree.
    let none = forged(&|f: &mut Hierarchy| {
        f.nodes[inner].piece_len = 0;
        f.nodes[inner].deviation = Real::INFINITY;
    });
    assert!(none.is_ok(), "{none:?}");
}

/// A file re-sealed after any edit (so that the hash does not catch it) is refused with a
/// typed error, or holds a tree that queries walk without a panic: the version of the
/// `lod_cache` fuzz target (`fuzz/`) that runs with the tests.
mod edited {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    fn valid() -> &'static (TriMesh, Vec<u8>) {
        static VALID: OnceLock<(TriMesh, Vec<u8>)> = OnceLock::new();
        VALID.get_or_init(|| {
            // A bumpy sphere and a washer beside it, so that the file holds measured
            // overhangs (`overhang.rs`) too.
            let sphere = testmesh::bumpy_sphere(1, 0.05, 0.1, 3);
            let washer = testmesh::annulus(0.02, 0.03, 16);
            let n = sphere.vertices().len() as u32;
            let vertices = sphere
                .vertices()
                .iter()
                .copied()
                .chain(
                    washer
                        .vertices()
                        .iter()
                        .map(|v| v + Vec3::new(0.0, 0.0, 0.06)),
                )
                .collect();
            let triangles = sphere
                .triangles()
                .iter()
                .copied()
                .chain(washer.triangles().iter().map(|t| t.map(|i| i + n)))
                .collect();
            let mesh = testmesh::mesh(vertices, triangles);
            let bytes = saved(&Hierarchy::build(&mesh), hierarchy_key(&mesh));
            (mesh, bytes)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(96))]
        #[test]
        fn edited_files_are_refused_or_walk_safely(
            edits in prop::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 1..6),
        ) {
            let (mesh, bytes) = valid();
            let mut file = bytes.clone();
            let body = file.len() - CHECKSUM_BYTES;
            for (at, xor) in &edits {
                file[at.index(body)] ^= xor;
            }
            let hash = checksum(&file[..body]);
            file[body..].copy_from_slice(&hash.to_le_bytes());
            let Ok(h) = Hierarchy::read_from(&file[..], mesh) else {
                return Ok(());
            };
            let obstacle = Hierarchy::build(mesh);
            let near = Pose::from_position(Vec3::new(0.09, 0.0, 0.0));
            let mut lod = LodBackend::with_hierarchies(h, vec![(obstacle, near)]).unwrap();
            let mut out = ContactSet::new();
            for threshold in [0.0, 0.025] {
                let params = QueryParams::new(0.01, threshold).unwrap();
                for dx in [0.0, -0.02] {
                    // A typed error (a non-finite contact from absurd values) or contacts,
                    // which `Contact::new` has checked.
                    if lod.query(&Pose::from_position(Vec3::new(dx, 0.0, 0.0)), &params, &mut out).is_ok() {
                        prop_assert!(out.iter().all(|c| c.validate().is_ok()));
                    }
                }
            }
        }
    }
}

#[test]
fn a_saved_hierarchy_read_back_answers_as_the_built_one() {
    let tool = sphere();
    let obstacle = testmesh::bumpy_sphere(2, 0.08, 0.0, 2);
    let at = Pose::from_position(Vec3::new(0.125, 0.0, 0.0));
    let read = |m: &TriMesh| {
        Hierarchy::read_from(&saved(&Hierarchy::build(m), hierarchy_key(m))[..], m).unwrap()
    };
    let mut built = LodBackend::new(&tool, &[(obstacle.clone(), at)]).unwrap();
    let mut loaded =
        LodBackend::with_hierarchies(read(&tool), vec![(read(&obstacle), at)]).unwrap();
    let pose = Pose::from_position(Vec3::new(0.0, 0.002, 0.0));
    for threshold in [0.0, 0.025] {
        let params = QueryParams::new(0.01, threshold).unwrap();
        let (mut a, mut b) = (ContactSet::new(), ContactSet::new());
        built.query(&pose, &params, &mut a).unwrap();
        loaded.query(&pose, &params, &mut b).unwrap();
        assert!(!a.is_empty());
        assert_eq!(a.as_slice(), b.as_slice());
    }
    let nan = Pose::from_position(Vec3::new(Real::NAN, 0.0, 0.0));
    assert!(matches!(
        LodBackend::with_hierarchies(read(&tool), vec![(read(&obstacle), nan)]),
        Err(LodError::NonFinitePose { .. })
    ));
}

#[test]
fn a_cached_backend_loads_the_second_time_and_answers_the_same() {
    let dir = std::env::temp_dir().join(format!("haptic-lod-cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let tool = sphere();
    let obstacle = testmesh::bumpy_sphere(2, 0.08, 0.0, 2);
    let obstacles = [(obstacle, Pose::from_position(Vec3::new(0.125, 0.0, 0.0)))];
    let (mut built, first) = LodBackend::with_cache(&tool, &obstacles, &dir).unwrap();
    assert!(
        first.iter().all(|o| matches!(o, CacheOutcome::Built(_))),
        "{first:?}"
    );
    let (mut loaded, second) = LodBackend::with_cache(&tool, &obstacles, &dir).unwrap();
    assert!(
        second.iter().all(|o| matches!(o, CacheOutcome::Loaded(_))),
        "{second:?}"
    );
    let params = QueryParams::new(0.01, 0.0).unwrap();
    let pose = Pose::from_position(Vec3::new(0.0, 0.002, 0.0));
    let (mut a, mut b) = (ContactSet::new(), ContactSet::new());
    built.query(&pose, &params, &mut a).unwrap();
    loaded.query(&pose, &params, &mut b).unwrap();
    assert!(!a.is_empty());
    assert_eq!(a.as_slice(), b.as_slice());
    // A corrupt file is rebuilt and replaced, never used.
    let CacheOutcome::Loaded(path) = &second[0] else {
        unreachable!()
    };
    let mut bytes = std::fs::read(path).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 0xff;
    std::fs::write(path, &bytes).unwrap();
    let (_, third) = LodBackend::with_cache(&tool, &obstacles, &dir).unwrap();
    assert!(
        matches!(&third[0], CacheOutcome::Rebuilt(_, why) if why.contains("corrupt")),
        "{third:?}"
    );
    let (_, fourth) = LodBackend::with_cache(&tool, &obstacles, &dir).unwrap();
    assert!(matches!(fourth[0], CacheOutcome::Loaded(_)));
    let _ = std::fs::remove_dir_all(&dir);
}
