//! A round peg and the bushing it slides in: close-fitting walls whose tessellations line up
//! nowhere (the peg's and the bushing's numbers of segments have no common factor but 1 or 2),
//! so that their contacts push nearly all ways at once and cancel.

use haptic_collision::TriMesh;
use haptic_core::Real;

use super::{
    build, check_below, check_density, check_positive, ensure_indexable, lateral_grid, star_prism,
};

/// Segments around the peg at density 1.
const PEG_SEGMENTS: usize = 40;
/// Segments around the bushing at density 1 (prime to the peg's 40).
const BUSHING_SEGMENTS: usize = 33;

/// A closed round peg along z, `z ∈ [−length/2, length/2]`: a prism over the regular polygon of
/// `40·density` vertices on the circle of `radius_m`, its wall in `4·density` layers, its ends
/// fans about the axis. `80·density·(4·density + 1)` triangles (400 at density 1).
///
/// # Errors
/// Sizes that are not positive and finite, or `density == 0`.
pub fn round_peg(radius_m: Real, length_m: Real, density: usize) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("radius_m", radius_m)?;
    check_positive("length_m", length_m)?;
    let n = PEG_SEGMENTS * density;
    let outline: Vec<[Real; 2]> = (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * (i as Real / n as Real);
            [radius_m * a.cos(), radius_m * a.sin()]
        })
        .collect();
    star_prism("round peg", &outline, length_m, 4 * density)
}

/// A closed bushing along z, from `z = 0` to `length_m`: a tube of bore `bore_radius_m` and
/// outside `outer_radius_m`, both walls regular polygons of `33·density` vertices on their
/// circles in `5·density` rows of quads (the bore's facing the axis), its ends rings of one quad
/// a segment. `132·density·(5·density + 1)` triangles (792 at density 1).
///
/// # Errors
/// Sizes that are not positive and finite, `bore ≥ outer`, or `density == 0`.
pub fn bushing(
    bore_radius_m: Real,
    outer_radius_m: Real,
    length_m: Real,
    density: usize,
) -> anyhow::Result<TriMesh> {
    check_density(density)?;
    check_positive("bore_radius_m", bore_radius_m)?;
    check_positive("outer_radius_m", outer_radius_m)?;
    check_positive("length_m", length_m)?;
    check_below(
        "bore_radius_m",
        bore_radius_m,
        "outer_radius_m",
        outer_radius_m,
    )?;
    let segments = BUSHING_SEGMENTS * density;
    let layers = 5 * density;
    ensure_indexable(2 * segments * (layers + 1))?;
    let rows: Vec<Real> = (0..=layers)
        .map(|j| length_m * (j as Real / layers as Real))
        .collect();
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    let bore = lateral_grid(
        &mut vertices,
        &mut triangles,
        segments,
        &rows,
        |_, _| bore_radius_m,
        false,
    );
    let outside = lateral_grid(
        &mut vertices,
        &mut triangles,
        segments,
        &rows,
        |_, _| outer_radius_m,
        true,
    );
    let (bottom, top) = (0, bore.last_row());
    for i in 0..segments {
        // The top ring faces +z, the bottom one −z: (outward × along the circle) is +z.
        let (b0, b1) = (bore.id(top, i), bore.id(top, i + 1));
        let (o0, o1) = (outside.id(top, i), outside.id(top, i + 1));
        triangles.push([b0, o0, o1]);
        triangles.push([b0, o1, b1]);
        let (b0, b1) = (bore.id(bottom, i), bore.id(bottom, i + 1));
        let (o0, o1) = (outside.id(bottom, i), outside.id(bottom, i + 1));
        triangles.push([b0, o1, o0]);
        triangles.push([b0, b1, o1]);
    }
    build("bushing", vertices, triangles)
}
