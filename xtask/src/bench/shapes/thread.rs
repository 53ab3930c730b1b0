//! A threaded rod and its nut, tessellated along the thread.
//!
//! The thread's surface is `r(θ, z)`, the profile (a symmetric trapezoid) at the phase
//! `s = fract(z/pitch − θ/2π)`. Its corners (crest to flank, flank to root) run along helices of
//! constant phase, so the vertices lie on helical rows: for each of `32·density` angles, one
//! vertex per row phase `φ_q` of every pitch, the profile's four corners among them. Every facet
//! then lies between two neighbouring rows, on one face of the profile (the crest, a flank or the
//! root), and stays within the chord's sagitta of the surface, however coarse the tessellation:
//! two tessellations of the same thread are the same shape to well within a fit's clearance. A
//! grid of constant-z rows (the obvious tessellation) cuts the corners instead, by up to 0.15 mm
//! on an M8-like thread at 32 segments around, more than a 0.1 mm clearance
//! (`docs/experiments/lod-accuracy-and-speed-probes.md`, probes 13 and 17).
//!
//! The ends are cut at `z = 0` and `z = length`: each angle's column of vertices starts and ends
//! there, and the facets between an end and the first helical row are the only ones that cross a
//! corner of the profile.

use std::f64::consts::TAU;

use anyhow::ensure;
use haptic_collision::TriMesh;
use haptic_core::{Real, Vec3};

use super::{build, check_below, check_density, check_positive, ensure_indexable, lateral_grid};

/// An externally threaded rod (a bolt without head), axis z from 0 to `length_m`, with a
/// right-handed single-start thread (the crest climbs one pitch per counter-clockwise turn
/// about +z).
///
/// The lateral surface is `r(θ, z)` = the thread profile at the phase
/// `s = fract((z − pitch·θ/2π)/pitch)`: a symmetric trapezoid with a flat crest of 1/8 pitch at
/// the major radius, a flat root of 1/4 pitch at the minor radius, and straight flanks between.
///
/// - `major_radius_m`: crest radius (m); `minor_radius_m`: root radius (m), `0 < minor < major`.
/// - `pitch_m`: axial distance between neighbouring crests (m); `length_m`: rod length (m).
/// - `density`: `32·density` segments around and `9·density` helical rows a pitch (the module
///   docs), cut at both ends; the ends are fans to a vertex on the axis. About
///   `64·density·(9·density·length/pitch + 2)` triangles (9 344 for the M8-like rod of 16
///   pitches at density 1, 37 120 at density 2).
///
/// A [`threaded_nut`] of the same thread and density, placed on the rod at an axial offset that
/// is a whole number of pitches, has its inner vertices on the rod's helical rows and angles.
///
/// # Errors
/// Sizes that are not positive and finite, `minor ≥ major`, `density == 0`, or too many vertices
/// for `u32` indices.
pub fn threaded_rod(
    major_radius_m: Real,
    minor_radius_m: Real,
    pitch_m: Real,
    length_m: Real,
    density: usize,
) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("length_m", length_m)?;
    let thread = ThreadProfile::new(major_radius_m, minor_radius_m, pitch_m)?;
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let side = HelicalGrid::append(
        &mut vertices,
        &mut triangles,
        &thread,
        length_m,
        density,
        0.0,
        true,
    )?;
    ensure_indexable(vertices.len() + 2)?;
    let (bottom, top) = (vertices.len() as u32, vertices.len() as u32 + 1);
    vertices.push(Vec3::zeros());
    vertices.push(Vec3::new(0.0, 0.0, length_m));
    for i in 0..side.segments() {
        triangles.push([bottom, side.bottom(i + 1), side.bottom(i)]);
        triangles.push([top, side.top(i), side.top(i + 1)]);
    }
    build("threaded rod", vertices, triangles)
}

