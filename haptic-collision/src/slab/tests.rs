use super::*;
use proptest::prelude::*;

const DELTA: Real = 1e-3;

/// The square `[x0, x0 + size] × [y0, y0 + size]` at height `z`, counter-clockwise about `+z`.
fn square(x0: Real, y0: Real, size: Real, z: Real) -> [Vec3; 4] {
    [
        Vec3::new(x0, y0, z),
        Vec3::new(x0 + size, y0, z),
        Vec3::new(x0 + size, y0 + size, z),
        Vec3::new(x0, y0 + size, z),
    ]
}

/// `(∫g, ∫g x, ∫g²)` of a region as its contact stands for it.
fn sums_of(r: &RegionContact) -> (Real, Vec3, Real) {
    let g = r.area_m2 * (r.depth_m + DELTA);
    (g, r.centroid * g, g * (r.depth_m + DELTA))
}

/// A square `[x0, x0 + side]²` at `z = 0` split into `k × k` cells of two triangles each,
/// counter-clockwise about `+z` (or `−z` when `down`), mapped by `f`.
fn grid(k: usize, x0: Real, side: Real, down: bool, f: &dyn Fn(Vec3) -> Vec3) -> Vec<[Vec3; 3]> {
    let at = |i: usize, j: usize| {
        let s = side / k as Real;
        f(Vec3::new(x0 + i as Real * s, x0 + j as Real * s, 0.0))
    };
    let mut out = Vec::new();
    for i in 0..k {
        for j in 0..k {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if down {
                out.push([a, c, b]);
                out.push([a, d, c]);
            } else {
                out.push([a, b, c]);
                out.push([a, c, d]);
            }
        }
    }
    out
}

/// The sums over every pair of `tool` × `obstacle` triangles.
fn total(tool: &[[Vec3; 3]], obstacle: &[[Vec3; 3]], offset: HeightOffset) -> (Real, Vec3, Real) {
    let mut s = (0.0, Vec3::zeros(), 0.0);
    for a in tool {
        for b in obstacle {
            let nb = (b[1] - b[0]).cross(&(b[2] - b[0])).normalize();
            if let Some(r) = pair_region(a, b, &nb, DELTA, offset).region {
                let (g, gx, g2) = sums_of(&r);
                s.0 += g;
                s.1 += gx;
                s.2 += g2;
            }
        }
    }
    s
}

/// A tool square parallel to a floor square, its surface spread 0.6 mm about it: 0.5 mm up,
/// the pieces lie apart but within δ, their depth held at their distance; 1.2 mm up, beyond
/// δ, within reach only through the spread, the depth held at `−δ` and the weight next to
/// nothing.
#[test]
fn pieces_beyond_delta_are_told_from_pieces_apart_within_it() {
    let offset = HeightOffset {
        mean_m: 0.0,
        half_width_m: 0.6e-3,
    };
    let floor = grid(1, 0.0, 0.01, false, &|v| v);
    let region = |h: Real| {
        let tool = grid(1, 0.0, 0.01, true, &|v| v + Vec3::new(0.0, 0.0, h));
        let nb = Vec3::z();
        pair_region(&tool[0], &floor[0], &nb, DELTA, offset)
            .region
            .expect("within reach")
    };
    let within = region(0.5e-3);
    assert!(within.pieces_apart && !within.pieces_beyond(DELTA));
    assert_eq!(within.depth_m, -0.5e-3);
    let beyond = region(1.2e-3);
    assert!(beyond.pieces_apart && beyond.pieces_beyond(DELTA));
    assert_eq!(beyond.depth_m, -DELTA);
    // Crossing pieces are neither.
    let crossing = region(-0.2e-3);
    assert!(!crossing.pieces_apart && !crossing.pieces_beyond(DELTA));
}

