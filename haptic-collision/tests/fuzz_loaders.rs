//! Short fuzzing of the mesh loaders in the default test run: arbitrary bytes, and valid files
//! with bytes flipped, truncated or spliced, never panic and never give a mesh with a NaN.
//! (Long runs: `fuzz/` with cargo-fuzz, see docs/decisions.md.)

use haptic_collision::{LoadOptions, MeshFormat, TriMesh};
use proptest::prelude::*;

const FORMATS: [MeshFormat; 3] = [MeshFormat::Stl, MeshFormat::Obj, MeshFormat::Ply];

/// Small valid files of each format (a tetrahedron).
fn seeds() -> Vec<(MeshFormat, Vec<u8>)> {
    let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n".to_vec();
    let ply = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n".to_vec();
    let stl = b"solid t\nfacet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\nendloop\nendfacet\nfacet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\nendsolid t\n".to_vec();
    vec![
        (MeshFormat::Obj, obj),
        (MeshFormat::Ply, ply),
        (MeshFormat::Stl, stl),
    ]
}

fn check(bytes: &[u8], format: MeshFormat) {
    if let Ok((mesh, _)) = TriMesh::from_bytes(bytes, format, &LoadOptions::default()) {
        assert!(
            mesh.vertices()
                .iter()
                .all(|v| v.iter().all(|c| c.is_finite()))
        );
        let n = mesh.vertices().len() as u32;
        assert!(mesh.triangles().iter().flatten().all(|&i| i < n));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600), f in 0usize..3) {
        check(&bytes, FORMATS[f]);
    }

    #[test]
    fn mutated_files_never_panic(
        seed in 0usize..3,
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let (format, mut bytes) = seeds().swap_remove(seed);
        for (at, b) in flips {
            let i = at.index(bytes.len());
            bytes[i] = b;
        }
        if truncate {
            let n = cut.index(bytes.len() + 1);
            bytes.truncate(n);
        }
        check(&bytes, format);
    }
}

#[test]
fn the_seeds_load() {
    for (format, bytes) in seeds() {
        assert!(
            TriMesh::from_bytes(&bytes, format, &LoadOptions::default()).is_ok(),
            "{format:?}"
        );
    }
}