/// A cylindrical nut, axis z from 0 to `length_m`, whose internal thread mates
/// [`threaded_rod`]'s: the inner surface is `r_in(θ, z) = r(θ, z) + clearance` with the rod's
/// profile `r` and phase convention, so a rod of the same thread at the identity pose sits in the
/// nut with a radial gap of `clearance_m` everywhere.
///
/// - `major_radius_m`, `minor_radius_m`, `pitch_m`: the mating rod's thread (m).
/// - `length_m`: nut length along z (m).
/// - `outer_radius_m`: radius of the outer cylinder (m), more than `major + clearance`.
/// - `clearance_m`: radial gap to the rod (m, ≥ 0).
/// - `density`: inner surface on the rod's helical rows and angles (the module docs); outer
///   cylinder with the same `32·density` angles and `2·density` rows; flat annular end caps
///   joining the inner and outer rings with one quad per segment. About
///   `64·density·(9·density·length/pitch + 2·density + 3)` triangles (3 904 for an 8 mm nut of
///   1.25 mm pitch at density 1, 15 360 at density 2).
///
/// The inner surface is the outside of the solid: its normals point towards the axis.
///
/// # Errors
/// Sizes that are not positive and finite, `minor ≥ major`, a negative clearance, an outer
/// radius not above `major + clearance`, `density == 0`, or too many vertices for `u32` indices.
pub fn threaded_nut(
    major_radius_m: Real,
    minor_radius_m: Real,
    pitch_m: Real,
    length_m: Real,
    outer_radius_m: Real,
    clearance_m: Real,
    density: usize,
) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("length_m", length_m)?;
    let thread = ThreadProfile::new(major_radius_m, minor_radius_m, pitch_m)?;
    ensure!(
        clearance_m.is_finite() && clearance_m >= 0.0,
        "clearance_m = {clearance_m} must be finite and not negative"
    );
    ensure!(
        outer_radius_m.is_finite() && outer_radius_m > major_radius_m + clearance_m,
        "outer_radius_m = {outer_radius_m} must exceed major_radius_m + clearance_m = {}",
        major_radius_m + clearance_m
    );
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let inner = HelicalGrid::append(
        &mut vertices,
        &mut triangles,
        &thread,
        length_m,
        density,
        clearance_m,
        false,
    )?;
    let segments = inner.segments();
    let outer_layers = 2 * density;
    let outer_rows: Vec<Real> = (0..=outer_layers)
        .map(|j| length_m * (j as Real / outer_layers as Real))
        .collect();
    ensure_indexable(vertices.len() + segments * outer_rows.len())?;
    let outer = lateral_grid(
        &mut vertices,
        &mut triangles,
        segments,
        &outer_rows,
        |_, _| outer_radius_m,
        true,
    );
    let outer_top = outer.last_row();
    for k in 0..segments {
        let (i0, i1) = (inner.bottom(k), inner.bottom(k + 1));
        let (o0, o1) = (outer.id(0, k), outer.id(0, k + 1));
        // Bottom cap, normal −z.
        triangles.push([i0, o1, o0]);
        triangles.push([i0, i1, o1]);
        let (i0, i1) = (inner.top(k), inner.top(k + 1));
        let (o0, o1) = (outer.id(outer_top, k), outer.id(outer_top, k + 1));
        // Top cap, normal +z.
        triangles.push([i0, o0, o1]);
        triangles.push([i0, o1, i1]);
    }
    build("threaded nut", vertices, triangles)
}

/// The thread of [`threaded_rod`] and [`threaded_nut`].
#[derive(Debug, Clone, Copy)]
pub(super) struct ThreadProfile {
    /// Crest radius (m).
    major: Real,
    /// Root radius (m).
    minor: Real,
    /// Axial distance between crests (m).
    pub(super) pitch: Real,
}

impl ThreadProfile {
    /// Length of the crest flat, in pitches.
    const CREST: Real = 1.0 / 8.0;
    /// Length of each flank, in pitches.
    const FLANK: Real = 5.0 / 16.0;
    /// Length of the root flat, in pitches.
    const ROOT: Real = 1.0 / 4.0;