/// A facing tool square 0.1 mm above a floor square, its shadow beyond a wall of the floor's
/// prism: no region, and how far beyond that wall and how long the two shadows face each other
/// across it (diagonally past a corner, the first wall found: a lower bound, facing over
/// nothing).
#[test]
fn a_facing_piece_beyond_a_wall_says_how_far_and_how_long_it_faces_it() {
    let square = |x0: Real, y0: Real, z: Real| square(x0, y0, 0.01, z);
    let floor = square(0.0, 0.0, 0.0);
    let nb = Vec3::z();
    let beside = |x0, y0| {
        let r = pair_region_beside(
            &square(x0, y0, 0.1e-3),
            &floor,
            &nb,
            DELTA,
            HeightOffset::NONE,
            false,
            (&[], &[]),
        );
        assert!(r.region.is_none() && r.nearest_m == Real::INFINITY);
        r.beside
    };
    // Beyond the wall x = 10 mm by 0.2 mm, its y from 6 to 16 mm: 4 mm facing.
    let (d, shared) = beside(0.0102, 0.006).unwrap();
    assert!((d - 0.2e-3).abs() < 1e-12, "{d}");
    assert!((shared - 0.004).abs() < 1e-12, "{shared}");
    // Diagonally past the corner (10, 10) mm: beyond both walls by 0.2 and 0.3 mm.
    let (d, shared) = beside(0.0102, 0.0103).unwrap();
    assert!(
        (0.2e-3 - 1e-12..=0.3e-3 + 1e-12).contains(&d) && shared == 0.0,
        "{d} {shared}"
    );
    assert!(d <= beside_prism_m(&square(0.0102, 0.0103, 0.1e-3), &floor, &nb, DELTA) + 1e-12);
    // Over it in part: a region, and nothing beside; `pair_region` does not measure.
    let over = pair_region_beside(
        &square(0.008, 0.006, 0.1e-3),
        &floor,
        &nb,
        DELTA,
        HeightOffset::NONE,
        false,
        (&[], &[]),
    );
    assert!(over.region.is_some() && over.beside.is_none());
    let plain = pair_region(
        &square(0.0102, 0.006, 0.1e-3),
        &floor,
        &nb,
        DELTA,
        HeightOffset::NONE,
    );
    assert_eq!(plain.beside, None);
}

/// A facing tool square over a floor square in part: the region's boundary along the walls of
/// the floor's prism is where the tool overhangs it, measured only when asked; over it wholly,
/// none.
#[test]
fn a_region_measures_its_length_along_the_walls_it_ends_at() {
    let floor = square(0.0, 0.0, 0.01, 0.0);
    let nb = Vec3::z();
    let walls = |tool: &[Vec3], measure: bool| {
        pair_region_beside(
            tool,
            &floor,
            &nb,
            DELTA,
            HeightOffset::NONE,
            measure,
            (&[], &[]),
        )
        .region
        .unwrap()
        .walls_m
    };
    // Over x 8–10 mm, y 6–10 mm: along the walls x = 10 mm (4 mm) and y = 10 mm (2 mm).
    let over_a_corner = square(0.008, 0.006, 0.01, 0.1e-3);
    assert!((walls(&over_a_corner, true) - 0.006).abs() < 1e-12);
    assert_eq!(walls(&over_a_corner, false), 0.0);
    // Across the floor in y, over x 8–10 mm: both walls y = 0 and y = 10 mm, and x = 10 mm.
    let across = [
        Vec3::new(0.008, -0.002, 0.1e-3),
        Vec3::new(0.012, -0.002, 0.1e-3),
        Vec3::new(0.012, 0.012, 0.1e-3),
        Vec3::new(0.008, 0.012, 0.1e-3),
    ];
    assert!((walls(&across, true) - 0.014).abs() < 1e-12);
    // Wholly over it: no wall.
    assert_eq!(walls(&square(0.002, 0.002, 0.004, 0.1e-3), true), 0.0);
    // `pair_region` does not measure.
    let plain = pair_region(&over_a_corner, &floor, &nb, DELTA, HeightOffset::NONE);
    assert_eq!(plain.region.unwrap().walls_m, 0.0);
}

