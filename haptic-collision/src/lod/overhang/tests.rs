//! The overhang bands: sound (every uncovered point of a planar piece lies in a band), their
//! uncovered areas measured, and curved pieces left unmeasured.

use haptic_core::{Real, Vec3};
use nalgebra::UnitQuaternion;
use proptest::prelude::*;

use super::super::MAX_PIECE_VERTICES;
use super::super::build::Hierarchy;
use super::super::testmesh::{Lcg, annulus, bumpy_sphere, mesh};
use super::{Across, NodeSurface, OverhangScratch, overhang_widths};
use crate::geometry::plane_basis;
use crate::mesh::TriMesh;

/// The source triangles below node `i`.
fn triangles_below(h: &Hierarchy, i: usize) -> Vec<u32> {
    let mut stack = vec![i];
    let mut out = Vec::new();
    while let Some(j) = stack.pop() {
        let n = &h.nodes[j];
        if n.is_leaf() {
            out.push(n.triangle);
        } else {
            stack.push(j + 1);
            stack.push(n.right as usize);
        }
    }
    out
}

/// A flat patch: an `nx × ny` grid of cells of side `cell_m` in the plane z = 0, each cell kept
/// whole, in part (one of its two triangles) or not at all, as `rng` draws; then turned and
/// moved by `pose` (so that the plane is no axis's).
fn patch(
    nx: usize,
    ny: usize,
    cell_m: Real,
    rng: &mut Lcg,
    turn: &UnitQuaternion<Real>,
) -> TriMesh {
    let at = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let vertices: Vec<Vec3> = (0..=ny)
        .flat_map(|j| (0..=nx).map(move |i| Vec3::new(i as Real * cell_m, j as Real * cell_m, 0.0)))
        .map(|v| turn * v + Vec3::new(0.01, -0.02, 0.03))
        .collect();
    let mut triangles = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            let draw = rng.next();
            if draw < 0.6 {
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            } else if draw < 0.75 {
                triangles.push([a, b, c]);
            } else if draw < 0.85 {
                triangles.push([a, c, d]);
            }
        }
    }
    if triangles.is_empty() {
        triangles.push([at(0, 0), at(1, 0), at(1, 1)]);
    }
    // Drop the vertices no triangle uses: none is needed for the test, and the mesh stays small.
    mesh(vertices, triangles)
}