    /// A thread of crest radius `major` (m), root radius `minor` (m) and pitch `pitch` (m).
    pub(super) fn new(major: Real, minor: Real, pitch: Real) -> anyhow::Result<Self> {
        check_positive("minor_radius_m", minor)?;
        check_positive("major_radius_m", major)?;
        check_positive("pitch_m", pitch)?;
        check_below("minor_radius_m", minor, "major_radius_m", major)?;
        Ok(Self {
            major,
            minor,
            pitch,
        })
    }

    /// Height of the profile at phase `s` ∈ [0, 1] as a fraction of the thread depth: 1 on the
    /// crest (`s` ∈ [0, 1/8)), falling along a flank to 0 on the root ([7/16, 11/16)), rising
    /// back to 1 at `s = 1`.
    fn depth_fraction(s: Real) -> Real {
        let falling = Self::CREST;
        let root = falling + Self::FLANK;
        let rising = root + Self::ROOT;
        if s < falling {
            1.0
        } else if s < root {
            1.0 - (s - falling) / Self::FLANK
        } else if s < rising {
            0.0
        } else {
            (s - rising) / Self::FLANK
        }
    }

    /// Radius r(θ, z) (m) of the rod's thread surface at angle `theta` (rad) and height `z` (m).
    pub(super) fn radius(&self, theta: Real, z: Real) -> Real {
        let s = (z / self.pitch - theta / TAU).rem_euclid(1.0);
        self.minor + (self.major - self.minor) * Self::depth_fraction(s)
    }

    /// The phases in [0, 1) of the helical rows of a pitch at `density`: the profile's corners
    /// (0, 1/8, 7/16, 11/16) and, between them, the crest in `density` equal parts, each flank
    /// in `3·density` and the root in `2·density` (spacings of 1/8 to 5/48 of a pitch at
    /// density 1).
    pub(super) fn row_phases(density: usize) -> Vec<Real> {
        let faces = [
            (Self::CREST, density),
            (Self::FLANK, 3 * density),
            (Self::ROOT, 2 * density),
            (Self::FLANK, 3 * density),
        ];
        let mut phases = Vec::with_capacity(9 * density);
        let mut start = 0.0;
        for (length, parts) in faces {
            phases.extend((0..parts).map(|p| start + length * (p as Real / parts as Real)));
            start += length;
        }
        phases
    }
}

/// The vertex columns of a helical grid appended by [`HelicalGrid::append`]: per angle, its
/// vertices from `z = 0` up to `z = length`, each with its helical row (`None` at the ends).
#[derive(Debug, Clone)]
struct HelicalGrid {
    /// Per angle index (`32·density` of them): the column's vertex indices, bottom to top.
    columns: Vec<Vec<u32>>,
}

/// Where a column's vertex lies along the thread: an end of the column, or a helical row
/// (`pitch index × rows a pitch + phase index`), ordered bottom to top.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum RowKey {
    Bottom,
    Row(i64),
    Top,
}