/// A vertical tool square standing beside a floor square (edge-on), `x` beyond its edge
/// at `x = 0`: how far beside it lies, where its heights reach the band.
#[test]
fn a_piece_beside_a_prism_says_how_far() {
    let floor = [
        Vec3::new(-0.01, -0.01, 0.0),
        Vec3::new(0.0, -0.01, 0.0),
        Vec3::new(0.0, 0.01, 0.0),
        Vec3::new(-0.01, 0.01, 0.0),
    ];
    let wall = |x: Real, z: Real| {
        [
            Vec3::new(x, -0.005, z - 0.002),
            Vec3::new(x, 0.005, z - 0.002),
            Vec3::new(x, 0.005, z + 0.002),
            Vec3::new(x, -0.005, z + 0.002),
        ]
    };
    let nb = Vec3::z();
    let beside = |x, z| beside_prism_m(&wall(x, z), &floor, &nb, DELTA);
    assert!(
        pair_region(&wall(0.3e-3, 0.0), &floor, &nb, DELTA, HeightOffset::NONE)
            .region
            .is_none()
    );
    assert!((beside(0.3e-3, 0.0) - 0.3e-3).abs() < 1e-12);
    // Beyond a corner: the larger of its distances from the two walls' planes.
    let corner: Vec<Vec3> = wall(0.3e-3, 0.0)
        .iter()
        .map(|v| v + Vec3::new(0.0, 0.0152, 0.0))
        .collect();
    assert!((beside_prism_m(&corner, &floor, &nb, DELTA) - 0.3e-3).abs() < 1e-12);
    // Past the corner (0, 0.01) along the diagonal, the wall turned 45° to it: beyond
    // neither wall's plane (each sees part of it inside), apart by 0.3 mm across its side.
    let (d, l) = (0.3e-3, 0.005);
    let diagonal: Vec<Vec3> = wall(0.0, 0.0)
        .iter()
        .map(|v| {
            let along = v.y / 0.005 * l * std::f64::consts::FRAC_1_SQRT_2;
            let out = d * std::f64::consts::FRAC_1_SQRT_2;
            Vec3::new(out + along, 0.01 + out - along, v.z)
        })
        .collect();
    assert!(
        (beside_prism_m(&diagonal, &floor, &nb, DELTA) - d).abs() < 1e-12,
        "{}",
        beside_prism_m(&diagonal, &floor, &nb, DELTA)
    );
    // Moved onto the corner, its shadow crosses the floor's: beside by nothing.
    let onto: Vec<Vec3> = diagonal
        .iter()
        .map(|v| v - Vec3::new(1.0, 1.0, 0.0) * (d * std::f64::consts::FRAC_1_SQRT_2 * 2.0))
        .collect();
    assert_eq!(beside_prism_m(&onto, &floor, &nb, DELTA), 0.0);
    // Its heights out of the band: not within reach whatever its place.
    assert_eq!(beside(0.3e-3, 0.0035), Real::INFINITY);
    // Within the prism, the band 2δ tall along the wall is its region, and it lies over the
    // prism: beside by nothing; so does a wall tilted across the prism's wall.
    assert!(
        pair_region(&wall(-0.3e-3, 0.0), &floor, &nb, DELTA, HeightOffset::NONE)
            .region
            .is_some()
    );
    assert_eq!(beside(-0.3e-3, 0.0), 0.0);
    let tilted: Vec<Vec3> = wall(0.0, 0.0)
        .iter()
        .map(|v| v - Vec3::new(0.1 * v.z, 0.0, 0.0))
        .collect();
    assert_eq!(beside_prism_m(&tilted, &floor, &nb, DELTA), 0.0);
}

/// A piece crossing the floor's plane steeply, over the floor's prism only far below it, and
/// beside the prism where its heights are within reach: beside by what its part within reach
/// is, not over the prism (the whole piece's shadow crosses the floor's). A spoon's sheet
/// through a curved back put its coarse pieces so, and was dropped with the force its
/// triangles push.
#[test]
fn a_piece_over_a_prism_only_out_of_reach_is_beside_it() {
    let floor = [
        Vec3::new(-0.01, -0.01, 0.0),
        Vec3::new(0.0, -0.01, 0.0),
        Vec3::new(0.0, 0.01, 0.0),
        Vec3::new(-0.01, 0.01, 0.0),
    ];
    // x = 0.3 mm + 0.1 z: beyond the wall x = 0 by 0.3 ± 0.1 δ within reach, over the floor
    // below z = −3 mm.
    let steep = [
        Vec3::new(0.3e-3 - 1.2e-3, -0.005, -0.012),
        Vec3::new(0.3e-3 - 1.2e-3, 0.005, -0.012),
        Vec3::new(0.3e-3 + 0.2e-3, 0.005, 0.002),
        Vec3::new(0.3e-3 + 0.2e-3, -0.005, 0.002),
    ];
    let nb = Vec3::z();
    let r = pair_region(&steep, &floor, &nb, DELTA, HeightOffset::NONE);
    assert!(r.region.is_none(), "{r:?}");
    let d = beside_prism_m(&steep, &floor, &nb, DELTA);
    assert!((d - (0.3e-3 - 0.1 * DELTA)).abs() < 1e-12, "{d}");
    // Over the prism above the slab, but within the reach of the surfaces it stands for
    // (which may come nearer than the piece): no region, and beside by nothing.
    let above = [
        Vec3::new(-0.006, -0.002, 1.2 * DELTA),
        Vec3::new(-0.002, -0.002, 1.2 * DELTA),
        Vec3::new(-0.002, 0.002, 1.2 * DELTA),
    ];
    assert!(
        pair_region(&above, &floor, &nb, DELTA, HeightOffset::NONE)
            .region
            .is_none()
    );
    assert_eq!(beside_prism_m(&above, &floor, &nb, 1.5 * DELTA), 0.0);
    assert_eq!(beside_prism_m(&above, &floor, &nb, DELTA), Real::INFINITY);
}