/// For every planar piece of `h` (the mesh `m`'s hierarchy) the build measured: sampled on a
/// grid over the piece, every point no triangle lies over is within `tᵢ` of edge `i` for some
/// `i` (the bands are sound), and the uncovered samples in each band add up to its uncovered
/// area `Uᵢ` within the grid's resolution. Returns how many pieces had a band wider than 0.
fn check_bands(h: &Hierarchy, m: &TriMesh) -> usize {
    let mut banded = 0;
    for (i, node) in h.nodes.iter().enumerate() {
        if node.is_leaf() || node.piece_len == 0 {
            continue;
        }
        let bands = &h.overhang[node.piece_start as usize..][..node.piece_len as usize];
        if !bands[0].width_m.is_finite() {
            continue;
        }
        banded += usize::from(bands.iter().any(|b| b.width_m > 0.0));
        let (u, w) = plane_basis(&node.normal);
        let flat = |p: &Vec3| {
            let d = p - node.plane_point;
            [u.dot(&d), w.dot(&d)]
        };
        let piece: Vec<[Real; 2]> = h.piece_of(node).iter().map(flat).collect();
        let k = piece.len();
        // Inward distance from edge `e`.
        let from = |e: usize, x: &[Real; 2]| {
            let (p, q) = (piece[e], piece[(e + 1) % k]);
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            (dx * (x[1] - p[1]) - dy * (x[0] - p[0])) / (dx * dx + dy * dy).sqrt()
        };
        let tris: Vec<[[Real; 2]; 3]> = triangles_below(h, i)
            .iter()
            .map(|&t| m.triangle(t as usize).map(|p| flat(&p)))
            .collect();
        let under = |x: &[Real; 2]| {
            tris.iter().any(|t| {
                let c = |a: &[Real; 2], b: &[Real; 2]| {
                    (b[0] - a[0]) * (x[1] - a[1]) - (b[1] - a[1]) * (x[0] - a[0])
                };
                let (d0, d1, d2) = (c(&t[0], &t[1]), c(&t[1], &t[2]), c(&t[2], &t[0]));
                let tol = 1e-9 * node.radius * node.radius;
                (d0 >= -tol && d1 >= -tol && d2 >= -tol) || (d0 <= tol && d1 <= tol && d2 <= tol)
            })
        };
        let (lo, hi) = piece.iter().fold(
            ([Real::INFINITY; 2], [Real::NEG_INFINITY; 2]),
            |(l, h), p| {
                (
                    [l[0].min(p[0]), l[1].min(p[1])],
                    [h[0].max(p[0]), h[1].max(p[1])],
                )
            },
        );
        const N: usize = 80;
        let (sx, sy) = ((hi[0] - lo[0]) / N as Real, (hi[1] - lo[1]) / N as Real);
        for a in 0..N {
            for b in 0..N {
                let x = [
                    lo[0] + (a as Real + 0.5) * sx,
                    lo[1] + (b as Real + 0.5) * sy,
                ];
                if (0..k).any(|e| from(e, &x) < 0.0) || under(&x) {
                    continue;
                }
                let tol = 1e-9 * node.radius;
                assert!(
                    (0..k).any(|e| from(e, &x) <= bands[e].width_m + tol),
                    "node {i}: {x:?} lies under no triangle and in no band {bands:?}"
                );
            }
        }
        // Each band sampled on its own grid, along its edge and across it.
        for e in 0..k {
            let t = bands[e].width_m;
            if t <= 0.0 {
                continue;
            }
            let (p, q) = (piece[e], piece[(e + 1) % k]);
            let length = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
            let along = [(q[0] - p[0]) / length, (q[1] - p[1]) / length];
            let across = [-along[1], along[0]];
            // The band may reach past the edge's ends (a corner's acute angle): from the ends'
            // shadow across the whole piece.
            let (s_lo, s_hi) =
                piece
                    .iter()
                    .fold((Real::INFINITY, Real::NEG_INFINITY), |(l, h), c| {
                        let s = (c[0] - p[0]) * along[0] + (c[1] - p[1]) * along[1];
                        (l.min(s), h.max(s))
                    });
            const NA: usize = 400;
            const NC: usize = 80;
            let (ds, dc) = ((s_hi - s_lo) / NA as Real, t / NC as Real);
            let mut sampled = 0.0;
            for a in 0..NA {
                for c in 0..NC {
                    let (s, r) = (s_lo + (a as Real + 0.5) * ds, (c as Real + 0.5) * dc);
                    let x = [
                        p[0] + along[0] * s + across[0] * r,
                        p[1] + along[1] * s + across[1] * r,
                    ];
                    if (0..k).all(|f| from(f, &x) >= 0.0) && !under(&x) {
                        sampled += ds * dc;
                    }
                }
            }
            // The grid misses or adds at most a cell along the outlines it crosses.
            let resolution = 3.0 * (s_hi - s_lo + 2.0 * t) * ds.max(dc) + 0.03 * bands[e].area_m2;
            assert!(
                (sampled - bands[e].area_m2).abs() <= resolution,
                "node {i} edge {e}: sampled {sampled} against {} (± {resolution})",
                bands[e].area_m2
            );
        }
    }
    banded
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Random flat patches with holes, notches and loose triangles, in any orientation and at
    /// any scale: the bands are sound and their uncovered areas measured.
    #[test]
    fn a_planar_pieces_uncovered_part_lies_in_its_bands(
        seed in any::<u64>(),
        nx in 3usize..9,
        ny in 3usize..9,
        cell_m in prop::sample::select(vec![1e-3, 2.5e-2, 0.3]),
        axis in (-1.0..1.0f64, -1.0..1.0f64, 0.1..1.0f64),
        angle in 0.0..3.0f64,
    ) {
        let mut rng = Lcg(seed);
        let turn = UnitQuaternion::from_scaled_axis(Vec3::new(axis.0, axis.1, axis.2).normalize() * angle);
        let m = patch(nx, ny, cell_m, &mut rng, &turn);
        let h = Hierarchy::build(&m);
        check_bands(&h, &m);
    }
}

