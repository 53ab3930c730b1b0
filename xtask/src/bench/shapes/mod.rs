//! Procedural closed triangle meshes for the collision benchmark suite: a box, an involute spur
//! gear (alone or as a meshing pair), a threaded rod and its nut, a round peg and its bushing,
//! a ball and its socket, a ring and a cone; and remeshed copies of any mesh (the same surface,
//! another tessellation).
//!
//! Every mesh is closed and watertight (every edge shared by exactly two triangles, vertices
//! shared along seams), its triangles counter-clockwise seen from outside, and it is built with
//! [`DegeneratePolicy::Reject`], so a degenerate triangle is an error rather than silently
//! dropped. Lengths are in metres, angles in radians.
//!
//! `density` scales the tessellation: 1 is the coarse one, 2 doubles the subdivisions in both
//! surface directions (about 4× the triangles), and so on.

use std::f64::consts::{PI, TAU};

use anyhow::{Context, ensure};
use haptic_collision::{DegeneratePolicy, TriMesh};
use haptic_core::{Real, Vec3};

mod remesh;
mod revolved;
mod round;
mod thread;

pub use remesh::{split_at_centroids, split_at_midpoints};
pub use revolved::{ball, cone, ring, socket};
pub use round::{bushing, round_peg};
#[cfg(test)]
use thread::ThreadProfile;
pub use thread::{threaded_nut, threaded_rod};

/// Pressure angle of the gears' involute flanks (rad): 20°.
const PRESSURE_ANGLE: Real = PI / 9.0;

/// An axis-aligned box centred at the origin.
///
/// - `half_extents`: half the box's size along x, y and z (m), each positive.
/// - `density`: each face is a grid of `4·density × 4·density` quads, two triangles each, so the
///   box has `192·density²` triangles.
///
/// # Errors
/// A half extent that is not positive and finite, `density == 0`, or too many vertices for `u32`
/// indices.
pub fn box_mesh(half_extents: Vec3, density: usize) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    for (name, &h) in ["half_extents.x", "half_extents.y", "half_extents.z"]
        .iter()
        .zip(half_extents.iter())
    {
        check_positive(name, h)?;
    }
    let n = 4 * density;
    ensure_indexable(6 * (n + 1) * (n + 1))?;
    // Lattice coordinate k ∈ 0..=n along `axis` → position (m); exact at both ends.
    let coordinate = |axis: usize, k: usize| {
        -half_extents[axis] + 2.0 * half_extents[axis] * (k as Real / n as Real)
    };
    // Surface vertices are the lattice points with a coordinate at 0 or n, each created once, so
    // the faces share their edges and corners.
    let mut index = std::collections::HashMap::<[usize; 3], u32>::new();
    let mut vertices = Vec::new();
    let mut vertex = |k: [usize; 3]| -> u32 {
        *index.entry(k).or_insert_with(|| {
            vertices.push(Vec3::new(
                coordinate(0, k[0]),
                coordinate(1, k[1]),
                coordinate(2, k[2]),
            ));
            (vertices.len() - 1) as u32
        })
    };
    let mut triangles = Vec::with_capacity(12 * n * n);
    for axis in 0..3 {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, n] {
            // Face axes (u, v) with u × v along the outward normal: e_b × e_c = +e_axis.
            let (u, v) = if side == n { (b, c) } else { (c, b) };
            for i in 0..n {
                for j in 0..n {
                    let corner = |di: usize, dj: usize| {
                        let mut k = [0; 3];
                        k[axis] = side;
                        k[u] = i + di;
                        k[v] = j + dj;
                        k
                    };
                    let p00 = vertex(corner(0, 0));
                    let p10 = vertex(corner(1, 0));
                    let p11 = vertex(corner(1, 1));
                    let p01 = vertex(corner(0, 1));
                    triangles.push([p00, p10, p11]);
                    triangles.push([p00, p11, p01]);
                }
            }
        }
    }
    build("box", vertices, triangles)
}