impl HelicalGrid {
    /// Appends the surface `r(θ, z) + offset_m` of `thread` for `z ∈ [0, length]` on helical rows
    /// (the module docs), facing away from the axis if `outward`, towards it otherwise.
    ///
    /// Each column (angle `θ_i = 2π i/segments`) holds a vertex at `z = 0`, one on every helical
    /// row strictly inside (a row within a quarter of the least row spacing of an end is left
    /// out, so that no facet is a sliver), and one at `z = length`. Two neighbouring columns are
    /// joined by walking both upwards, always stepping the column whose next vertex lies on the
    /// lower helical row, so every facet spans one row interval of the thread.
    fn append(
        vertices: &mut Vec<Vec3>,
        triangles: &mut Vec<[u32; 3]>,
        thread: &ThreadProfile,
        length: Real,
        density: usize,
        offset_m: Real,
        outward: bool,
    ) -> anyhow::Result<Self> {
        let segments = 32 * density;
        let phases = ThreadProfile::row_phases(density);
        let per_pitch = phases.len() as i64;
        let least_spacing = phases
            .iter()
            .zip(phases.iter().skip(1).chain([&1.0]))
            .map(|(a, b)| b - a)
            .fold(Real::INFINITY, Real::min);
        let margin = 0.25 * least_spacing * thread.pitch;
        let pitches = (length / thread.pitch).ceil() as i64 + 1;
        ensure_indexable(segments * (phases.len() * (pitches as usize + 2) + 2))?;
        let mut keyed: Vec<Vec<(RowKey, u32)>> = Vec::with_capacity(segments + 1);
        for i in 0..segments {
            let turn = i as Real / segments as Real;
            let theta = TAU * turn;
            let mut column = Vec::new();
            let mut push = |key: RowKey, z: Real, column: &mut Vec<(RowKey, u32)>| {
                let r = thread.radius(theta, z) + offset_m;
                column.push((key, vertices.len() as u32));
                vertices.push(Vec3::new(r * theta.cos(), r * theta.sin(), z));
            };
            push(RowKey::Bottom, 0.0, &mut column);
            for m in -1..=pitches {
                for (q, phase) in phases.iter().enumerate() {
                    // On the helix of phase `phase`, a turn `turn` round from θ = 0.
                    let z = thread.pitch * (m as Real + phase + turn);
                    if z > margin && z < length - margin {
                        push(RowKey::Row(m * per_pitch + q as i64), z, &mut column);
                    }
                }
            }
            push(RowKey::Top, length, &mut column);
            keyed.push(column);
        }
        // Past a full turn, column 0 again: its row `k` is the row `k − per_pitch` of θ = 2π.
        let wrapped = keyed[0]
            .iter()
            .map(|&(key, id)| match key {
                RowKey::Row(k) => (RowKey::Row(k - per_pitch), id),
                end => (end, id),
            })
            .collect();
        keyed.push(wrapped);
        for pair in keyed.windows(2) {
            zip_columns(&pair[0], &pair[1], outward, triangles);
        }
        keyed.pop();
        Ok(Self {
            columns: keyed
                .into_iter()
                .map(|c| c.into_iter().map(|(_, id)| id).collect())
                .collect(),
        })
    }

    /// Number of angles.
    fn segments(&self) -> usize {
        self.columns.len()
    }

    /// The vertex at `z = 0` of column `i` (modulo the number of angles).
    fn bottom(&self, i: usize) -> u32 {
        self.columns[i % self.columns.len()][0]
    }

    /// The vertex at `z = length` of column `i` (modulo the number of angles).
    fn top(&self, i: usize) -> u32 {
        let column = &self.columns[i % self.columns.len()];
        column[column.len() - 1]
    }
}

/// Triangulates the strip between column `a` and the next column `b` (angle increasing), both
/// bottom to top: from the two bottoms, each step adds the vertex of lower [`RowKey`] (ties: `a`'s
/// first), so that a triangle never spans more than one helical row interval of either column.
fn zip_columns(a: &[(RowKey, u32)], b: &[(RowKey, u32)], outward: bool, out: &mut Vec<[u32; 3]>) {
    let (mut ia, mut ib) = (0, 0);
    while ia + 1 < a.len() || ib + 1 < b.len() {
        let step_a = ib + 1 == b.len() || (ia + 1 < a.len() && a[ia + 1].0 <= b[ib + 1].0);
        // θ then z: (a, b, next) is counter-clockwise seen from outside.
        let (p, q, r) = if step_a {
            ia += 1;
            (a[ia - 1].1, b[ib].1, a[ia].1)
        } else {
            ib += 1;
            (a[ia].1, b[ib - 1].1, b[ib].1)
        };
        out.push(if outward { [p, q, r] } else { [p, r, q] });
    }
}