/// A washer (a flat ring, 64 segments): its pieces of a few segments overhang the opening by
/// their chords' sagitta, the bands along those chords say so, and every piece is measured.
#[test]
fn a_washers_pieces_overhang_its_opening_along_their_chords() {
    let m = annulus(0.027, 0.03, 64);
    let h = Hierarchy::build(&m);
    let banded = check_bands(&h, &m);
    let inner = h.nodes.iter().filter(|n| !n.is_leaf()).count();
    assert!(banded > inner / 4, "{banded} of {inner} pieces banded");
    // Every inner node is planar and measured (finite).
    assert!(
        h.nodes
            .iter()
            .filter(|n| !n.is_leaf())
            .all(|n| h.overhang[n.piece_start as usize].width_m.is_finite())
    );
    // A piece of two segments (four triangles, cover short of 1) overhangs by its sagitta,
    // `r (1 − cos(2π/64))`, along one edge, and nowhere else.
    let sagitta = 0.027 * (1.0 - (std::f64::consts::TAU / 64.0).cos());
    let two = h.nodes.iter().find(|n| n.triangles == 4).unwrap();
    let bands = &h.overhang[two.piece_start as usize..][..two.piece_len as usize];
    let widest = bands.iter().map(|b| b.width_m).fold(0.0, Real::max);
    assert!(
        (widest - sagitta).abs() <= 1e-9,
        "{bands:?} against {sagitta}"
    );
    assert_eq!(
        bands.iter().filter(|b| b.width_m > 0.0).count(),
        1,
        "{bands:?}"
    );
}

/// A flat convex face has no band anywhere; a curved surface is not measured.
#[test]
fn convex_faces_have_no_band_and_curved_pieces_none_measured() {
    let square = mesh(
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.01, 0.0, 0.0),
            Vec3::new(0.01, 0.01, 0.0),
            Vec3::new(0.0, 0.01, 0.0),
            Vec3::new(0.005, 0.005, 0.0),
        ],
        vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
    );
    let h = Hierarchy::build(&square);
    assert!(
        h.overhang
            .iter()
            .all(|b| b.width_m == 0.0 && b.area_m2 == 0.0),
        "{:?}",
        h.overhang
    );
    let sphere = bumpy_sphere(2, 0.05, 0.1, 1);
    let h = Hierarchy::build(&sphere);
    for (i, n) in h.nodes.iter().enumerate() {
        if !n.is_leaf() && n.piece_len > 0 {
            assert!(h.overhang[n.piece_start as usize].width_m.is_infinite());
            assert!(h.overhang_of(n, h.moments_of(i as u32)).is_empty());
        }
    }
}

/// Two triangles meeting at one corner (a bow tie) under a square piece given with a corner
/// twice: the gaps on either side of the tie lie in the bands (the boundary edges that cross
/// the inner polygon push it back past them), their area is counted, and the edge of no length
/// bounds nothing (before, it made every point's nearest edge and every band 0 wide).
#[test]
fn a_gap_between_two_parts_lies_in_the_bands_and_a_repeated_corner_bounds_nothing() {
    let m = mesh(
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(2.0, 2.0, 0.0),
        ],
        vec![[0, 1, 2], [2, 4, 3]],
    );
    let tris: Vec<[Vec3; 3]> = (0..2).map(|t| m.triangle(t)).collect();
    let across = Across::of(&m);
    let surface = NodeSurface {
        triangles: &[0, 1],
        rank: &[0, 1],
        range: (0, 2),
        basis: (Vec3::x(), Vec3::y()),
        origin: Vec3::zeros(),
    };
    let hull = [[0.0, 0.0], [2.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
    let (mut widths, mut uncovered) = ([0.0; MAX_PIECE_VERTICES], [0.0; MAX_PIECE_VERTICES]);
    let mut scratch = OverhangScratch::default();
    overhang_widths(
        &hull,
        &surface,
        &tris,
        &across,
        &mut scratch,
        &mut widths,
        &mut uncovered,
    );
    assert_eq!(widths[1], 0.0, "{widths:?}");
    // Inward distance from the edge from corner `e`.
    let from = |e: usize, x: [Real; 2]| {
        let (p, q) = (hull[e], hull[(e + 1) % hull.len()]);
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        let len = (dx * dx + dy * dy).sqrt();
        if len == 0.0 {
            Real::INFINITY
        } else {
            (dx * (x[1] - p[1]) - dy * (x[0] - p[0])) / len
        }
    };
    // The two gaps: left of x = 1 − |y − 1| and right of x = 1 + |y − 1|.
    for k in 1..40 {
        for j in 1..40 {
            let x = [k as Real * 0.05, j as Real * 0.05];
            let off = (x[1] - 1.0).abs();
            if (x[0] - 1.0).abs() > off + 1e-9 {
                assert!(
                    (0..hull.len()).any(|e| from(e, x) <= widths[e] + 1e-12),
                    "{x:?} {widths:?}"
                );
            }
        }
    }
    // The two gaps, of area 1 each, are counted in the bands' uncovered areas.
    let counted: Real = uncovered[..hull.len()].iter().sum();
    assert!(counted >= 2.0 - 1e-9, "{uncovered:?}");
}