/// A spur gear with involute teeth, centred at the origin, axis z, faces at `z = ±face_width/2`.
///
/// Tooth 0 is centred on +x. Standard proportions: pitch radius `m·z/2`, addendum `m`, dedendum
/// `1.25·m`, 20° pressure angle, tooth thickness half the circular pitch at the pitch circle.
/// The flanks are involutes of the base circle; below the base circle (gears of up to 41 teeth)
/// they continue as a short fillet that widens the tooth quadratically towards the root circle,
/// by a quarter of the remaining gap (clear of the mating tip's path in the meshing test, at
/// 0.19 mm clearance). The outline is star-shaped about the centre
/// (its polar angle increases strictly along it), so the caps are fans from the centre.
///
/// - `teeth`: number of teeth `z` (at least 3).
/// - `module_m`: module `m` (m), the pitch diameter per tooth.
/// - `face_width_m`: thickness along z (m).
/// - `density`: per tooth, `8·density` outline points per flank and `4·density` per tip and root
///   arc (`24·density` per tooth); side wall with `4·density` layers along z. Triangles:
///   `48·density·teeth·(4·density + 1)` (4 800 at 20 teeth, density 1; 17 280 at density 2).
///
/// # Errors
/// Non-positive or non-finite sizes, fewer than 3 teeth, teeth so few that they come to a point
/// or leave no root gap, `density == 0`, or too many vertices for `u32` indices.
pub fn spur_gear(
    teeth: usize,
    module_m: Real,
    face_width_m: Real,
    density: usize,
) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("face_width_m", face_width_m)?;
    let profile = GearProfile::new(teeth, module_m)?;
    // 4·density layers rather than 2·density: with fan caps (which refine only around), doubling
    // the density then multiplies the triangle count by 3.6 instead of 3.3.
    star_prism(
        "spur gear",
        &profile.outline(density),
        face_width_m,
        4 * density,
    )
}

/// Two meshing spur gears of the same module and face width: gear a at the origin (as
/// [`spur_gear`]), gear b at distance `m·(z_a + z_b)/2 + clearance` along +x, rotated about z so
/// that its teeth sit centred in a's gaps.
///
/// - `teeth_a`, `teeth_b`: numbers of teeth.
/// - `module_m`: module (m); `face_width_m`: thickness along z (m).
/// - `clearance_m`: extra centre distance (m, ≥ 0). It opens a radial tip clearance of
///   `0.25·m + clearance` and, per flank, a backlash of about `clearance·sin 20°` normal to the
///   flanks; 0 puts the flanks in tangent contact.
/// - `density`: as [`spur_gear`].
///
/// Returns `(a, b, centre_b, angle_b)`: both meshes in their own frames (each centred at its
/// origin), and b's pose in a's frame: a point `p` of b is at `centre_b + R_z(angle_b)·p`
/// (`centre_b` in m, `angle_b` in rad, in `[0, 2π/z_b)`).
///
/// # Errors
/// As [`spur_gear`], or a clearance that is negative or not finite.
pub fn gear_pair(
    teeth_a: usize,
    teeth_b: usize,
    module_m: Real,
    face_width_m: Real,
    clearance_m: Real,
    density: usize,
) -> anyhow::Result<(TriMesh, TriMesh, Vec3, Real)> {
    ensure!(
        clearance_m.is_finite() && clearance_m >= 0.0,
        "clearance_m = {clearance_m} must be finite and not negative"
    );
    let a = spur_gear(teeth_a, module_m, face_width_m, density).context("gear a")?;
    let b = spur_gear(teeth_b, module_m, face_width_m, density).context("gear b")?;
    let (centre, angle) = gear_pair_pose(teeth_a, teeth_b, module_m, clearance_m);
    Ok((a, b, centre, angle))
}

