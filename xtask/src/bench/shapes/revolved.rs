//! Surfaces of revolution about z: a ball and the spherical socket it turns in (a ball joint,
//! contact over a conforming concave patch), a ring and the cone it seats on (a valve seat, a
//! line contact all around whose sideways pushes cancel).
//!
//! Each is a profile in the `(r, z)` half-plane swept about z in `segments` steps: a polyline
//! from a pole on the axis to another (a ball, a socket, a cone: closed by its poles), or a
//! closed loop off the axis (a ring). The profile is walked so that the solid lies to its right,
//! counter-clockwise for a loop, and the triangles face out.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use haptic_collision::TriMesh;
use haptic_core::{Real, Vec3};

use super::{build, check_below, check_density, check_positive, ensure_indexable};

/// Segments about the axis of a ball, a socket and a cone at density 1.
const SEGMENTS: usize = 48;
/// Rows along a quarter circle of a ball's or a socket's profile at density 1.
const QUARTER_ROWS: usize = 12;
/// Segments about a ring's axis at density 1.
const RING_SEGMENTS: usize = 64;
/// Segments about a ring's tube at density 1.
const TUBE_SEGMENTS: usize = 16;

/// The profile swept about z: `(r, z)` points, and whether the last joins the first.
struct Profile {
    points: Vec<[Real; 2]>,
    closed: bool,
}

/// The mesh of `profile` swept about z in `segments` steps. Points on the axis (`r = 0`, only
/// at the ends of an open profile) are one vertex each, and the triangles that would collapse
/// there are left out.
fn revolve(what: &str, profile: &Profile, segments: usize) -> anyhow::Result<TriMesh> {
    let points = &profile.points;
    ensure_indexable(points.len() * segments)?;
    let mut vertices = Vec::with_capacity(points.len() * segments);
    // The vertex of each profile point at each step about the axis.
    let mut ids = Vec::with_capacity(points.len());
    for &[r, z] in points {
        let first = vertices.len() as u32;
        if r == 0.0 {
            vertices.push(Vec3::new(0.0, 0.0, z));
            ids.push((first, false));
        } else {
            for i in 0..segments {
                let theta = TAU * (i as Real / segments as Real);
                vertices.push(Vec3::new(r * theta.cos(), r * theta.sin(), z));
            }
            ids.push((first, true));
        }
    }
    let id = |k: usize, i: usize| {
        let (first, around) = ids[k];
        if around {
            first + (i % segments) as u32
        } else {
            first
        }
    };
    let spans = if profile.closed {
        points.len()
    } else {
        points.len() - 1
    };
    let mut triangles = Vec::with_capacity(2 * spans * segments);
    for k in 0..spans {
        let next = (k + 1) % points.len();
        for i in 0..segments {
            // Along the circle, then along the profile: (∂θ × ∂s) faces out.
            let (a, b) = (id(k, i), id(k, i + 1));
            let (c, d) = (id(next, i + 1), id(next, i));
            for t in [[a, b, c], [a, c, d]] {
                if t[0] != t[1] && t[1] != t[2] && t[2] != t[0] {
                    triangles.push(t);
                }
            }
        }
    }
    build(what, vertices, triangles)
}

/// `rows + 1` points of the arc of radius `radius_m` about `(0, z0_m)` from the angle `from` to
/// `to` (from the −z axis towards +r), the ends included.
fn arc(radius_m: Real, z0_m: Real, from: Real, to: Real, rows: usize) -> Vec<[Real; 2]> {
    (0..=rows)
        .map(|j| {
            let a = from + (to - from) * (j as Real / rows as Real);
            // Exactly on the axis at the poles.
            let r = if a == 0.0 || a == PI {
                0.0
            } else {
                radius_m * a.sin()
            };
            [r, z0_m - radius_m * a.cos()]
        })
        .collect()
}

/// A closed ball of radius `radius_m` centred at the origin: a UV sphere of `48·density`
/// segments about z and `24·density` rows from pole to pole, `96·density·(24·density − 1)`
/// triangles (2,208 at density 1).
///
/// # Errors
/// A radius that is not positive and finite, or `density == 0`.
pub fn ball(radius_m: Real, density: usize) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("radius_m", radius_m)?;
    let profile = Profile {
        points: arc(radius_m, 0.0, 0.0, PI, 2 * QUARTER_ROWS * density),
        closed: false,
    };
    revolve("ball", &profile, SEGMENTS * density)
}

/// A closed spherical socket opening up (+z), its cavity a hemisphere of `inner_radius_m`
/// about the origin: a hemispherical shell out to `outer_radius_m` with a flat rim at `z = 0`.
/// `48·density` segments about z, `12·density` rows along each quarter arc;
/// `2304·density²` triangles.
///
/// # Errors
/// Radii that are not positive and finite, `inner ≥ outer`, or `density == 0`.
pub fn socket(
    inner_radius_m: Real,
    outer_radius_m: Real,
    density: usize,
) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("inner_radius_m", inner_radius_m)?;
    check_positive("outer_radius_m", outer_radius_m)?;
    check_below(
        "inner_radius_m",
        inner_radius_m,
        "outer_radius_m",
        outer_radius_m,
    )?;
    let rows = QUARTER_ROWS * density;
    // Up the outside to the rim, across it, down the cavity to its bottom.
    let mut points = arc(outer_radius_m, 0.0, 0.0, FRAC_PI_2, rows);
    let mut inside = arc(inner_radius_m, 0.0, 0.0, FRAC_PI_2, rows);
    inside.reverse();
    points.extend(inside);
    let profile = Profile {
        points,
        closed: false,
    };
    revolve("socket", &profile, SEGMENTS * density)
}

/// A closed ring (torus) about z centred at the origin: a tube of radius `tube_radius_m` about
/// the circle of `radius_m`, `64·density` segments about z and `16·density` about the tube,
/// `2048·density²` triangles.
///
/// # Errors
/// Radii that are not positive and finite, `tube ≥ radius`, or `density == 0`.
pub fn ring(radius_m: Real, tube_radius_m: Real, density: usize) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("radius_m", radius_m)?;
    check_positive("tube_radius_m", tube_radius_m)?;
    check_below("tube_radius_m", tube_radius_m, "radius_m", radius_m)?;
    let n = TUBE_SEGMENTS * density;
    // Counter-clockwise in (r, z), from the outermost point.
    let points = (0..n)
        .map(|j| {
            let a = TAU * (j as Real / n as Real);
            [radius_m + tube_radius_m * a.cos(), tube_radius_m * a.sin()]
        })
        .collect();
    let profile = Profile {
        points,
        closed: true,
    };
    revolve("ring", &profile, RING_SEGMENTS * density)
}

/// A closed cone about z standing on its base at `z = 0`, of base radius `radius_m` and apex at
/// `z = height_m`: `48·density` segments about z, its side and its base each in `4·density`
/// rows; `48·density·(16·density − 2)` triangles (672 at density 1).
///
/// # Errors
/// Sizes that are not positive and finite, or `density == 0`.
pub fn cone(radius_m: Real, height_m: Real, density: usize) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("radius_m", radius_m)?;
    check_positive("height_m", height_m)?;
    let rows = 4 * density;
    let step = |j: usize| j as Real / rows as Real;
    // Out across the base, then up the side to the apex.
    let points = (0..=rows)
        .map(|j| [radius_m * step(j), 0.0])
        .chain((1..=rows).map(|j| [radius_m * (1.0 - step(j)), height_m * step(j)]))
        .collect();
    let profile = Profile {
        points,
        closed: false,
    };
    revolve("cone", &profile, SEGMENTS * density)
}
