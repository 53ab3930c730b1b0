use std::path::PathBuf;

use haptic_core::{Mat3, Real, Vec3};
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;

use super::{DegeneratePolicy, LoadOptions, MeshError, MeshFormat, TriMesh};
use crate::lod::testmesh::{bumpy_sphere, cuboid, icosphere_raw, mesh};

/// A fresh file in the system's temporary directory with `bytes` in it.
fn temp_file(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("haptic-collision-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write temp file");
    path
}

/// Binary STL of the given triangles (f32 corners).
fn binary_stl(tris: &[[[f32; 3]; 3]], header: &[u8]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b[..header.len()].copy_from_slice(header);
    b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        b.extend_from_slice(&[0u8; 12]);
        for v in t {
            for c in v {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    b
}

fn cube_tris(m: &TriMesh) -> Vec<[[f32; 3]; 3]> {
    (0..m.triangles().len())
        .map(|t| m.triangle(t).map(|v| [v.x as f32, v.y as f32, v.z as f32]))
        .collect()
}

const OBJ_CUBE: &str = "# unit cube, quads\n\
v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

const PLY_CUBE: &str = "ply\nformat ascii 1.0\nelement vertex 8\n\
property float x\nproperty float y\nproperty float z\n\
element face 6\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n\
4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n";

fn load_err(name: &str, bytes: &[u8], opts: &LoadOptions) -> MeshError {
    let path = temp_file(name, bytes);
    TriMesh::load(&path, opts).expect_err("load should fail")
}

#[test]
fn binary_and_ascii_stl_load_with_scale_and_recentre() {
    let cube = cuboid(Vec3::new(1.0, 2.0, 3.0));
    let tris = cube_tris(&cube);
    let path = temp_file("cube.stl", &binary_stl(&tris, b"binary cube"));
    let (m, rep) = TriMesh::load(&path, &LoadOptions::with_scale(1e-3)).unwrap();
    assert_eq!(rep.format, MeshFormat::Stl);
    assert_eq!((rep.vertices, rep.triangles), (8, 12));
    let (lo, hi) = m.bounding_box();
    assert!((hi - Vec3::new(1e-3, 2e-3, 3e-3)).norm() < 1e-15);
    assert!((lo + hi).norm() < 1e-15);

    // A binary file whose header starts with "solid" is still read as binary.
    let path = temp_file("solid_header.stl", &binary_stl(&tris, b"solid but binary"));
    let (m2, _) = TriMesh::load(&path, &LoadOptions::default()).unwrap();
    assert_eq!(m2.triangles().len(), 12);

    // ASCII, shifted, recentred.
    let mut ascii = String::from("solid cube\n");
    for t in &tris {
        ascii.push_str("facet normal 0 0 0\nouter loop\n");
        for v in t {
            ascii.push_str(&format!("vertex {} {} {}\n", v[0] + 5.0, v[1], v[2]));
        }
        ascii.push_str("endloop\nendfacet\n");
    }
    ascii.push_str("endsolid cube\n");
    let path = temp_file("cube_ascii.stl", ascii.as_bytes());
    let opts = LoadOptions {
        recentre: true,
        ..LoadOptions::default()
    };
    let (m3, rep3) = TriMesh::load(&path, &opts).unwrap();
    assert_eq!((rep3.vertices, rep3.triangles), (8, 12));
    assert!((rep3.translation_m - Vec3::new(-5.0, 0.0, 0.0)).norm() < 1e-12);
    let (lo, hi) = m3.bounding_box();
    assert!((lo + hi).norm() < 1e-12);
    assert!((m3.mass_properties(1.0).unwrap().volume_m3 - 48.0).abs() < 1e-9);
}

#[test]
fn obj_and_ply_polygons_are_triangulated() {
    let path = temp_file("cube.obj", OBJ_CUBE.as_bytes());
    let (m, rep) = TriMesh::load(&path, &LoadOptions::default()).unwrap();
    assert_eq!(
        (rep.format, rep.triangles, rep.polygons_triangulated),
        (MeshFormat::Obj, 12, 6)
    );
    let mp = m.mass_properties(1.0).unwrap();
    assert!((mp.volume_m3 - 1.0).abs() < 1e-12, "{}", mp.volume_m3);
    assert!((mp.centre_of_mass_m - Vec3::repeat(0.5)).norm() < 1e-12);

    let path = temp_file("cube.ply", PLY_CUBE.as_bytes());
    let (m, rep) = TriMesh::load(&path, &LoadOptions::with_scale(2.0)).unwrap();
    assert_eq!(
        (rep.format, rep.triangles, rep.polygons_triangulated),
        (MeshFormat::Ply, 12, 6)
    );
    assert!((m.mass_properties(1.0).unwrap().volume_m3 - 8.0).abs() < 1e-12);

    let b = binary_ply_triangle([1.0, 0.0, 0.0]);
    let (m, _) = TriMesh::from_bytes(&b, MeshFormat::Ply, &LoadOptions::default()).unwrap();
    assert_eq!(m.triangle(0)[1], Vec3::x());
}

/// Binary little-endian PLY of one triangle `(0,0,0), second, (0,1,0)`.
fn binary_ply_triangle(second: [f64; 3]) -> Vec<u8> {
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\n\
property double y\nproperty double z\nelement face 1\nproperty list uchar uint vertex_indices\n\
end_header\n"
        .to_vec();
    for v in [[0.0f64, 0.0, 0.0], second, [0.0, 1.0, 0.0]] {
        for c in v {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    b.push(3);
    for i in [0u32, 1, 2] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

#[test]
fn each_bad_input_gives_its_error() {
    let d = LoadOptions::default();
    // Missing file.
    let missing = std::env::temp_dir().join("haptic-collision-no-such-file.stl");
    assert!(matches!(
        TriMesh::load(&missing, &d),
        Err(MeshError::Io {
            kind: std::io::ErrorKind::NotFound,
            ..
        })
    ));
    // Unknown extension.
    assert!(matches!(
        TriMesh::load("mesh.xyz", &d),
        Err(MeshError::UnsupportedFormat { .. })
    ));
    // Truncated binary STL: the header announces 12 triangles, the last record is cut.
    let tris = cube_tris(&cuboid(Vec3::repeat(1.0)));
    let full = binary_stl(&tris, b"cube");
    assert!(matches!(
        load_err("truncated.stl", &full[..full.len() - 20], &d),
        MeshError::Truncated { triangles: 12, .. }
    ));
    assert!(matches!(
        load_err("short.stl", &full[..40], &d),
        MeshError::Truncated { .. }
    ));
    // Empty meshes.
    assert_eq!(
        load_err("empty.stl", &binary_stl(&[], b""), &d),
        MeshError::Empty
    );
    assert_eq!(
        load_err("empty.obj", b"v 0 0 0\nv 1 0 0\n", &d),
        MeshError::Empty
    );
    // NaN and Inf coordinates in files.
    let mut nan_tris = tris.clone();
    nan_tris[3][1][2] = f32::NAN;
    assert!(matches!(
        load_err("nan.stl", &binary_stl(&nan_tris, b""), &d),
        MeshError::NonFiniteVertex { .. }
    ));
    assert!(matches!(
        load_err("nan.obj", b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", &d),
        MeshError::NonFiniteVertex { index: 1 }
    ));
    assert!(matches!(
        load_err(
            "inf.ply",
            &binary_ply_triangle([0.0, Real::INFINITY, 0.0]),
            &d
        ),
        MeshError::NonFiniteVertex { index: 1 }
    ));
    // Index out of range.
    assert_eq!(
        load_err(
            "index.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n",
            &d
        ),
        MeshError::IndexOutOfRange {
            triangle: 1,
            vertex: 8,
            vertex_count: 3
        }
    );
    let ply_bad = PLY_CUBE.replacen("4 4 5 6 7\n", "4 4 5 6 17\n", 1);
    assert!(matches!(
        load_err("index.ply", ply_bad.as_bytes(), &d),
        MeshError::IndexOutOfRange {
            vertex: 17,
            vertex_count: 8,
            ..
        }
    ));
    let ply_neg = PLY_CUBE.replacen("4 4 5 6 7\n", "4 4 5 -6 7\n", 1);
    assert!(matches!(
        load_err("negative.ply", ply_neg.as_bytes(), &d),
        MeshError::IndexOutOfRange { vertex: -6, .. }
    ));
    // Malformed content.
    assert!(matches!(
        load_err("bad.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 two 3\n", &d),
        MeshError::Malformed {
            format: MeshFormat::Obj,
            ..
        }
    ));
    assert!(matches!(
        load_err(
            "bad.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\nzero\n",
            &d
        ),
        MeshError::Malformed {
            format: MeshFormat::Ply,
            ..
        }
    ));
    assert!(matches!(
        load_err(
            "truncated.ply",
            &PLY_CUBE.as_bytes()[..PLY_CUBE.len() - 30],
            &d
        ),
        MeshError::Malformed {
            format: MeshFormat::Ply,
            ..
        }
    ));
    assert!(matches!(
        load_err(
            "noface.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\nend_header\n1\n",
            &d
        ),
        MeshError::Malformed { .. }
    ));
    assert!(matches!(
        load_err(
            "bad_ascii.stl",
            b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n",
            &d
        ),
        MeshError::Malformed {
            format: MeshFormat::Stl,
            ..
        }
    ));
    // Bad scale.
    assert!(matches!(
        TriMesh::load(&missing, &LoadOptions::with_scale(0.0)),
        Err(MeshError::BadParameter { .. })
    ));
    assert!(matches!(
        TriMesh::from_bytes(
            OBJ_CUBE.as_bytes(),
            MeshFormat::Obj,
            &LoadOptions::with_scale(Real::NAN)
        ),
        Err(MeshError::BadParameter { .. })
    ));
}

#[test]
fn degenerate_triangles_are_counted_then_dropped_or_rejected() {
    // The cube plus two degenerate triangles: a repeated corner and three collinear corners.
    let obj = format!("{OBJ_CUBE}v 2 0 0\nf 1 2 9\nf 1 1 3\n");
    let (m, rep) =
        TriMesh::from_bytes(obj.as_bytes(), MeshFormat::Obj, &LoadOptions::default()).unwrap();
    assert_eq!((rep.degenerate_dropped, m.triangles().len()), (2, 12));
    let reject = LoadOptions {
        degenerate: DegeneratePolicy::Reject,
        ..LoadOptions::default()
    };
    assert_eq!(
        TriMesh::from_bytes(obj.as_bytes(), MeshFormat::Obj, &reject).unwrap_err(),
        MeshError::DegenerateTriangles {
            count: 2,
            first: 12
        }
    );
    // Only degenerate triangles: nothing is left.
    assert_eq!(
        TriMesh::from_bytes(
            b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n",
            MeshFormat::Obj,
            &LoadOptions::default()
        )
        .unwrap_err(),
        MeshError::Empty
    );
}

#[test]
fn box_mass_properties_are_exact() {
    let (a, b, c) = (0.03, 0.02, 0.01);
    let m = cuboid(Vec3::new(a, b, c))
        .translated(&Vec3::new(0.1, -0.2, 0.3))
        .unwrap();
    let density = 7800.0;
    let mp = m.mass_properties(density).unwrap();
    let vol = 8.0 * a * b * c;
    let mass = vol * density;
    assert!((mp.volume_m3 - vol).abs() < 1e-15);
    assert!((mp.mass_kg - mass).abs() < 1e-12);
    assert!((mp.centre_of_mass_m - Vec3::new(0.1, -0.2, 0.3)).norm() < 1e-14);
    let (x, y, z) = (2.0 * a, 2.0 * b, 2.0 * c);
    let expected = Mat3::from_diagonal(&Vector3::new(y * y + z * z, x * x + z * z, x * x + y * y))
        * (mass / 12.0);
    assert!((mp.inertia_about_com - expected).norm() < 1e-12 * expected.norm());
    assert_eq!((mp.boundary_edges, mp.open_volume_change_rel), (0, 0.0));
    assert!(mp.rigid_body().is_ok());
}

#[test]
fn sphere_mass_properties_converge() {
    let (v, t) = icosphere_raw(4);
    let m = mesh(v.into_iter().map(|p| p * 0.05).collect(), t);
    let mp = m.mass_properties(1000.0).unwrap();
    let r: Real = 0.05;
    let vol = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    assert!(
        (mp.volume_m3 / vol - 1.0).abs() < 0.01,
        "{}",
        mp.volume_m3 / vol
    );
    let i = 0.4 * mp.mass_kg * r * r;
    for k in 0..3 {
        assert!((mp.inertia_about_com[(k, k)] / i - 1.0).abs() < 0.02);
    }
    assert!(mp.centre_of_mass_m.norm() < 1e-9);
}

#[test]
fn open_inverted_and_bad_density_are_errors() {
    let cube = cuboid(Vec3::repeat(0.01));
    // Remove one face (two triangles): a box without a lid.
    let open = TriMesh::new(
        cube.vertices().to_vec(),
        cube.triangles()[2..].to_vec(),
        DegeneratePolicy::Reject,
    )
    .unwrap()
    .0;
    assert_eq!(open.boundary_edge_count(), 4);
    assert!(matches!(
        open.mass_properties(1000.0),
        Err(MeshError::OpenMesh {
            boundary_edges: 4,
            ..
        })
    ));
    let inverted = TriMesh::new(
        cube.vertices().to_vec(),
        cube.triangles()
            .iter()
            .map(|t| [t[0], t[2], t[1]])
            .collect(),
        DegeneratePolicy::Reject,
    )
    .unwrap()
    .0;
    assert!(matches!(
        inverted.mass_properties(1000.0),
        Err(MeshError::NonPositiveVolume { .. })
    ));
    for bad in [0.0, -1.0, Real::NAN, Real::INFINITY] {
        assert!(matches!(
            cube.mass_properties(bad),
            Err(MeshError::BadParameter { .. })
        ));
    }
}

/// The repository's meshes (`assets/meshes`): the spoon's slits are within the open-mesh
/// tolerance, the cup's openings are not, the jaws are closed.
#[test]
fn repository_meshes_mass_properties() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/meshes");
    let d = LoadOptions::default();
    let (spoon, _) = TriMesh::load(dir.join("newell_teaspoon.stl"), &d).unwrap();
    let mp = spoon.mass_properties(1000.0).unwrap();
    assert_eq!(mp.boundary_edges, 48);
    assert!(mp.open_volume_change_rel > 0.0 && mp.open_volume_change_rel < 0.01);
    let (cup, _) = TriMesh::load(dir.join("newell_teacup.stl"), &d).unwrap();
    assert!(matches!(
        cup.mass_properties(1000.0),
        Err(MeshError::OpenMesh {
            boundary_edges: 132,
            ..
        })
    ));
    let (jaw, rep) = TriMesh::load(
        dir.join("jaw_lower_openfulljaw_p26.stl"),
        &LoadOptions::with_scale(1e-3),
    )
    .unwrap();
    assert_eq!((rep.triangles, rep.vertices), (40_174, 20_119));
    assert_eq!(jaw.mass_properties(1000.0).unwrap().boundary_edges, 0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Moving a closed mesh rigidly moves its centre of mass with it and rotates its inertia
    /// (`R I Rᵀ`); volume and mass do not change.
    #[test]
    fn mass_properties_follow_rigid_motions(
        seed in 0u64..1000,
        axis in prop::array::uniform3(-1.0f64..1.0),
        angle in -3.0f64..3.0,
        shift in prop::array::uniform3(-0.5f64..0.5),
    ) {
        let m = bumpy_sphere(1, 0.05, 0.3, seed);
        let rot = Rotation3::from_scaled_axis(Vector3::from(axis).normalize() * angle);
        let t = Vec3::from(shift);
        let moved = TriMesh::new(
            m.vertices().iter().map(|v| rot * v + t).collect(),
            m.triangles().to_vec(),
            DegeneratePolicy::Reject,
        )
        .unwrap()
        .0;
        let a = m.mass_properties(1200.0).unwrap();
        let b = moved.mass_properties(1200.0).unwrap();
        prop_assert!((a.volume_m3 - b.volume_m3).abs() < 1e-12 * a.volume_m3.max(1e-9) + 1e-18);
        prop_assert!((rot * a.centre_of_mass_m + t - b.centre_of_mass_m).norm() < 1e-12);
        let r = rot.matrix();
        let expected = r * a.inertia_about_com * r.transpose();
        prop_assert!((expected - b.inertia_about_com).norm() < 1e-9 * expected.norm());
    }
}