/// Pose of gear b in gear a's frame for [`gear_pair`]: centre (m) and rotation about z (rad).
fn gear_pair_pose(
    teeth_a: usize,
    teeth_b: usize,
    module_m: Real,
    clearance_m: Real,
) -> (Vec3, Real) {
    let distance = module_m * (teeth_a + teeth_b) as Real / 2.0 + clearance_m;
    // Gear a's tooth 0 lies on +x, on the line of centres, facing b. Gear b must therefore show
    // the centre of a gap in that direction, which is angle π in b's own frame. b's teeth are
    // centred at β + k·2π/z_b and its gaps half a tooth pitch further, at β + (k + ½)·2π/z_b.
    // Solving β + (k + ½)·2π/z_b = π: β = π − π/z_b modulo b's pitch 2π/z_b. With z_b odd, π is
    // an odd number of half pitches, so b's gaps already lie at π and β = 0; with z_b even, π is
    // a whole number of pitches (a tooth faces a), so b turns by half a pitch, β = π/z_b. The
    // pair is then symmetric about the x axis and the backlash is shared equally by both flanks.
    let angle = if teeth_b % 2 == 0 {
        PI / teeth_b as Real
    } else {
        0.0
    };
    (Vec3::new(distance, 0.0, 0.0), angle)
}

/// Tooth outline of an involute spur gear (see [`spur_gear`]), tooth 0 centred on +x.
#[derive(Debug, Clone, Copy)]
struct GearProfile {
    /// Number of teeth.
    teeth: usize,
    /// Root circle radius (m).
    root_radius: Real,
    /// Base circle radius (m), the involutes' origin.
    base_radius: Real,
    /// Tip (addendum) circle radius (m).
    tip_radius: Real,
    /// Half-angle of a tooth at the base circle (rad).
    base_half_angle: Real,
    /// Extra half-angle of the root fillet at the root circle (rad; 0 when the root circle is not
    /// below the base circle).
    fillet: Real,
}

/// The involute function `tan α − α` (rad).
fn involute(alpha: Real) -> Real {
    alpha.tan() - alpha
}

impl GearProfile {
    /// The profile of a gear of `teeth` teeth and module `module_m` (m).
    fn new(teeth: usize, module_m: Real) -> anyhow::Result<Self> {
        ensure!(teeth >= 3, "a gear needs at least 3 teeth, got {teeth}");
        check_positive("module_m", module_m)?;
        let z = teeth as Real;
        let pitch_radius = module_m * z / 2.0;
        let base_radius = pitch_radius * PRESSURE_ANGLE.cos();
        let root_radius = pitch_radius - 1.25 * module_m;
        // Half the tooth thickness at the pitch circle is a quarter of the circular pitch, π/(2z);
        // the involute has turned by inv(α) between the base and the pitch circle.
        let base_half_angle = PI / (2.0 * z) + involute(PRESSURE_ANGLE);
        let fillet = if root_radius < base_radius {
            0.25 * (PI / z - base_half_angle)
        } else {
            0.0
        };
        let profile = Self {
            teeth,
            root_radius,
            base_radius,
            tip_radius: pitch_radius + module_m,
            base_half_angle,
            fillet,
        };
        ensure!(
            profile.half_angle(profile.tip_radius) > 0.0,
            "{teeth} teeth come to a point below the tip circle"
        );
        ensure!(
            profile.half_angle(root_radius) < PI / z
                && (root_radius >= base_radius || fillet > 0.0),
            "{teeth} teeth leave no gap at the root circle"
        );
        Ok(profile)
    }

    /// Half-angle (rad) of a tooth at radius `r` (m) between the root and the tip circle:
    /// strictly decreasing in `r`.
    fn half_angle(&self, r: Real) -> Real {
        if r >= self.base_radius {
            self.base_half_angle - involute((self.base_radius / r).acos())
        } else {
            let t = (self.base_radius - r) / (self.base_radius - self.root_radius);
            self.base_half_angle + self.fillet * t * t
        }
    }

