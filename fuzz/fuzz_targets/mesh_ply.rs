#![no_main]
//! The Ply loader never panics, and a mesh it accepts has finite vertices and valid indices.

use haptic_collision::{LoadOptions, MeshFormat, TriMesh};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    if let Ok((mesh, _)) = TriMesh::from_bytes(bytes, MeshFormat::Ply, &LoadOptions::default()) {
        assert!(mesh.vertices().iter().all(|v| v.iter().all(|c| c.is_finite())));
        let n = mesh.vertices().len() as u32;
        assert!(mesh.triangles().iter().flatten().all(|&i| i < n));
    }
});