/// A tilted tool square over a floor, partly beyond δ and partly below the floor: the same
/// sums from two triangles or a 6 × 6 grid on either side, so the force does not depend on
/// how a flat surface is tessellated.
#[test]
fn the_sums_do_not_depend_on_the_tessellation() {
    let tilt = nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(0.05, 0.3, 0.0));
    let place =
        |v: Vec3| tilt * (v - Vec3::new(0.005, 0.005, 0.0)) + Vec3::new(0.006, 0.004, 0.0003);
    let floor = |k| grid(k, 0.0, 0.012, false, &|v| v);
    let tool = |k| grid(k, 0.0, 0.01, true, &place);
    let coarse = total(&tool(1), &floor(1), HeightOffset::NONE);
    assert!(coarse.0 > 0.0);
    for (kt, kf) in [(6, 1), (1, 6), (6, 6), (3, 5)] {
        let fine = total(&tool(kt), &floor(kf), HeightOffset::NONE);
        assert!(
            (fine.0 - coarse.0).abs() < 1e-12 * coarse.0,
            "{kt}×{kf}: {fine:?} {coarse:?}"
        );
        assert!((fine.1 - coarse.1).norm() < 1e-12 * coarse.0);
        assert!((fine.2 - coarse.2).abs() < 1e-12 * coarse.2);
    }
}

/// `E[w]` and `E[w²]` by a fine midpoint sum over the spread.
fn weight_by_sum(delta: Real, s: Real, h: Real) -> (Real, Real) {
    let n = 20_000;
    let (mut g, mut g2) = (0.0, 0.0);
    for i in 0..n {
        let e = -s + 2.0 * s * (i as Real + 0.5) / n as Real;
        let x = h + e;
        // `w` continued linearly below −δ (see `Weight::antiderivatives`).
        let w = if x <= delta { delta - x } else { 0.0 };
        g += w / n as Real;
        g2 += w * w / n as Real;
    }
    (g, g2)
}

/// Dunavant's degree-5 rule: barycentric points (as `(a, b)`, the point `a` at one vertex and
/// `b` at the two others, in every rotation) and weights.
const DUNAVANT5: [(Real, Real, Real); 3] = [
    (1.0 / 3.0, 1.0 / 3.0, 0.225),
    (
        0.059_715_871_789_770,
        0.470_142_064_105_115,
        0.132_394_152_788_506,
    ),
    (
        0.797_426_985_353_087,
        0.101_286_507_323_456,
        0.125_939_180_544_827,
    ),
];

/// The band's sums by Dunavant's rule (exact for polynomials of degree 5, so for the band's
/// weights, of degree 3): what `Sums::add_band` computed before its closed form.
fn band_by_quadrature(p: &Poly, weight: &Weight) -> Sums {
    let mut sums = Sums::default();
    for ([v0, v1, v2], area) in fan(p) {
        let mut at = |x: Vec3, wt: Real| {
            let (g, g2) = weight.at(x.z);
            sums.g += area * wt * g;
            sums.gx += x * (area * wt * g);
            sums.g2 += area * wt * g2;
        };
        let (a0, b0, w0) = DUNAVANT5[0];
        at(v0 * a0 + v1 * b0 + v2 * b0, w0);
        for &(a, b, wt) in &DUNAVANT5[1..] {
            at(v0 * a + v1 * b + v2 * b, wt);
            at(v0 * b + v1 * a + v2 * b, wt);
            at(v0 * b + v1 * b + v2 * a, wt);
        }
    }
    sums
}