    /// The outline's radius r(φ) (m) at the polar angle `phi` (rad).
    #[cfg(test)]
    fn radius(&self, phi: Real) -> Real {
        let pitch_angle = TAU / self.teeth as Real;
        let x = phi.rem_euclid(pitch_angle);
        // Angle from the nearest tooth's centre line, in [0, π/z].
        let local = x.min(pitch_angle - x);
        if local <= self.half_angle(self.tip_radius) {
            return self.tip_radius;
        }
        if local >= self.half_angle(self.root_radius) {
            return self.root_radius;
        }
        // On a flank: the half-angle decreases strictly with the radius, bisect for it.
        let (mut lo, mut hi) = (self.root_radius, self.tip_radius);
        for _ in 0..64 {
            let mid = lo + 0.5 * (hi - lo);
            if self.half_angle(mid) > local {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo + 0.5 * (hi - lo)
    }

    /// The outline as (x, y) points (m), counter-clockwise, polar angle strictly increasing. Per
    /// tooth: `4·density` points on the root arc before it, `8·density` up its leading flank
    /// (uniform in radius), `4·density` on its tip arc and `8·density` down its trailing flank;
    /// each piece includes its first point and not its last (the next piece's first).
    fn outline(&self, density: usize) -> Vec<[Real; 2]> {
        let (arc, flank) = (4 * density, 8 * density);
        let pitch_angle = TAU / self.teeth as Real;
        let root_half = self.half_angle(self.root_radius);
        let tip_half = self.half_angle(self.tip_radius);
        let span = self.tip_radius - self.root_radius;
        let frac = |i: usize, n: usize| i as Real / n as Real;
        let mut polar: Vec<(Real, Real)> = Vec::with_capacity(self.teeth * 2 * (arc + flank));
        for k in 0..self.teeth {
            let centre = pitch_angle * k as Real;
            // Root arc, from the previous tooth's trailing flank to this tooth's leading flank.
            let (a0, a1) = (centre - pitch_angle + root_half, centre - root_half);
            polar.extend((0..arc).map(|i| (self.root_radius, a0 + (a1 - a0) * frac(i, arc))));
            polar.extend((0..flank).map(|i| {
                let r = self.root_radius + span * frac(i, flank);
                (r, centre - self.half_angle(r))
            }));
            polar.extend((0..arc).map(|i| {
                (
                    self.tip_radius,
                    centre - tip_half + 2.0 * tip_half * frac(i, arc),
                )
            }));
            polar.extend((0..flank).map(|i| {
                let r = self.tip_radius - span * frac(i, flank);
                (r, centre + self.half_angle(r))
            }));
        }
        polar
            .into_iter()
            .map(|(r, a)| [r * a.cos(), r * a.sin()])
            .collect()
    }
}

/// A closed prism along z, `z ∈ [−height/2, height/2]`, over an outline (m) that is
/// counter-clockwise and star-shaped about the origin: side wall with `layers` layers, caps as
/// fans from a vertex on the axis.
fn star_prism(
    what: &str,
    outline: &[[Real; 2]],
    height: Real,
    layers: usize,
) -> anyhow::Result<TriMesh> {
    let n = outline.len();
    ensure_indexable(n * (layers + 1) + 2)?;
    let half = height / 2.0;
    let mut vertices = Vec::with_capacity(n * (layers + 1) + 2);
    for j in 0..=layers {
        let z = -half + height * (j as Real / layers as Real);
        vertices.extend(outline.iter().map(|&[x, y]| Vec3::new(x, y, z)));
    }
    let (bottom, top) = (vertices.len() as u32, vertices.len() as u32 + 1);
    vertices.push(Vec3::new(0.0, 0.0, -half));
    vertices.push(Vec3::new(0.0, 0.0, half));
    let id = |j: usize, i: usize| (j * n + i % n) as u32;
    let mut triangles = Vec::with_capacity(2 * n * (layers + 1));
    for j in 0..layers {
        for i in 0..n {
            // Along the outline then up: (edge × z) points out of a counter-clockwise outline.
            let (a, b, c, d) = (id(j, i), id(j, i + 1), id(j + 1, i + 1), id(j + 1, i));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    for i in 0..n {
        triangles.push([bottom, id(0, i + 1), id(0, i)]);
        triangles.push([top, id(layers, i), id(layers, i + 1)]);
    }
    build(what, vertices, triangles)
}

/// Vertices of a lateral grid appended by [`lateral_grid`]: row `j`, angle index `i`.
#[derive(Debug, Clone, Copy)]
struct Grid {
    /// Index of the grid's first vertex.
    first: usize,
    /// Vertices per row.
    segments: usize,
    /// Number of rows.
    rows: usize,
}

impl Grid {
    /// Index of the vertex in row `j` at angle index `i` (taken modulo `segments`, so the seam
    /// at θ = 2π reuses the vertices at θ = 0).
    fn id(&self, j: usize, i: usize) -> u32 {
        (self.first + j * self.segments + i % self.segments) as u32
    }

    /// Index of the last row.
    fn last_row(&self) -> usize {
        self.rows - 1
    }
}

/// Appends a surface of revolution-like grid `r(θ, z)` (m) sampled at the angles
/// `θ_i = 2π·i/segments` and the heights `rows` (m, increasing), with its quads as two
/// triangles each, facing away from the axis if `outward`, towards it otherwise. The caller has
/// checked that the indices fit `u32`.
fn lateral_grid(
    vertices: &mut Vec<Vec3>,
    triangles: &mut Vec<[u32; 3]>,
    segments: usize,
    rows: &[Real],
    radius: impl Fn(Real, Real) -> Real,
    outward: bool,
) -> Grid {
    let grid = Grid {
        first: vertices.len(),
        segments,
        rows: rows.len(),
    };
    for &z in rows {
        for i in 0..segments {
            let theta = TAU * (i as Real / segments as Real);
            let r = radius(theta, z);
            vertices.push(Vec3::new(r * theta.cos(), r * theta.sin(), z));
        }
    }
    for j in 0..rows.len().saturating_sub(1) {
        for i in 0..segments {
            let (a, b) = (grid.id(j, i), grid.id(j, i + 1));
            let (c, d) = (grid.id(j + 1, i + 1), grid.id(j + 1, i));
            // θ then z: ∂θ × ∂z points away from the axis.
            if outward {
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            } else {
                triangles.push([a, c, b]);
                triangles.push([a, d, c]);
            }
        }
    }
    grid
}

/// The validated mesh, degenerate triangles rejected (none are expected).
fn build(what: &str, vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> anyhow::Result<TriMesh> {
    let (mesh, _dropped) = TriMesh::new(vertices, triangles, DegeneratePolicy::Reject)
        .with_context(|| format!("building the {what} mesh"))?;
    Ok(mesh)
}

/// Checks that the tessellation density is at least 1.
fn check_density(density: usize) -> anyhow::Result<()> {
    ensure!(density >= 1, "density must be at least 1, got {density}");
    Ok(())
}

/// Checks that a size is positive and finite.
fn check_positive(what: &str, value: Real) -> anyhow::Result<()> {
    ensure!(
        value.is_finite() && value > 0.0,
        "{what} = {value} must be positive and finite"
    );
    Ok(())
}

/// Checks that the size `what` is below the size `limit_what` (both already checked positive).
fn check_below(what: &str, value: Real, limit_what: &str, limit: Real) -> anyhow::Result<()> {
    ensure!(
        value < limit,
        "{what} = {value} must be below {limit_what} = {limit}"
    );
    Ok(())
}

/// Checks that `count` vertices can be addressed by `u32` indices.
fn ensure_indexable(count: usize) -> anyhow::Result<()> {
    ensure!(
        u32::try_from(count).is_ok(),
        "{count} vertices do not fit u32 indices: lower the density"
    );
    Ok(())
}

#[cfg(test)]
mod tests;
