//! Procedural meshes for the tests: boxes, icospheres, bumpy spheres, cylinders, wavy slabs.

use std::collections::HashMap;

use haptic_core::{Real, Vec3};

use crate::mesh::{DegeneratePolicy, TriMesh};

pub use haptic_test_support::rng::Lcg;

pub fn mesh(vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> TriMesh {
    TriMesh::new(vertices, triangles, DegeneratePolicy::Reject)
        .expect("test mesh is valid")
        .0
}

/// An axis-aligned box of half-extents `h` centred at the origin, outward CCW triangles.
pub fn cuboid(h: Vec3) -> TriMesh {
    let v: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        })
        .collect();
    let t = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    mesh(v, t)
}

/// Unit icosphere after `levels` subdivisions (20·4^levels triangles).
pub fn icosphere_raw(levels: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let p = (1.0 + 5.0f64.sqrt()) / 2.0;
    let mut v: Vec<Vec3> = [
        [-1.0, p, 0.0],
        [1.0, p, 0.0],
        [-1.0, -p, 0.0],
        [1.0, -p, 0.0],
        [0.0, -1.0, p],
        [0.0, 1.0, p],
        [0.0, -1.0, -p],
        [0.0, 1.0, -p],
        [p, 0.0, -1.0],
        [p, 0.0, 1.0],
        [-p, 0.0, -1.0],
        [-p, 0.0, 1.0],
    ]
    .iter()
    .map(|c| Vec3::from(*c).normalize())
    .collect();
    let mut t: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut cache: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, v: &mut Vec<Vec3>| {
            let key = (a.min(b), a.max(b));
            *cache.entry(key).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                (v.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(t.len() * 4);
        for [a, b, c] in t {
            let ab = mid(a, b, &mut v);
            let bc = mid(b, c, &mut v);
            let ca = mid(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        t = next;
    }
    (v, t)
}

/// Sphere of radius `r` whose vertex radii are perturbed by up to `bump · r` (closed, bumpy).
pub fn bumpy_sphere(levels: usize, r: Real, bump: Real, seed: u64) -> TriMesh {
    let (v, t) = icosphere_raw(levels);
    let mut rng = Lcg(seed);
    let v = v
        .into_iter()
        .map(|p| p * r * (1.0 + bump * (2.0 * rng.next() - 1.0)))
        .collect();
    mesh(v, t)
}

/// A closed cylinder of radius `r` and height `h` (z from 0 to `h`) with `segments` sides: the
/// wall first, as full-length strips of two triangles each (strip `s` is triangles `2s` and
/// `2s + 1`), then the two caps as fans about their centres. Outward CCW triangles.
pub fn cylinder(r: Real, h: Real, segments: usize) -> TriMesh {
    layered_cylinder(r, h, segments, 1)
}

/// [`cylinder`] with its wall in `layers` rows of quads (row by row, two triangles a quad).
pub fn layered_cylinder(r: Real, h: Real, segments: usize, layers: usize) -> TriMesh {
    let n = segments as u32;
    let rows = layers.max(1) as u32;
    let mut v = Vec::with_capacity((layers + 1) * segments + 2);
    for k in 0..=rows {
        let z = h * Real::from(k) / Real::from(rows);
        for s in 0..segments {
            let a = std::f64::consts::TAU * s as Real / segments as Real;
            v.push(Vec3::new(r * a.cos(), r * a.sin(), z));
        }
    }
    v.push(Vec3::zeros());
    v.push(Vec3::new(0.0, 0.0, h));
    let (bottom, top) = ((rows + 1) * n, (rows + 1) * n + 1);
    let mut t = Vec::with_capacity(2 * segments * (layers + 1));
    for k in 0..rows {
        let (lo, hi) = (k * n, (k + 1) * n);
        for s in 0..n {
            let s1 = (s + 1) % n;
            t.push([lo + s, lo + s1, hi + s1]);
            t.push([lo + s, hi + s1, hi + s]);
        }
    }
    let last = rows * n;
    for s in 0..n {
        let s1 = (s + 1) % n;
        t.push([bottom, s1, s]);
        t.push([top, last + s, last + s1]);
    }
    mesh(v, t)
}

/// A closed slab whose top is a wavy height field over the square `|x|, |y| ≤ half_m`: the sum
/// of `amplitude_m · sin(2π x / λ + φ) · cos(2π y / λ + ψ)` over `waves` (`(λ, φ, ψ)`), on a
/// grid of `n × n` quads (their diagonals alternating), over a flat bottom at `z = −depth_m`.
/// Outward CCW triangles.
pub fn wavy_slab(
    half_m: Real,
    n: usize,
    amplitude_m: Real,
    waves: &[(Real, Real, Real)],
    depth_m: Real,
) -> TriMesh {
    let tau = std::f64::consts::TAU;
    let height = |x: Real, y: Real| {
        waves
            .iter()
            .map(|&(l, p, q)| amplitude_m * (tau * x / l + p).sin() * (tau * y / l + q).cos())
            .sum::<Real>()
    };
    let side = n as u32 + 1;
    let at = |k: u32| -half_m + 2.0 * half_m * Real::from(k) / n as Real;
    let mut v = Vec::with_capacity((n + 1) * (n + 1) + 4 * n + 1);
    for i in 0..side {
        for j in 0..side {
            v.push(Vec3::new(at(i), at(j), height(at(i), at(j))));
        }
    }
    let id = |i: u32, j: u32| i * side + j;
    let mut t = Vec::with_capacity(2 * n * n + 12 * n);
    for i in 0..side - 1 {
        for j in 0..side - 1 {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                t.extend([[a, b, c], [a, c, d]]);
            } else {
                t.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    // The rim, counter-clockwise seen from above, walled down to the bottom.
    let last = side - 1;
    let rim: Vec<u32> = (0..last)
        .map(|i| id(i, 0))
        .chain((0..last).map(|j| id(last, j)))
        .chain((1..=last).rev().map(|i| id(i, last)))
        .chain((1..=last).rev().map(|j| id(0, j)))
        .collect();
    let base = v.len() as u32;
    for &r in &rim {
        let p = v[r as usize];
        v.push(Vec3::new(p.x, p.y, -depth_m));
    }
    let m = rim.len() as u32;
    for k in 0..m {
        let (a, b) = (rim[k as usize], rim[((k + 1) % m) as usize]);
        let (a2, b2) = (base + k, base + (k + 1) % m);
        t.extend([[a, a2, b2], [a, b2, b]]);
    }
    let centre = v.len() as u32;
    v.push(Vec3::new(0.0, 0.0, -depth_m));
    for k in 0..m {
        t.push([centre, base + (k + 1) % m, base + k]);
    }
    mesh(v, t)
}

/// A plate's face in the plane z = 0, facing `+z`, around a round hole of radius `r_in`:
/// `segments` quads from the hole's circle out to `outer_m(cos, sin)` along the same ray (the
/// ray of vertex `s` at the angle `2π (s + phase) / segments`), each split in two (long thin
/// triangles, as a plate's face around a drilled hole is meshed).
pub fn drilled_face(
    r_in: Real,
    segments: usize,
    phase: Real,
    outer_m: impl Fn(Real, Real) -> Real,
) -> TriMesh {
    let n = segments as u32;
    let mut v = Vec::new();
    for outer in [false, true] {
        for s in 0..segments {
            let a = std::f64::consts::TAU * (s as Real + phase) / segments as Real;
            let (c, d) = (a.cos(), a.sin());
            let r = if outer { outer_m(c, d) } else { r_in };
            v.push(Vec3::new(r * c, r * d, 0.0));
        }
    }
    let mut t = Vec::new();
    for s in 0..n {
        let s1 = (s + 1) % n;
        t.push([s, s1, n + s1]);
        t.push([s, n + s1, n + s]);
    }
    mesh(v, t)
}

/// A flat ring in the plane z = 0, facing `+z`, between radii `r_in` and `r_out`
/// ([`drilled_face`]).
pub fn annulus(r_in: Real, r_out: Real, segments: usize) -> TriMesh {
    drilled_face(r_in, segments, 0.0, |_, _| r_out)
}