proptest! {
    /// A tool square standing edge-on on the diagonal of a floor square split in two triangles
    /// lies on the wall their prisms share (a peg's end flush with a row of its hole's
    /// tessellation): turned and moved anywhere, so that roundoff puts it inside both prisms,
    /// or neither, or one, the two triangles' regions weigh what the whole square's does, once.
    /// (Without the wall's rule: none, once or twice, as the turn had it.)
    #[test]
    fn a_polygon_on_a_shared_wall_counts_once(
        axis in prop::array::uniform3(-1.0..1.0f64),
        angle in 0.0..std::f64::consts::PI,
        shift in prop::array::uniform3(-0.1..0.1f64),
    ) {
        prop_assume!(Vec3::from(axis).norm() > 1e-3);
        let turn = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vec3::from(axis)),
            angle,
        );
        let place = |x: Real, y: Real, z: Real| turn * Vec3::new(x, y, z) + Vec3::from(shift);
        let side = 2e-3;
        let (a, b, c, d) = (
            place(0.0, 0.0, 0.0),
            place(side, 0.0, 0.0),
            place(side, side, 0.0),
            place(0.0, side, 0.0),
        );
        let nb = turn * Vec3::z();
        // The diagonal `a c` is the shared edge; the tool square stands on it, from 0.3 mm
        // below the floor to 0.6 mm above (the penalty's slab is ±1 mm).
        let along = |t: Real, z: Real| place(side * t, side * t, z);
        let tool = [along(0.1, -3e-4), along(0.9, -3e-4), along(0.9, 6e-4), along(0.1, 6e-4)];
        let weight = |poly: &[Vec3]| {
            pair_region(&tool, poly, &nb, DELTA, HeightOffset::NONE)
                .region
                .map_or(0.0, |r| sums_of(&r).0)
        };
        let whole = weight(&[a, b, c, d]);
        let halves = weight(&[a, b, c]) + weight(&[a, c, d]);
        prop_assert!(whole > 0.0);
        prop_assert!((halves - whole).abs() <= 1e-6 * whole, "{halves} against {whole}");
    }

    /// The closed form of the spread weight against a direct average.
    #[test]
    fn spread_weight_matches_its_average(s in 1e-5..3e-3f64, h in -2e-3..5e-3f64) {
        let (g, g2) = Weight::new(DELTA, s).at(h);
        let (gs, g2s) = weight_by_sum(DELTA, s, h);
        prop_assert!((g - gs).abs() < 1e-7 * DELTA, "{g} {gs}");
        prop_assert!((g2 - g2s).abs() < 1e-7 * DELTA * DELTA, "{g2} {g2s}");
    }

    /// The band's closed form against the quadrature, to roundoff, on polygons within the
    /// band (heights between the knee and the top), upright ones included.
    #[test]
    fn the_bands_closed_form_is_its_quadrature(
        xy in prop::array::uniform10(-3e-3..3e-3f64),
        h in prop::array::uniform5(0.0..1.0f64),
        s in 1e-5..3e-3f64,
        n in 3usize..6,
    ) {
        let weight = Weight::new(DELTA, s);
        let mut poly: Poly = ([[0.0; 3]; MAX_CLIPPED], n);
        for (k, p) in poly.0[..n].iter_mut().enumerate() {
            *p = [xy[2 * k], xy[2 * k + 1], DELTA - s + h[k] * 2.0 * s];
        }
        let mut closed = Sums::default();
        closed.add_band(&poly, &weight);
        let quadrature = band_by_quadrature(&poly, &weight);
        let area: Real = fan(&poly).map(|(_, a)| a).sum();
        prop_assume!(area > 1e-9);
        // The quadrature's own roundoff: `Weight::at` takes differences of antiderivatives of
        // size `2δ²` and `8δ³/3` over `2s`, which lose digits as `s` shrinks.
        let tol_g = 1e-13 * area * DELTA * DELTA / s + 1e-12 * quadrature.g.abs();
        let tol_g2 = 1e-13 * area * 4.0 * DELTA.powi(3) / (3.0 * s) + 1e-12 * quadrature.g2.abs();
        prop_assert!((closed.g - quadrature.g).abs() <= tol_g, "{} {}", closed.g, quadrature.g);
        prop_assert!((closed.gx - quadrature.gx).norm() <= tol_g * 5e-3);
        prop_assert!((closed.g2 - quadrature.g2).abs() <= tol_g2, "{} {}", closed.g2, quadrature.g2);
    }

    /// The closed forms and the band's quadrature against the spread weight summed over a
    /// fine grid of a triangle that crosses the knee, the top of the band or neither.
    #[test]
    fn polygon_sums_match_the_spread_weight_summed(
        x in prop::array::uniform6(-2e-3..2e-3f64),
        h in prop::array::uniform3(0.0..1.0f64),
        s in prop_oneof![Just(0.0), 1e-5..3e-3f64],
    ) {
        // Heights in `[−2δ, δ + s]`: below the band's top, where the weight ends.
        let h = h.map(|t| -2.0 * DELTA + t * (3.0 * DELTA + s));
        let v = [
            Vec3::new(x[0], x[1], h[0]),
            Vec3::new(x[2], x[3], h[1]),
            Vec3::new(x[4], x[5], h[2]),
        ];
        let area = 0.5 * (v[1] - v[0]).cross(&(v[2] - v[0])).norm();
        prop_assume!(area > 1e-8);
        let mut poly: Poly = ([[0.0; 3]; MAX_CLIPPED], 3);
        for (p, q) in poly.0.iter_mut().zip(&v) {
            *p = [q.x, q.y, q.z];
        }
        let weight = Weight::new(DELTA, s);
        let mut sums = Sums::default();
        sums.add(&poly, &weight);
        let n = 300;
        let (mut g, mut gx, mut g2) = (0.0, Vec3::zeros(), 0.0);
        let cell = area / (n * n) as Real;
        for i in 0..n {
            for j in 0..n - i {
                for (a, b, up) in [
                    (i as Real + 1.0 / 3.0, j as Real + 1.0 / 3.0, true),
                    (i as Real + 2.0 / 3.0, j as Real + 2.0 / 3.0, false),
                ] {
                    if !up && i + j + 1 >= n {
                        continue;
                    }
                    let p = v[0]
                        + (v[1] - v[0]) * (a / n as Real)
                        + (v[2] - v[0]) * (b / n as Real);
                    // `s = 0`: the weight continued linearly, as the clipped polygon has it.
                    let (w, w2) = if s > 0.0 {
                        weight.at(p.z)
                    } else {
                        (DELTA - p.z, (DELTA - p.z).powi(2))
                    };
                    g += w * cell;
                    gx += p * (w * cell);
                    g2 += w2 * cell;
                }
            }
        }
        let scale = area * DELTA;
        prop_assert!((sums.g - g).abs() < 1e-4 * scale, "{} {g}", sums.g);
        prop_assert!((sums.gx - gx).norm() < 1e-4 * scale * 4e-3, "{} {gx}", sums.gx);
        prop_assert!((sums.g2 - g2).abs() < 1e-4 * scale * DELTA, "{} {g2}", sums.g2);
    }

    /// Against the integral summed over a fine grid of points of the tool triangle: the
    /// weight, its centroid and its mean depth; and the region never stands for more than
    /// the triangle, nor lies beyond δ.
    #[test]
    fn a_triangle_pair_integrates_the_penalty(
        a in prop::array::uniform9(-2e-3..2e-3f64),
        b in prop::array::uniform9(-2e-3..2e-3f64),
    ) {
        let tri = |x: [Real; 9]| [
            Vec3::new(x[0], x[1], x[2] * 0.5),
            Vec3::new(x[3], x[4], x[5] * 0.5),
            Vec3::new(x[6], x[7], x[8] * 0.5),
        ];
        let (ta, mut tb) = (tri(a), tri(b));
        let cr = (tb[1] - tb[0]).cross(&(tb[2] - tb[0]));
        prop_assume!(cr.norm() > 1e-7 && (ta[1] - ta[0]).cross(&(ta[2] - ta[0])).norm() > 1e-7);
        if cr.z < 0.0 {
            tb.swap(1, 2);
        }
        let nb = (tb[1] - tb[0]).cross(&(tb[2] - tb[0])).normalize();
        let r = pair_region(&ta, &tb, &nb, DELTA, HeightOffset::NONE);
        // The sum: points of a fine barycentric grid on `ta`, each standing for its share.
        let (n, area_a) = (200, 0.5 * (ta[1] - ta[0]).cross(&(ta[2] - ta[0])).norm());
        let (mut g, mut gx, mut g2) = (0.0, Vec3::zeros(), 0.0);
        let count = n * n;
        for i in 0..n {
            for j in 0..n - i {
                // Two sub-triangles' centroids per cell; each stands for area / n².
                for (u, v) in [
                    ((i as Real + 1.0 / 3.0) / n as Real, (j as Real + 1.0 / 3.0) / n as Real),
                    ((i as Real + 2.0 / 3.0) / n as Real, (j as Real + 2.0 / 3.0) / n as Real),
                ] {
                    if u + v > 1.0 {
                        continue;
                    }
                    let x = ta[0] + (ta[1] - ta[0]) * u + (ta[2] - ta[0]) * v;
                    let h = nb.dot(&(x - tb[0]));
                    let inside = (0..3).all(|k| {
                        let (p, q) = (tb[k], tb[(k + 1) % 3]);
                        nb.dot(&(q - p).cross(&(x - p))) >= 0.0
                    });
                    if inside && h.abs() <= DELTA {
                        let w = (DELTA - h) * area_a / count as Real;
                        g += w;
                        gx += x * w;
                        g2 += w * (DELTA - h);
                    }
                }
            }
        }
        let scale = area_a * DELTA;
        match r.region {
            Some(reg) => {
                let (rg, rgx, rg2) = sums_of(&reg);
                prop_assert!((rg - g).abs() < 0.02 * scale, "{rg} {g}");
                prop_assert!((rgx - gx).norm() < 0.02 * scale * 4e-3);
                prop_assert!((rg2 - g2).abs() < 0.02 * scale * DELTA);
                prop_assert!(reg.area_m2 <= area_a * (1.0 + 1e-9));
                prop_assert!(reg.depth_m >= -DELTA && reg.depth_m <= DELTA);
                // The nearest point is no farther than the mean.
                prop_assert!(r.nearest_m <= reg.depth_m.abs() + 1e-15);
            }
            None => prop_assert!(g < 0.02 * scale, "missed {g}"),
        }
    }
}

