#![no_main]
//! A saved LOD hierarchy, whatever its bytes, is refused with a typed error or holds a tree that
//! queries walk without a panic and whose contacts are valid.
//!
//! Built with `--cfg fuzzing`, the reader does not check the file's hash, so that mutated files
//! reach the parser and the tree check behind it. The input either is a whole file (first byte
//! below 32) or edits a valid one: 5-byte chunks, each an offset (`u32`, little-endian, taken
//! modulo the length) and a byte to XOR there; an odd first byte also cuts the file at the first
//! chunk's offset.

use std::sync::OnceLock;

use haptic_collision::lod::{Hierarchy, hierarchy_key};
use haptic_collision::{DegeneratePolicy, LodBackend, TriMesh};
use haptic_core::{CollisionBackend, ContactSet, Pose, QueryParams, Real, Vec3};
use libfuzzer_sys::fuzz_target;

/// A UV sphere of radius 5 cm (8 segments, 6 rings), its hierarchy and that hierarchy's file.
fn valid() -> &'static (TriMesh, Hierarchy, Vec<u8>) {
    static VALID: OnceLock<(TriMesh, Hierarchy, Vec<u8>)> = OnceLock::new();
    VALID.get_or_init(|| {
        let (seg, rings, r) = (8u32, 6u32, 0.05);
        let mut v = vec![Vec3::new(0.0, 0.0, r), Vec3::new(0.0, 0.0, -r)];
        for i in 1..rings {
            let theta = std::f64::consts::PI * Real::from(i) / Real::from(rings);
            for j in 0..seg {
                let phi = std::f64::consts::TAU * Real::from(j) / Real::from(seg);
                v.push(
                    r * Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    ),
                );
            }
        }
        let at = |i: u32, j: u32| 2 + (i - 1) * seg + j % seg;
        let mut t = Vec::new();
        for j in 0..seg {
            t.push([0, at(1, j), at(1, j + 1)]);
            t.push([1, at(rings - 1, j + 1), at(rings - 1, j)]);
            for i in 1..rings - 1 {
                t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        let (mesh, _) = TriMesh::new(v, t, DegeneratePolicy::Reject).expect("a valid sphere");
        let h = Hierarchy::build(&mesh);
        let mut bytes = Vec::new();
        h.write_to(&mut bytes, hierarchy_key(&mesh))
            .expect("writes to memory");
        (mesh, h, bytes)
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let (mesh, obstacle, bytes) = valid();
    let file = if mode < 32 {
        rest.to_vec()
    } else {
        let mut file = bytes.clone();
        for (k, chunk) in rest.chunks_exact(5).enumerate() {
            let at = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]) as usize;
            let at = at % file.len().max(1);
            if k == 0 && mode % 2 == 1 {
                file.truncate(at);
            } else if let Some(b) = file.get_mut(at) {
                *b ^= chunk[4];
            }
        }
        file
    };
    let Ok(h) = Hierarchy::read_from(&file[..], mesh) else {
        return;
    };
    let near = Pose::from_position(Vec3::new(0.09, 0.0, 0.0));
    let mut lod = LodBackend::with_hierarchies(h, vec![(obstacle.clone(), near)])
        .expect("finite pose, few triangles");
    let mut out = ContactSet::new();
    for threshold in [0.0, 0.025] {
        let params = QueryParams::new(0.01, threshold).expect("valid parameters");
        for dx in [0.0, -0.02] {
            if lod
                .query(
                    &Pose::from_position(Vec3::new(dx, 0.0, 0.0)),
                    &params,
                    &mut out,
                )
                .is_ok()
            {
                assert!(out.iter().all(|c| c.validate().is_ok()));
            }
        }
    }
});