/// A region's weight over the bands where the pieces overhang their surfaces
/// ([`RegionContact::overhang_m3`]): 0 where it reaches none; where it reaches one, its extent
/// along the edge by how far into the band it reaches, at most the band's uncovered area, at the
/// region's largest weight per area; the whole weight where a piece may overhang anywhere; the
/// tool's bands measured in its own plane.
#[test]
fn a_regions_weight_over_the_overhang_bands_is_bounded() {
    let floor = square(0.0, 0.0, 0.01, 0.0);
    let nb = Vec3::z();
    let none = Overhang::default();
    let band = |width_m: Real, area_m2: Real| [Overhang { width_m, area_m2 }, none, none, none];
    let overhang = |tool: &[Vec3], bands: (&[Overhang], &[Overhang])| {
        let r = pair_region_beside(tool, &floor, &nb, DELTA, HeightOffset::NONE, false, bands)
            .region
            .unwrap();
        (r.overhang_m3, r.area_m2 * (r.depth_m + DELTA))
    };
    // A 2 mm square 0.1 mm over the floor (`g` = 0.9 mm): its weight 3.6 · 10⁻⁹ m³.
    let (far, near) = (
        square(0.004, 0.005, 0.002, 1e-4),
        square(0.004, 0.0005, 0.002, 1e-4),
    );
    let floor_band = band(1e-3, 5e-6);
    // Five millimetres from the band along the floor's edge y = 0: none.
    assert_eq!(overhang(&far, (&[], &floor_band)).0, 0.0);
    // Half a millimetre into a band of 1 mm, over 2 mm: 1 mm² at 0.9 mm.
    let (o, w) = overhang(&near, (&[], &floor_band));
    assert!((w - 3.6e-9).abs() < 1e-20, "{w}");
    assert!((o - 0.9e-9).abs() < 1e-20, "{o}");
    // At most the band's uncovered area, 0.5 mm².
    let (o, _) = overhang(&near, (&[], &band(1e-3, 5e-7)));
    assert!((o - 0.45e-9).abs() < 1e-20, "{o}");
    // Overhanging anywhere (not measured): the whole weight.
    let (o, w) = overhang(&far, (&[], &band(Real::INFINITY, Real::INFINITY)));
    assert_eq!(o, w);
    // The tool's own band along its edge from corner 0, 0.5 mm wide, wholly in the region.
    let (o, _) = overhang(&far, (&band(5e-4, 1.0), &[]));
    assert!((o - 0.9e-9).abs() < 1e-20, "{o}");
    // `pair_region` measures nothing.
    assert_eq!(
        pair_region(&near, &floor, &nb, DELTA, HeightOffset::NONE)
            .region
            .unwrap()
            .overhang_m3,
        0.0
    );
}
