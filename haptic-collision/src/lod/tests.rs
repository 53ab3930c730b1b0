use haptic_core::{CollisionBackend, ContactSet, NO_FEATURE, Pose, QueryParams, Real, Vec3};
use nalgebra::{UnitQuaternion, Vector3};
use proptest::prelude::*;

use super::build::Hierarchy;
use super::testmesh::{Lcg, annulus, bumpy_sphere, cuboid, drilled_face, icosphere_raw, mesh};
use super::{LodBackend, LodError, StoppingRule};
use crate::geometry::{closest_point_on_triangle, point_polygon_distance, triangle_normal};
use crate::mesh::TriMesh;
use crate::reference::ReferenceBackend;

/// Signed volume of a closed mesh (positive for outward CCW triangles).
fn volume(m: &TriMesh) -> Real {
    (0..m.triangles().len())
        .map(|t| {
            let [a, b, c] = m.triangle(t);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

/// Triangles below node `i`.
fn triangles_below(h: &Hierarchy, i: usize, out: &mut Vec<u32>) {
    let node = &h.nodes[i];
    if node.is_leaf() {
        out.push(node.triangle);
    } else {
        triangles_below(h, i + 1, out);
        triangles_below(h, node.right as usize, out);
    }
}

/// Barycentric grid samples of a triangle.
fn samples(t: &[Vec3; 3], k: usize, out: &mut Vec<Vec3>) {
    for i in 0..=k {
        for j in 0..=(k - i) {
            let (u, v) = (i as Real / k as Real, j as Real / k as Real);
            out.push(t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v);
        }
    }
}

fn meshes_for_tests() -> Vec<TriMesh> {
    vec![
        cuboid(Vec3::new(0.03, 0.02, 0.01)),
        // Creases between fine faces: the build cuts along them (`split.rs`).
        grid_box(Vec3::new(0.03, 0.02, 0.01), 5),
        bumpy_sphere(2, 0.05, 0.0, 1),
        bumpy_sphere(2, 0.04, 0.05, 7),
        {
            // An open, wavy height-field sheet (concave and convex parts).
            let n = 8;
            let mut v = Vec::new();
            for i in 0..=n {
                for j in 0..=n {
                    let (x, y) = (i as Real / n as Real - 0.5, j as Real / n as Real - 0.5);
                    v.push(Vec3::new(x, y, 0.1 * (6.0 * x).sin() * (4.0 * y).cos()) * 0.1);
                }
            }
            let mut t = Vec::new();
            for i in 0..n as u32 {
                for j in 0..n as u32 {
                    let a = i * (n as u32 + 1) + j;
                    let b = a + n as u32 + 1;
                    t.push([a, b, a + 1]);
                    t.push([a + 1, b, b + 1]);
                }
            }
            mesh(v, t)
        },
    ]
}

#[test]
fn test_meshes_are_outward() {
    assert!(volume(&cuboid(Vec3::new(1.0, 2.0, 3.0))) > 47.9);
    let (v, t) = icosphere_raw(1);
    assert!(volume(&mesh(v, t)) > 0.0);
}

#[test]
fn hierarchy_bounds_and_deviation_are_true_upper_bounds() {
    for m in meshes_for_tests() {
        let h = Hierarchy::build(&m);
        assert_eq!(h.node_count(), 2 * m.triangles().len() - 1);
        let mut finite = 0;
        for i in 0..h.node_count() {
            let node = h.nodes[i];
            let mut tris = Vec::new();
            triangles_below(&h, i, &mut tris);
            let mut pts = Vec::new();
            for &t in &tris {
                samples(&m.triangle(t as usize), 6, &mut pts);
            }
            // Sphere and slab enclose the surface.
            for p in &pts {
                assert!((p - node.center).norm() <= node.radius * (1.0 + 1e-9) + 1e-15);
                assert!(
                    node.normal.dot(&(p - node.plane_point)).abs() <= node.half_thickness + 1e-12
                );
            }
            if !node.deviation.is_finite() {
                continue;
            }
            finite += 1;
            let s = node.deviation;
            let piece = h.piece_of(&node);
            assert!(piece.len() >= 3 && piece.len() <= super::MAX_PIECE_VERTICES);
            // The piece's ball holds it.
            let ball = h.piece_ball_of(i as u32);
            for v in piece {
                assert!((v - ball.center).norm() <= ball.radius_m * (1.0 + 1e-12));
            }
            // Surface → piece.
            for p in &pts {
                let d = point_polygon_distance(p, piece, &node.normal);
                assert!(
                    d <= s + 1e-12,
                    "node {i}: surface point {d} from piece, s = {s}"
                );
            }
            // Piece → surface, the whole mesh (fan samples of the polygon).
            let mut qs = Vec::new();
            for k in 1..piece.len() - 1 {
                samples(&[piece[0], piece[k], piece[k + 1]], 8, &mut qs);
            }
            for q in &qs {
                let d = (0..m.triangles().len())
                    .map(|t| (closest_point_on_triangle(q, &m.triangle(t)) - q).norm())
                    .fold(Real::INFINITY, Real::min);
                assert!(
                    d <= s + 1e-12,
                    "node {i}: piece point {d} from surface, s = {s}"
                );
            }
            // The piece is convex and CCW about the normal.
            for k in 0..piece.len() {
                let (a, b, c) = (
                    piece[k],
                    piece[(k + 1) % piece.len()],
                    piece[(k + 2) % piece.len()],
                );
                assert!((b - a).cross(&(c - b)).dot(&node.normal) >= -1e-15);
            }
        }
        assert!(
            finite > h.node_count() / 2,
            "most nodes must have a usable piece"
        );
        // Leaves stand for their own triangle: their deviation is exactly 0.
        assert!(
            h.nodes
                .iter()
                .filter(|n| n.is_leaf())
                .all(|n| n.deviation == 0.0)
        );
    }
}

fn random_pose(rng: &mut Lcg, spread: Real) -> Pose {
    let axis = Vector3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
    let angle = 3.0 * rng.next();
    let q = UnitQuaternion::from_scaled_axis(axis.normalize() * angle);
    Pose {
        position: Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * spread,
        orientation: q,
    }
}

fn scene(seed: u64) -> (TriMesh, Vec<(TriMesh, Pose)>) {
    let tool = bumpy_sphere(1, 0.03, 0.15, seed);
    let mut rng = Lcg(seed ^ 0x9e37);
    let obstacles = vec![
        (
            cuboid(Vec3::new(0.04, 0.03, 0.02)),
            random_pose(&mut rng, 0.02),
        ),
        (
            bumpy_sphere(2, 0.035, 0.1, seed + 1),
            random_pose(&mut rng, 0.02),
        ),
    ];
    (tool, obstacles)
}

/// Any stopping rule.
fn any_rule() -> impl Strategy<Value = StoppingRule> {
    prop_oneof![
        Just(StoppingRule::Deviation),
        Just(StoppingRule::DeviationAndCoherence),
        Just(StoppingRule::CoherenceBudget)
    ]
}

fn min_distance_and_max_depth(set: &ContactSet) -> (Real, Real) {
    let max_depth = set.max_depth_m().unwrap_or(Real::NEG_INFINITY);
    let min_dist = set
        .iter()
        .map(|c| (-c.depth_m).max(0.0))
        .fold(Real::INFINITY, Real::min);
    (min_dist, max_depth)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Threshold 0 with every contact written is exact: the same contacts, with the same
    /// areas, as the all-pairs reference.
    #[test]
    fn threshold_zero_matches_brute_force(
        seed in 0u64..1_000_000,
        pose_seed in 0u64..1_000_000,
        rule in any_rule(),
    ) {
        let (tool, obstacles) = scene(seed);
        let mut lod = LodBackend::new(&tool, &obstacles)
            .unwrap()
            .with_max_contacts(None)
            .with_stopping_rule(rule);
        let mut reference = ReferenceBackend::new(&tool, &obstacles).unwrap();
        let pose = random_pose(&mut Lcg(pose_seed), 0.09);
        let params = QueryParams::new(0.01, 0.0).unwrap();
        let (mut a, mut b) = (ContactSet::new(), ContactSet::new());
        lod.query(&pose, &params, &mut a).unwrap();
        reference.query(&pose, &params, &mut b).unwrap();
        prop_assert_eq!(a.len(), b.len());
        let key = |c: &haptic_core::Contact| (c.feature_a, c.feature_b);
        let mut ka: Vec<_> = a.iter().map(|c| (key(c), c.area_m2)).collect();
        let mut kb: Vec<_> = b.iter().map(|c| (key(c), c.area_m2)).collect();
        // (Two obstacles can give the same pair of indices: ties ordered by area.)
        ka.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
        kb.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
        // The same pairs, with the same areas (to the rounding of sums taken in another order).
        for (x, y) in ka.iter().zip(&kb) {
            prop_assert_eq!(x.0, y.0);
            prop_assert!((x.1 - y.1).abs() <= 1e-12 * x.1.max(1e-12), "{} {}", x.1, y.1);
        }
        // Each contact stands for at most its tool triangle (the part over the obstacle
        // triangle), the closest approach for next to nothing (but not 0: see
        // `closest_approach_area_m2`) and pushes nothing; the regions push with the whole
        // stiffness.
        for c in a.iter() {
            if c.feature_a == NO_FEATURE {
                prop_assert_eq!(c.area_m2, crate::compact::area_floor_m2(params.delta_m));
                prop_assert_eq!(c.stiffness_share, 0.0);
                continue;
            }
            prop_assert_eq!(c.stiffness_share, 1.0);
            let tri = tool.triangle(c.feature_a as usize);
            let area = 0.5 * (tri[1] - tri[0]).cross(&(tri[2] - tri[0])).norm();
            prop_assert!(c.area_m2 > 0.0 && c.area_m2 <= area * (1.0 + 1e-9), "{} {area}", c.area_m2);
        }
        let (da, pa) = min_distance_and_max_depth(&a);
        let (db, pb) = min_distance_and_max_depth(&b);
        if !a.is_empty() {
            prop_assert!((da - db).abs() <= 1e-9 && (pa - pb).abs() <= 1e-9, "{da} {db} {pa} {pb}");
        }
        for c in a.iter() {
            prop_assert!(c.depth_m >= -0.01);
            prop_assert!((c.p_a - c.p_b - c.n * c.depth_m).norm() < 1e-12);
            prop_assert!((pose.transform_point(&c.r_a) - c.p_a).norm() < 1e-12);
        }
    }

    /// Compact contacts at threshold 0: at most the cap, the same total weight `Σ a (d + δ)`
    /// and closest approach (or deepest point) as every contact found, and `raw_contacts` says
    /// how many.
    #[test]
    fn compact_contacts_keep_area_and_closest_approach(
        seed in 0u64..1_000_000,
        pose_seed in 0u64..1_000_000,
        max in 2usize..64,
    ) {
        let (tool, obstacles) = scene(seed);
        let mut all = LodBackend::new(&tool, &obstacles).unwrap().with_max_contacts(None);
        let mut compact = all.clone().with_max_contacts(Some(max));
        let pose = random_pose(&mut Lcg(pose_seed), 0.09);
        let params = QueryParams::new(0.01, 0.0).unwrap();
        let (mut a, mut b) = (ContactSet::new(), ContactSet::new());
        all.query(&pose, &params, &mut a).unwrap();
        let stats = compact.query(&pose, &params, &mut b).unwrap();
        prop_assert_eq!(stats.raw_contacts as usize, a.len());
        prop_assert!(b.len() <= max.max(2) && b.len() <= a.len());
        // The clustering's weights, floored as it floors them.
        let weight = |s: &ContactSet| {
            s.iter()
                .map(|c| c.area_m2 * (c.depth_m + 0.01).max(1e-5))
                .sum::<Real>()
        };
        prop_assert!((weight(&a) - weight(&b)).abs() <= 1e-9 * weight(&a));
        if !a.is_empty() {
            let (da, pa) = min_distance_and_max_depth(&a);
            let (db, pb) = min_distance_and_max_depth(&b);
            prop_assert!(pa == pb, "{pa} {pb}");
            // The deepest contact is kept: the closest approach when apart.
            prop_assert!(pa > 0.0 || da == db, "{da} {db}");
        }
        for c in b.iter() {
            prop_assert!(c.validate().is_ok() && c.area_m2 > 0.0);
            prop_assert!((pose.transform_point(&c.r_a) - c.p_a).norm() < 1e-9);
        }
    }

    /// Above 0: never more node pairs, and the closest approach is off by at most ε when the
    /// exact configuration is apart (D > ε) and within reach (D < δ − ε).
    #[test]
    fn threshold_error_is_bounded(
        seed in 0u64..1_000_000,
        gap in 0.002f64..0.012,
        threshold in 0.005f64..0.05,
        rule in any_rule(),
    ) {
        let tool = bumpy_sphere(2, 0.03, 0.03, seed);
        let obstacle = bumpy_sphere(2, 0.04, 0.03, seed + 11);
        let mut rng = Lcg(seed);
        let dir = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5).normalize();
        let mut pose = random_pose(&mut rng, 0.0);
        pose.position = dir * (0.03 + 0.04 + gap);
        let obstacles = vec![(obstacle, Pose::identity())];
        let mut lod = LodBackend::new(&tool, &obstacles).unwrap().with_stopping_rule(rule);
        let delta = 0.02;
        let eps = threshold * lod.tool_bounding_radius_m();
        let mut exact = ContactSet::new();
        let s0 = lod.query(&pose, &QueryParams::new(delta, 0.0).unwrap(), &mut exact).unwrap();
        let (d0, _) = min_distance_and_max_depth(&exact);
        prop_assume!(d0 > eps && d0 < delta - eps);
        let mut coarse = ContactSet::new();
        let st = lod.query(&pose, &QueryParams::new(delta, threshold).unwrap(), &mut coarse).unwrap();
        prop_assert!(st.node_pairs_tested <= s0.node_pairs_tested);
        let (dt, _) = min_distance_and_max_depth(&coarse);
        prop_assert!((dt - d0).abs() <= eps + 1e-12, "exact {d0}, coarse {dt}, eps {eps}");
        for c in coarse.iter() {
            prop_assert!(c.depth_m >= -delta);
        }
    }
}

/// `Σ w`, `Σ w p_a`, `Σ w r_a`, `Σ w d` of `set`, with the clustering's weights.
fn weighted_sums(set: &ContactSet, delta: Real) -> (Real, Vec3, Vec3, Real) {
    let mut m = (0.0, Vec3::zeros(), Vec3::zeros(), 0.0);
    for c in set.iter() {
        let w = c.area_m2 * c.gap_weight_m(delta);
        m.0 += w;
        m.1 += c.p_a * w;
        m.2 += c.r_a * w;
        m.3 += c.depth_m * w;
    }
    m
}

#[test]
fn a_tool_piece_over_two_obstacles_counts_its_surface_once() {
    // A flat tool square, 0.2 mm over the seam of two flat obstacle squares (two obstacles),
    // δ = 1 mm. The pieces are exact (flat), so at a coarse threshold the walk stops above the
    // leaves, and the two obstacles' prisms share the tool square at the seam.
    let tool = flat_grid(4, 0.005, false);
    let obstacles = vec![
        (
            flat_grid(4, 0.005, true),
            Pose::from_position(Vec3::new(-0.005, 0.0, 0.0)),
        ),
        (
            flat_grid(4, 0.005, true),
            Pose::from_position(Vec3::new(0.005, 0.0, 0.0)),
        ),
    ];
    let pose = Pose::from_position(Vec3::new(0.0, 0.0, 0.0002));
    let delta = 0.001;
    let mut lod = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    for threshold in [0.0, 0.05] {
        let mut r = ContactSet::new();
        lod.query(&pose, &QueryParams::new(delta, threshold).unwrap(), &mut r)
            .unwrap();
        if threshold > 0.0 {
            assert!(
                r.iter().all(|c| c.feature_a == NO_FEATURE),
                "stopped above the leaves"
            );
        }
        // The tool's 1 cm² once, not twice, all of it 0.2 mm above the floor.
        let total: Real = r.iter().map(|c| c.area_m2).sum();
        assert!((total - 1e-4).abs() < 1e-4 * 1e-9, "{total}");
        let (w, p, _, d) = weighted_sums(&r, delta);
        assert!((w - 1e-4 * 0.0008).abs() < 1e-9 * w, "{w}");
        assert!((d / w + 0.0002).abs() < 1e-12, "{}", d / w);
        // The centre of pressure is the square's centre, above the seam.
        assert!((p / w - Vec3::new(0.0, 0.0, 0.0002)).norm() < 1e-12);
    }
}

#[test]
fn coarse_thresholds_test_fewer_pairs() {
    let tool = bumpy_sphere(3, 0.03, 0.02, 3);
    let obstacle = bumpy_sphere(3, 0.04, 0.02, 5);
    let pose = Pose::from_position(Vec3::new(0.0, 0.0, 0.069));
    let mut lod = LodBackend::new(&tool, &[(obstacle, Pose::identity())]).unwrap();
    let mut out = ContactSet::new();
    let mut tested = Vec::new();
    for threshold in [0.0, 0.004, 0.01, 0.025, 0.05] {
        let st = lod
            .query(
                &pose,
                &QueryParams::new(0.003, threshold).unwrap(),
                &mut out,
            )
            .unwrap();
        assert!(!out.is_empty());
        tested.push(st.node_pairs_tested);
    }
    assert!(tested.windows(2).all(|w| w[1] <= w[0]), "{tested:?}");
    assert!(tested[4] < tested[0], "{tested:?}");
}

#[test]
fn broad_phase_culls_far_tools() {
    let (tool, obstacles) = scene(4);
    let mut lod = LodBackend::new(&tool, &obstacles).unwrap();
    let mut out = ContactSet::new();
    let params = QueryParams::new(0.001, 0.0).unwrap();
    let st = lod
        .query(
            &Pose::from_position(Vec3::new(1.0, 0.0, 0.0)),
            &params,
            &mut out,
        )
        .unwrap();
    assert!(!st.broad_phase_hit);
    assert_eq!(st.node_pairs_tested, 0);
    assert!(out.is_empty());
    let st = lod.query(&Pose::identity(), &params, &mut out).unwrap();
    assert!(st.broad_phase_hit && st.node_pairs_tested > 0 && !out.is_empty());
}

#[test]
fn queries_do_not_allocate_after_warm_up() {
    for rule in StoppingRule::ALL {
        queries_do_not_allocate_after_warm_up_under(rule);
    }
}

fn queries_do_not_allocate_after_warm_up_under(rule: StoppingRule) {
    let (tool, obstacles) = scene(9);
    let mut lod = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_stopping_rule(rule);
    let mut out = ContactSet::new();
    let mut rng = Lcg(77);
    let poses: Vec<Pose> = (0..40).map(|_| random_pose(&mut rng, 0.06)).collect();
    let mut warm = 0;
    for round in 0..3 {
        for (k, pose) in poses.iter().enumerate() {
            let threshold = [0.0, 0.01, 0.05][k % 3];
            lod.query(pose, &QueryParams::new(0.005, threshold).unwrap(), &mut out)
                .unwrap();
        }
        // The traversal stack is reserved at its proven bound; the list of coarse pairs grows
        // to its largest size in the first round, then neither grows.
        if round == 0 {
            warm = lod.scratch_capacity();
        } else {
            assert_eq!(lod.scratch_capacity(), warm, "{rule}, round {round}");
        }
    }
    let cap = out.capacity();
    for pose in &poses {
        lod.query(pose, &QueryParams::new(0.005, 0.0).unwrap(), &mut out)
            .unwrap();
        assert_eq!(out.capacity(), cap);
    }
}

#[test]
fn bad_inputs_give_typed_errors() {
    let (tool, obstacles) = scene(1);
    let nan_pose = Pose {
        position: Vec3::new(Real::NAN, 0.0, 0.0),
        orientation: UnitQuaternion::identity(),
    };
    assert!(matches!(
        LodBackend::new(&tool, &[(obstacles[0].0.clone(), nan_pose)]),
        Err(LodError::NonFinitePose {
            what: "obstacle pose"
        })
    ));
    assert!(matches!(
        ReferenceBackend::new(&tool, &[(obstacles[0].0.clone(), nan_pose)]),
        Err(LodError::NonFinitePose { .. })
    ));
    let mut lod = LodBackend::new(&tool, &obstacles).unwrap();
    let mut out = ContactSet::new();
    let ok = QueryParams::new(0.001, 0.0).unwrap();
    assert!(matches!(
        lod.query(&nan_pose, &ok, &mut out),
        Err(LodError::NonFinitePose { what: "tool pose" })
    ));
    let bad_delta = QueryParams {
        delta_m: -1.0,
        error_threshold: 0.0,
    };
    assert!(matches!(
        lod.query(&Pose::identity(), &bad_delta, &mut out),
        Err(LodError::Core(haptic_core::CoreError::OutOfRange {
            what: "query.delta_m",
            ..
        }))
    ));
    let bad_eps = QueryParams {
        delta_m: 0.001,
        error_threshold: Real::NAN,
    };
    assert!(matches!(
        lod.query(&Pose::identity(), &bad_eps, &mut out),
        Err(LodError::Core(haptic_core::CoreError::NonFinite {
            what: "query.error_threshold",
        }))
    ));
}

#[test]
fn normals_point_out_of_the_tool() {
    // A small cube resting 1 mm above a large one: every contact normal points down (-z); the
    // bottom face's contacts are 1 mm away, the side faces' strips within δ of the floor farther.
    let tool = cuboid(Vec3::new(0.01, 0.01, 0.01));
    let floor = cuboid(Vec3::new(0.1, 0.1, 0.01));
    let mut lod = LodBackend::new(
        &tool,
        &[(floor, Pose::from_position(Vec3::new(0.0, 0.0, -0.021)))],
    )
    .unwrap();
    let mut out = ContactSet::new();
    for threshold in [0.0, 0.05] {
        lod.query(
            &Pose::identity(),
            &QueryParams::new(0.002, threshold).unwrap(),
            &mut out,
        )
        .unwrap();
        assert!(!out.is_empty());
        for c in out.iter() {
            assert!((c.n + Vec3::z()).norm() < 1e-9, "{c:?}");
            assert!(c.depth_m <= -0.001 + 1e-12 && c.depth_m >= -0.002, "{c:?}");
        }
        let nearest = out
            .iter()
            .map(|c| c.depth_m)
            .fold(Real::NEG_INFINITY, Real::max);
        assert!((nearest + 0.001).abs() < 1e-12, "{nearest}");
    }
    // Sunk 0.5 mm: depth 0.5 mm, still along -z.
    lod.query(
        &Pose::from_position(Vec3::new(0.0, 0.0, -0.0015)),
        &QueryParams::new(0.002, 0.0).unwrap(),
        &mut out,
    )
    .unwrap();
    let deepest = out
        .iter()
        .map(|c| c.depth_m)
        .fold(Real::NEG_INFINITY, Real::max);
    assert!((deepest - 0.0005).abs() < 1e-12, "{deepest}");
    let _ = triangle_normal;
}

/// A sheet over the grid `xs × ys`, at height `z(x)`, each cell two triangles, facing `+z`
/// (`up`) or `−z`.
fn sheet(xs: &[Real], ys: &[Real], z: impl Fn(Real) -> Real, up: bool) -> TriMesh {
    surface(xs, ys, |x, _| z(x), up)
}

/// A sheet over the grid `xs × ys`, at height `z(x, y)`, as [`sheet`].
fn surface(xs: &[Real], ys: &[Real], z: impl Fn(Real, Real) -> Real, up: bool) -> TriMesh {
    let mut vertices = Vec::new();
    for &y in ys {
        for &x in xs {
            vertices.push(Vec3::new(x, y, z(x, y)));
        }
    }
    let at = |i: usize, j: usize| (j * xs.len() + i) as u32;
    let mut triangles = Vec::new();
    for j in 0..ys.len() - 1 {
        for i in 0..xs.len() - 1 {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if up {
                triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                triangles.extend([[a, c, b], [a, d, c]]);
            }
        }
    }
    mesh(vertices, triangles)
}

/// `k + 1` evenly spaced values from `-half` to `half`.
fn even(k: usize, half: Real) -> Vec<Real> {
    (0..=k)
        .map(|t| -half + 2.0 * half * t as Real / k as Real)
        .collect()
}

/// A flat square grid of `k × k` cells of side `2 half / k` in the plane z = 0, facing `+z`
/// (`up`) or `−z`.
fn flat_grid(k: usize, half: Real, up: bool) -> TriMesh {
    sheet(&even(k, half), &even(k, half), |_| 0.0, up)
}

#[test]
fn coarse_closest_approach_is_exact_between_the_pieces() {
    // Two flat grids, so every piece is exact (deviation 0) and the walk stops at coarse pairs
    // for any threshold above 0. The obstacle is tilted so that its closest point is a corner:
    // the region over it reports its weighted mean depth; the search after the walk finds the
    // exact distance.
    let tool = flat_grid(8, 0.1, false);
    let obstacle = flat_grid(8, 0.05, true);
    let corner = Vec3::new(0.05, 0.05, 0.0);
    let tilt = nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(0.25, -0.25, 0.0));
    let gap = 0.004;
    let place = Pose {
        position: Vec3::new(0.0137, -0.0211, -gap) - tilt * corner,
        orientation: tilt,
    };
    let mut lod = LodBackend::new(&tool, &[(obstacle, place)]).unwrap();
    let (mut exact, mut coarse) = (ContactSet::new(), ContactSet::new());
    let delta = 0.01;
    lod.query(
        &Pose::identity(),
        &QueryParams::new(delta, 0.0).unwrap(),
        &mut exact,
    )
    .unwrap();
    let st = lod
        .query(
            &Pose::identity(),
            &QueryParams::new(delta, 0.05).unwrap(),
            &mut coarse,
        )
        .unwrap();
    let (d0, _) = min_distance_and_max_depth(&exact);
    let (dc, _) = min_distance_and_max_depth(&coarse);
    assert!((d0 - gap).abs() < 1e-12, "exact {d0}");
    assert!((dc - d0).abs() < 1e-12, "coarse {dc}, exact {d0}");
    assert!(
        coarse
            .iter()
            .any(|c| c.feature_a == haptic_core::NO_FEATURE)
    );
    assert!(st.primitive_pairs_tested < 10, "{st:?}");
}

/// A box of half-extents `h` centred at the origin, each face a `k × k` grid of cells of two
/// triangles (outward, counter-clockwise).
fn grid_box(h: Vec3, k: usize) -> TriMesh {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    // Each face: its normal axis and sign; (u, v) spans it with u × v along the outward normal.
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let (u, v) = if sign > 0.0 { (a, b) } else { (b, a) };
            let base = vertices.len() as u32;
            for i in 0..=k {
                for j in 0..=k {
                    let mut p = Vec3::zeros();
                    p[axis] = sign * h[axis];
                    p[u] = h[u] * (2.0 * i as Real / k as Real - 1.0);
                    p[v] = h[v] * (2.0 * j as Real / k as Real - 1.0);
                    vertices.push(p);
                }
            }
            let at = |i: usize, j: usize| base + (i * (k + 1) + j) as u32;
            for i in 0..k {
                for j in 0..k {
                    triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
    }
    mesh(vertices, triangles)
}

/// A box over a larger one, tilted so that its bottom face crosses the floor's plane and one of
/// its side faces comes within δ: at threshold 0 the weight, its centroid and its weighted depth
/// are the same whether each face is 2 triangles or a fine grid (the issue's "a box and its
/// subdivided copy give the same wrench face-on-face": with them the same, so is the force of
/// one representative, `k_c (d + δ)` at the centroid).
#[test]
fn a_box_and_its_subdivided_copy_give_the_same_contact_sums() {
    let delta = 0.001;
    let tilt = UnitQuaternion::from_scaled_axis(Vector3::new(0.03, -0.02, 0.2));
    let pose = Pose {
        position: Vec3::new(0.006, -0.004, 0.01 + 0.01 + 0.0002),
        orientation: tilt,
    };
    let sums = |k_tool: usize, k_floor: usize| {
        let tool = grid_box(Vec3::new(0.02, 0.015, 0.01), k_tool);
        let floor = grid_box(Vec3::new(0.04, 0.03, 0.01), k_floor);
        let mut lod = LodBackend::new(&tool, &[(floor, Pose::identity())])
            .unwrap()
            .with_max_contacts(None);
        let mut out = ContactSet::new();
        lod.query(&pose, &QueryParams::new(delta, 0.0).unwrap(), &mut out)
            .unwrap();
        assert!(out.iter().any(|c| c.depth_m > 0.0), "crossing");
        weighted_sums(&out, delta)
    };
    let coarse = sums(1, 1);
    for (kt, kf) in [(4, 1), (1, 5), (4, 5)] {
        let fine = sums(kt, kf);
        let w = coarse.0;
        assert!(
            (fine.0 - w).abs() < 1e-9 * w,
            "{kt}×{kf}: Σw {} vs {w}",
            fine.0
        );
        assert!(
            (fine.1 / fine.0 - coarse.1 / w).norm() < 1e-9,
            "{kt}×{kf}: centroid"
        );
        assert!(
            (fine.3 / fine.0 - coarse.3 / w).abs() < 1e-12,
            "{kt}×{kf}: depth"
        );
    }
}

/// The "a box and its subdivided copy give the same wrench within 1 % face-on-face",
/// through the whole contact stage: the contacts at threshold 0, clustered into five clusters
/// (each a torque pair of two springs with their stiffness shares, or one spring where a
/// cluster holds a single contact), and the penalty model's
/// wrench at them with the tool at rest, `(F, T / r)` about the tool's origin. Each
/// tessellation clusters cold from its own contacts, so the partitions differ; the force does
/// not (to 1e-6), and the torque is within 1 %. (Without the stiffness shares the force was
/// 23 % off.) Tilted, so that the gap varies across the face, the force still agrees and the
/// wrench is within 2 %: the torque pairs keep each cluster's couple (with one spring per
/// cluster the tilted torque was up to about 9 % off on this box); what is left is that a
/// coarse contact sits at its region's `g`-weighted centroid while its couple in the clustering
/// weighs by `g²`.
#[test]
fn a_box_and_its_subdivided_copy_give_the_same_clustered_wrench() {
    use haptic_cluster::{ClusterParams, Clusterer};
    use haptic_core::{ContactModel, Kinematics, RigidBody, ToolState};
    use haptic_dynamics::{PenaltyModel, PenaltyParams};

    let delta = 0.001;
    // Face on face: the box's bottom 0.2 mm into the floor, turned about the vertical; then
    // tilted by 0.5° about x, so the gap varies by 0.26 mm across the face.
    let flat = Pose {
        position: Vec3::new(0.006, -0.004, 0.01 + 0.01 - 0.0002),
        orientation: UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 0.2)),
    };
    let tilted = Pose {
        orientation: UnitQuaternion::from_scaled_axis(Vector3::new(0.5f64.to_radians(), 0.0, 0.0))
            * flat.orientation,
        ..flat
    };
    let lever = 0.027;
    let wrench = |pose: &Pose, k_tool: usize, k_floor: usize| {
        let tool = grid_box(Vec3::new(0.02, 0.015, 0.01), k_tool);
        let floor = grid_box(Vec3::new(0.04, 0.03, 0.01), k_floor);
        let mut lod = LodBackend::new(&tool, &[(floor, Pose::identity())]).unwrap();
        let mut contacts = ContactSet::new();
        lod.query(pose, &QueryParams::new(delta, 0.0).unwrap(), &mut contacts)
            .unwrap();
        let mut reps = ContactSet::new();
        let stats = Clusterer::new(ClusterParams::default())
            .unwrap()
            .cluster(contacts.as_slice(), delta, &mut reps)
            .unwrap();
        // A torque pair per cluster whose contacts spread, one spring for a lone contact.
        assert!(
            stats.clusters == 5 && (6..=10).contains(&reps.len()),
            "{k_tool}×{k_floor}: {} contacts, {} clusters, {} springs",
            contacts.len(),
            stats.clusters,
            reps.len()
        );
        let body = RigidBody::sphere(0.05, lever).unwrap();
        let y = ToolState::at_rest(pose).to_vector();
        let w = PenaltyModel::new(PenaltyParams::new(2000.0, 0.0, delta).unwrap())
            .unwrap()
            .evaluate(
                &body,
                &y,
                &Kinematics::new(&body, &y),
                reps.as_slice(),
                None,
            )
            .unwrap();
        let t = w.torque / lever;
        [w.force.x, w.force.y, w.force.z, t.x, t.y, t.z]
    };
    let norm = |v: &[Real; 6]| v.iter().map(|x| x * x).sum::<Real>().sqrt();
    for (name, pose, tolerance) in [("flat", &flat, 0.01), ("tilted", &tilted, 0.02)] {
        let coarse = wrench(pose, 1, 1);
        assert!(norm(&coarse) > 0.0);
        for (kt, kf) in [(4, 1), (1, 5), (4, 5), (8, 8)] {
            let fine = wrench(pose, kt, kf);
            let diff: [Real; 6] = std::array::from_fn(|i| fine[i] - coarse[i]);
            let force = (0..3).map(|i| diff[i] * diff[i]).sum::<Real>().sqrt();
            let f0 = (0..3).map(|i| coarse[i] * coarse[i]).sum::<Real>().sqrt();
            assert!(
                force <= 1e-6 * f0,
                "{name} {kt}×{kf}: force off by {}",
                force / f0
            );
            assert!(
                norm(&diff) <= tolerance * norm(&coarse),
                "{name} {kt}×{kf}: wrench off by {}",
                norm(&diff) / norm(&coarse)
            );
        }
    }
}

/// The penalty the contacts stand for before clustering, `F = Σ a (d + δ) n` and its torque
/// about the tool origin (per unit stiffness), as `(F, T / r)`.
fn integrated_penalty(set: &ContactSet, delta: Real, origin: &Vec3, lever: Real) -> [Real; 6] {
    let (mut f, mut t) = (Vec3::zeros(), Vec3::zeros());
    for c in set.iter() {
        let fi = c.n * (c.area_m2 * c.gap_weight_m(delta));
        f += fi;
        t += (c.p_a - origin).cross(&fi);
    }
    let t = t / lever;
    [f.x, f.y, f.z, t.x, t.y, t.z]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Compact contacts at threshold 0 give the all-pairs wrench within 5 % (the penalty
    /// integrated over the contacts, `Σ a (d + δ) n` and its torque, which the clustering's
    /// representatives sum), on bumpy spheres pressed together, whatever the cap.
    #[test]
    fn compact_contacts_give_the_all_pairs_wrench(
        seed in 0u64..1_000_000,
        delta in 0.002f64..0.008,
        press in 0.0f64..1.0,
        max in 16usize..=256,
    ) {
        let tool = bumpy_sphere(3, 0.03, 0.05, seed);
        let obstacle = bumpy_sphere(3, 0.04, 0.05, seed + 101);
        let mut rng = Lcg(seed ^ 0x5eed);
        let dir = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5).normalize();
        let mut pose = random_pose(&mut rng, 0.0);
        pose.position = dir * (0.07 - delta * press);
        let obstacles = vec![(obstacle, Pose::identity())];
        let mut all = LodBackend::new(&tool, &obstacles).unwrap().with_max_contacts(None);
        let mut compact = all.clone().with_max_contacts(Some(max));
        let params = QueryParams::new(delta, 0.0).unwrap();
        let (mut a, mut b) = (ContactSet::new(), ContactSet::new());
        all.query(&pose, &params, &mut a).unwrap();
        compact.query(&pose, &params, &mut b).unwrap();
        prop_assert!(b.len() <= max);
        let r = all.tool_bounding_radius_m();
        let w0 = integrated_penalty(&a, delta, &pose.position, r);
        let w = integrated_penalty(&b, delta, &pose.position, r);
        let norm = |v: &[Real; 6]| v.iter().map(|x| x * x).sum::<Real>().sqrt();
        let diff: [Real; 6] = std::array::from_fn(|i| w[i] - w0[i]);
        prop_assert!(norm(&w0) > 0.0, "no contact: {} raw", a.len());
        prop_assert!(norm(&diff) <= 0.05 * norm(&w0), "{} raw, {} compact: error {}", a.len(), b.len(), norm(&diff) / norm(&w0));
    }
}

/// The net force of the penalty integrated over `backend`'s contacts at `pose`
/// ([`integrated_penalty`]).
fn net_force(backend: &mut LodBackend, pose: &Pose, delta: Real, threshold: Real) -> Vec3 {
    let radius = backend.tool_bounding_radius_m();
    let mut out = ContactSet::new();
    let params = QueryParams::new(delta, threshold).unwrap();
    backend.query(pose, &params, &mut out).unwrap();
    let w = integrated_penalty(&out, delta, &pose.position, radius);
    Vec3::new(w[0], w[1], w[2])
}

/// [`net_force`] at `threshold` of `reference`'s meshes, compacting, under the paper's rule and
/// under the coherence rule.
fn under_both_rules(
    reference: &LodBackend,
    pose: &Pose,
    delta: Real,
    threshold: Real,
) -> (Vec3, Vec3) {
    let mut paper = reference
        .clone()
        .with_max_contacts(Some(256))
        .with_stopping_rule(StoppingRule::Deviation);
    let mut coherent = paper
        .clone()
        .with_stopping_rule(StoppingRule::DeviationAndCoherence);
    (
        net_force(&mut paper, pose, delta, threshold),
        net_force(&mut coherent, pose, delta, threshold),
    )
}

/// A corrugated sheet over `[−half_x, half_x] × [−half_y, half_y]`: `z = tri(x)`, a triangle
/// wave of period `period` and flanks at 45° (peak to peak `period / 2`), its kinks on grid
/// lines so that every flank is exact; facing `+z` (`up`) or `−z`.
fn corrugated(period: Real, half_x: Real, half_y: Real, up: bool) -> TriMesh {
    let kx = (2.0 * half_x / (0.5 * period)).round() as usize;
    let tri = |x: Real| {
        let t = ((x / period).rem_euclid(1.0) - 0.5).abs();
        period * (0.25 - t)
    };
    sheet(&even(kx, half_x), &even(4, half_y), tri, up)
}

/// Two mating corrugated sheets, the tool shifted sideways so that only the flanks facing one
/// way come within δ (a thread pushed along its axis, in miniature): the surface pushes the
/// tool sideways as much as up. At a threshold whose `ε` exceeds the corrugation, the paper's
/// rule stops at flat pieces across whole periods (normal coherence cos 45°) and pushes straight
/// up; the coherence rule splits them down to the flanks and gives the all-pairs force.
#[test]
fn the_coherence_rule_keeps_the_force_of_surfaces_with_small_features() {
    let period = 0.008;
    let obstacle = corrugated(period, 0.032, 0.016, true);
    let tool = corrugated(period, 0.032, 0.016, false);
    // Tool flanks 1 mm above the obstacle's, shifted 0.6 mm along x: the rising flanks are
    // 0.28 mm apart (normal gap (1 − 0.6) / √2 mm), the falling ones 1.13 mm, beyond δ.
    let pose = Pose {
        position: Vec3::new(0.0006, 0.0, 0.001),
        orientation: UnitQuaternion::identity(),
    };
    let delta = 0.001;
    let obstacles = vec![(obstacle, Pose::identity())];
    let mut reference = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    let radius = reference.tool_bounding_radius_m();
    let f0 = net_force(&mut reference, &pose, delta, 0.0);
    // `Σ a (d + δ) n` along the normals out of the tool, (1, 0, −1)/√2: the surface pushes the
    // tool toward −x and up, equally.
    assert!(f0.x > 0.0 && (f0.x + f0.z).abs() < 1e-6 * f0.x, "{f0:?}");
    // ε = 0.15 × radius ≈ 5 mm under the paper's rule: more than the corrugation's 4 mm peak
    // to peak.
    let threshold = 0.15;
    assert!(threshold * radius > 0.5 * period);
    let rel = |f: Vec3| (f - f0).norm() / f0.norm();
    let (fp, fc) = under_both_rules(&reference, &pose, delta, threshold);
    assert!(rel(fp) > 0.3, "paper's rule {fp:?} against {f0:?}");
    // The coherence rule caps ε at δ (here about 2.8 % of the radius), and each piece that
    // writes a contact stands for its surface within 1 − c ≤ ε / radius.
    assert!(
        rel(fc) < threshold && rel(fc) < 0.1 * rel(fp),
        "coherence rule {fc:?} against {f0:?}"
    );
    // The budgeted rule: every region here carries its share of the force and has c ≈ cos 45°,
    // so the sum of their bounds is far over the budget and they are refined as the coherence
    // rule refines them.
    let mut budget = reference
        .clone()
        .with_max_contacts(Some(256))
        .with_stopping_rule(StoppingRule::CoherenceBudget);
    let fb = net_force(&mut budget, &pose, delta, threshold);
    assert!(
        rel(fb) < threshold && rel(fb) < 0.1 * rel(fp),
        "budgeted rule {fb:?} against {f0:?}"
    );
}

/// A tool that presses a flat plate on a flat sheet and holds a corrugated strip over it,
/// whose ridges come within δ while its coarse pieces (and the surfaces' mean about them) lie
/// beyond δ: those coarse regions weigh next to nothing beside the plate's, so a budget on the
/// regions' summed bounds alone would keep them, and lose the ridges' force. The budgeted
/// rule refines incoherent regions whose pieces lie apart whatever the budget, and finds the
/// ridges as the coherence rule does, still coarser than the triangles (without that, 0.11
/// off).
#[test]
fn the_budgeted_rule_refines_incoherent_regions_whose_pieces_lie_apart() {
    let period = 0.008;
    // Plate for x < 0 at z = 0.4 mm; for x > 0 a triangle wave whose troughs (facing down)
    // come to z = 0 and ridges rise 2 mm above, its kinks on grid lines. Placed 0.4 mm up: the
    // plate 0.8 mm from the sheet, the troughs 0.4 mm.
    let wave = |x: Real| {
        if x <= 0.0 {
            0.0004
        } else {
            let t = ((x / period).rem_euclid(1.0) - 0.5).abs();
            0.5 * period * (0.5 - t)
        }
    };
    let xs = even(24, 0.024);
    let tool = sheet(&xs, &even(4, 0.008), wave, false);
    let obstacles = vec![(flat_grid(12, 0.03, true), Pose::identity())];
    let delta = 0.001;
    let pose = Pose {
        position: Vec3::new(0.0, 0.0, 0.0004),
        orientation: UnitQuaternion::identity(),
    };
    let mut reference = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    let f0 = net_force(&mut reference, &pose, delta, 0.0);
    let threshold = 0.15;
    let rel = |f: Vec3| (f - f0).norm() / f0.norm();
    let at = |rule| {
        let mut b = reference
            .clone()
            .with_max_contacts(Some(256))
            .with_stopping_rule(rule);
        let mut out = ContactSet::new();
        let params = QueryParams::new(delta, threshold).unwrap();
        let stats = b.query(&pose, &params, &mut out).unwrap();
        (
            net_force(&mut b, &pose, delta, threshold),
            stats.node_pairs_tested,
        )
    };
    let (fc, nc) = at(StoppingRule::DeviationAndCoherence);
    let (fb, nb) = at(StoppingRule::CoherenceBudget);
    let (fp, _) = at(StoppingRule::Deviation);
    // (The paper's rule stops at the root pair, whose pieces are beyond δ, and finds nothing.)
    assert!(rel(fp) > 0.5, "paper's rule {fp:?} against {f0:?}");
    assert!(rel(fc) < 0.05, "coherence rule {fc:?} against {f0:?}");
    assert!(rel(fb) < 0.05, "budgeted rule {fb:?} against {f0:?}");
    let mut exact = reference.clone();
    let mut out = ContactSet::new();
    let n0 = exact
        .query(&pose, &QueryParams::new(delta, 0.0).unwrap(), &mut out)
        .unwrap()
        .node_pairs_tested;
    assert!(
        nb < n0,
        "{nb} node pairs against {n0} at threshold 0 (the coherence rule {nc})"
    );
}

/// The coherence rule caps `ε` at `δ`: above the threshold `δ / radius` every threshold gives
/// the contacts of that one (the same walk), while the paper's rule keeps coarsening.
#[test]
fn the_coherence_rule_caps_epsilon_at_delta() {
    let period = 0.008;
    let obstacles = vec![(corrugated(period, 0.032, 0.016, true), Pose::identity())];
    let tool = corrugated(period, 0.032, 0.016, false);
    let pose = Pose {
        position: Vec3::new(0.0006, 0.0, 0.001),
        orientation: UnitQuaternion::identity(),
    };
    let delta = 0.001;
    let paper = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_stopping_rule(StoppingRule::Deviation);
    let radius = paper.tool_bounding_radius_m();
    let at_delta = delta / radius;
    assert!(0.15 > 4.0 * at_delta, "δ / radius {at_delta}");
    let contacts = |backend: &mut LodBackend, threshold: Real| {
        let mut out = ContactSet::new();
        let params = QueryParams::new(delta, threshold).unwrap();
        let stats = backend.query(&pose, &params, &mut out).unwrap();
        (out.as_slice().to_vec(), stats.node_pairs_tested)
    };
    let mut coherent = paper
        .clone()
        .with_stopping_rule(StoppingRule::DeviationAndCoherence);
    let capped = contacts(&mut coherent, at_delta);
    assert!(!capped.0.is_empty());
    for threshold in [0.05, 0.15, 1.0] {
        assert_eq!(contacts(&mut coherent, threshold), capped, "{threshold}");
    }
    let mut paper = paper;
    let (fine, coarse) = (contacts(&mut paper, at_delta), contacts(&mut paper, 0.15));
    assert!(
        coarse.1 < fine.1,
        "{} node pairs against {}",
        coarse.1,
        fine.1
    );
}

/// A trough (`z = c x²`, 1.1 mm deep, facing down) whose lowest line is 0.6 mm over a flat
/// sheet, δ = 1 mm: its coarse pieces lie where the trough's surface is on average, up to half
/// their deviation above its lowest line, so a piece whose deviation is within `ε = δ` can lie
/// beyond δ while its surface comes to 0.6 mm. The coherence rule drops a pair only where the
/// surfaces its pieces stand for are out of reach, and keeps the force; the paper's rule, whose
/// cull is at the pieces, loses it.
#[test]
fn the_coherence_rule_keeps_contacts_whose_pieces_lie_beyond_delta() {
    let (half_x, sag) = (0.008, 0.0011);
    let c = sag / (half_x * half_x);
    let tool = sheet(&even(16, half_x), &even(4, 0.004), |x| c * x * x, false);
    let obstacles = vec![(flat_grid(8, 0.012, true), Pose::identity())];
    let (delta, gap) = (0.001, 0.0006);
    let pose = Pose {
        position: Vec3::new(0.0, 0.0, gap),
        orientation: UnitQuaternion::identity(),
    };
    let mut reference = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    let f0 = net_force(&mut reference, &pose, delta, 0.0);
    assert!(f0.z < 0.0, "{f0:?}");
    // Above δ / radius both rules may stop at pieces of deviation up to δ, more than the sag.
    let (fp, fc) = under_both_rules(&reference, &pose, delta, 1.0);
    let rel = |f: Vec3| (f - f0).norm() / f0.norm();
    // (Culling at the pieces, as the paper's rule does, the coherence rule lost it too: 1.0.)
    assert!(rel(fp) > 0.5, "paper's rule {fp:?} against {f0:?}");
    assert!(rel(fc) < 0.1, "coherence rule {fc:?} against {f0:?}");
}

/// A random convex polygon of 3–8 vertices, CCW about its normal (returned), about `center`.
fn random_piece(rng: &mut Lcg, center: Vec3, size: Real) -> (Vec<Vec3>, Vec3) {
    let n = random_direction(rng);
    let (u, w) = crate::geometry::plane_basis(&n);
    let k = 3 + (rng.next() * 6.0) as usize;
    let mut angles: Vec<Real> = (0..k).map(|_| rng.next() * std::f64::consts::TAU).collect();
    angles.sort_by(Real::total_cmp);
    let r = size * (0.2 + rng.next());
    let verts = angles
        .iter()
        .map(|t| center + (u * t.cos() + w * t.sin()) * r)
        .collect();
    (verts, n)
}

fn random_direction(rng: &mut Lcg) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next(), rng.next(), rng.next()) * 2.0 - Vec3::repeat(1.0);
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

#[test]
fn pieces_found_beside_each_other_have_no_region_and_no_nearer_approach() {
    use super::build::PieceBall;
    use super::query::beside;
    use crate::geometry::convex_polygon_pair;
    use crate::slab::{HeightOffset, pair_region};
    let mut rng = Lcg(15);
    let (mut found_beside, mut with_region) = (0, 0);
    for case in 0..4000 {
        let delta = 0.05 + rng.next();
        let (a, na) = random_piece(&mut rng, Vec3::zeros(), 1.0);
        let offset = (Vec3::new(rng.next(), rng.next(), rng.next()) - Vec3::repeat(0.5)) * 4.0;
        let (b, nb) = random_piece(&mut rng, offset, 1.0);
        // Found so far: nothing, a crossing, or some distance.
        let found_m = [Real::INFINITY, 0.0, rng.next() * 3.0][case % 3];
        let (ball_a, ball_b) = (PieceBall::of(&a, Vec3::zeros()), PieceBall::of(&b, offset));
        let offsets = [
            HeightOffset::NONE,
            HeightOffset {
                mean_m: 0.3,
                half_width_m: 0.5,
            },
        ];
        if !beside(&ball_a.center, ball_a.radius_m, &ball_b, &nb, found_m) {
            with_region +=
                usize::from(pair_region(&a, &b, &nb, delta, offsets[0]).region.is_some());
            continue;
        }
        found_beside += 1;
        for o in offsets {
            let r = pair_region(&a, &b, &nb, delta, o);
            assert!(
                r.region.is_none() && r.nearest_m.is_infinite(),
                "case {case}: {r:?}"
            );
        }
        let d = convex_polygon_pair(&a, &na, &b, &nb).distance;
        assert!(
            d >= found_m,
            "case {case}: the pieces are {d} apart, nearer than {found_m}"
        );
    }
    // Neither test vacuous.
    assert!(
        found_beside > 500 && with_region > 100,
        "{found_beside} beside, {with_region} with a region"
    );
}

/// The threshold a query holds: the one asked under the paper's rule; at most `δ / radius`
/// under the default rule, whose `ε` is capped at `δ`.
#[test]
fn the_threshold_reached_is_capped_where_the_rule_caps_epsilon() {
    let box_mesh = cuboid(Vec3::new(0.01, 0.01, 0.01));
    let obstacles = vec![(cuboid(Vec3::new(0.05, 0.05, 0.01)), Pose::identity())];
    let lod = LodBackend::new(&box_mesh, &obstacles).unwrap();
    let r = lod.tool_bounding_radius_m();
    let delta = 1e-3;
    let at = |threshold| QueryParams::new(delta, threshold).unwrap();
    assert_eq!(lod.stopping_rule(), StoppingRule::CoherenceBudget);
    assert_eq!(lod.threshold_reached(&at(0.0)), 0.0);
    assert_eq!(lod.threshold_reached(&at(0.5 * delta / r)), 0.5 * delta / r);
    assert_eq!(lod.threshold_reached(&at(0.5)), delta / r);
    let paper = lod.with_stopping_rule(StoppingRule::Deviation);
    assert_eq!(paper.threshold_reached(&at(0.5)), 0.5);
}

/// A cap (a paraboloid sagging 3 mm over 16 mm, facing down) 0.3 or 0.6 mm over a flat sheet,
/// δ = 1 mm, `ε = δ`: its coarse pieces are coherent enough to stop (their normals spread
/// little), but the surface they stand for spreads over three penalty bands about them, and
/// only the part near the cap's lowest point lies within δ. A weight averaged over that spread
/// says little of where: the budgeted rule bounds each region's weight error by its area times
/// the spread's half-width, refines those regions, and gives the all-pairs force (with the
/// direction bound alone it was 0.12 and 0.59 off).
#[test]
fn the_budgeted_rule_refines_regions_whose_weight_the_spread_cannot_tell() {
    let (half, sag) = (0.008, 0.003);
    let c = sag / (half * half);
    let tool = surface(
        &even(16, half),
        &even(16, half),
        |x, y| c * (x * x + y * y),
        false,
    );
    let obstacles = vec![(flat_grid(8, 0.012, true), Pose::identity())];
    let delta = 0.001;
    let mut reference = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    for gap in [0.0003, 0.0006] {
        let pose = Pose {
            position: Vec3::new(0.0, 0.0, gap),
            orientation: UnitQuaternion::identity(),
        };
        let f0 = net_force(&mut reference, &pose, delta, 0.0);
        assert!(f0.z < 0.0, "{f0:?}");
        let mut budget = reference
            .clone()
            .with_max_contacts(Some(256))
            .with_stopping_rule(StoppingRule::CoherenceBudget);
        // Threshold 1: `ε` capped at δ.
        let fb = net_force(&mut budget, &pose, delta, 1.0);
        let rel = (fb - f0).norm() / f0.norm();
        assert!(rel < 0.05, "gap {gap}: {fb:?} against {f0:?}, {rel}");
    }
}

/// A reported closest approach is a distance between the surfaces, never nearer than they are,
/// whatever the threshold. Over a shallow V groove (two planes 9° apart), the stopped piece of
/// the whole groove lies in the middle of its slab, 0.8 mm above the groove's bottom: a cube
/// held corner down 0.5–1.8 mm over the bottom (beyond `δ` = 1 mm) is within `δ` of that piece.
/// Written at the pieces' distance, the closest approach was a contact within `δ` where the
/// surfaces have none, and a contact alone in a call pushed with the whole stiffness, whatever
/// its area; it now pushes nothing (no stiffness share: `closest.rs`).
#[test]
fn a_closest_approach_is_never_nearer_than_the_surfaces() {
    let (half, rise) = (0.02, 0.0016);
    let groove = mesh(
        vec![
            Vec3::new(-half, -half, rise),
            Vec3::new(0.0, -half, 0.0),
            Vec3::new(half, -half, rise),
            Vec3::new(-half, half, rise),
            Vec3::new(0.0, half, 0.0),
            Vec3::new(half, half, rise),
        ],
        vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]],
    );
    let tool = cuboid(Vec3::repeat(0.004));
    let obstacles = vec![(groove, Pose::identity())];
    let mut lod = LodBackend::new(&tool, &obstacles).unwrap();
    let delta = 0.001;
    // The cube's corner (1, 1, 1) turned to point straight down.
    let corner = Vector3::new(1.0, 1.0, 1.0).normalize();
    let down = UnitQuaternion::rotation_between(&corner, &-Vector3::z()).unwrap();
    let reach = 0.004 * 3f64.sqrt();
    let mut rng = Lcg(5);
    let (mut exact, mut coarse) = (ContactSet::new(), ContactSet::new());
    let (mut beyond, mut reported) = (0, 0);
    for _ in 0..200 {
        let height = 0.0005 + 0.0013 * rng.next();
        let turn = UnitQuaternion::from_scaled_axis(Vector3::new(
            0.2 * (rng.next() - 0.5),
            0.2 * (rng.next() - 0.5),
            std::f64::consts::TAU * rng.next(),
        ));
        let pose = Pose {
            position: Vec3::new(0.004 * (rng.next() - 0.5), 0.01 * (rng.next() - 0.5), 0.0)
                + Vec3::z() * (height + reach),
            orientation: turn * down,
        };
        lod.query(&pose, &QueryParams::new(delta, 0.0).unwrap(), &mut exact)
            .unwrap();
        let (nearest, _) = min_distance_and_max_depth(&exact);
        beyond += usize::from(exact.is_empty());
        lod.query(&pose, &QueryParams::new(delta, 0.2).unwrap(), &mut coarse)
            .unwrap();
        for c in coarse.iter() {
            if c.area_m2 == crate::compact::area_floor_m2(delta) {
                reported += 1;
                assert!(
                    -c.depth_m >= nearest - 1e-9,
                    "a closest approach at {} m, the surfaces {nearest} m apart",
                    -c.depth_m
                );
                assert_eq!(c.stiffness_share, 0.0);
            }
        }
    }
    // Both cases were met: surfaces beyond `δ`, and closest approaches within it.
    assert!(
        beyond >= 20 && reported >= 20,
        "{beyond} beyond, {reported} reported"
    );
}

/// A round peg standing in a drilled hole, pushed sideways so that its wall crosses the
/// rim by 20 µm on one side and stays 120 µm inside it on the other: the penalty's band along
/// the wall over the plate's face, 2δ tall, pushes the peg along its axis on the side where it
/// crosses, and nowhere else. The plate's coarse pieces around the hole are convex: they
/// overhang the opening by more than the clearance (where the wall would be within their
/// prisms with no surface there), or stop short of the rim where the wall does cross (where it
/// would be beside their prisms with surface there). Edge-on to those pieces, the wall's
/// region is all there or all missing as the rim's place, known only within the pieces'
/// deviations, says: the budgeted rule refines such regions, and the pairs beside a prism
/// within those deviations, down to where the pieces can tell: within the threshold of the
/// all-pairs force, at a ninth of its node pairs. (The suite's peg in its hole at 2.5 %:
/// axial forces a third of the reference's, and ghosts where it has none.)
#[test]
fn the_budgeted_rule_finds_where_a_wall_crosses_a_rim() {
    let (r, clearance) = (0.004, 0.00005);
    let segments = 64;
    let tool = super::testmesh::cylinder(r, 0.006, segments);
    let plate = annulus(r + clearance, 0.012, segments);
    let delta = 0.0005;
    let obstacles = vec![(plate, Pose::identity())];
    let mut reference = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    let pose = Pose {
        position: Vec3::new(0.00007, 0.0, -0.003),
        orientation: UnitQuaternion::identity(),
    };
    let f0 = net_force(&mut reference, &pose, delta, 0.0);
    // Along the axis only (the band pushes along the plate's normal).
    assert!(
        f0.z.abs() > 0.0 && f0.xy().norm() < 1e-9 * f0.z.abs(),
        "{f0:?}"
    );
    let mut budget = reference
        .clone()
        .with_max_contacts(Some(256))
        .with_stopping_rule(StoppingRule::CoherenceBudget);
    let pairs = |b: &mut LodBackend, threshold: Real| {
        let mut out = ContactSet::new();
        let params = QueryParams::new(delta, threshold).unwrap();
        b.query(&pose, &params, &mut out).unwrap().node_pairs_tested
    };
    let all_pairs = pairs(&mut reference.clone(), 0.0);
    for threshold in [0.01, 0.025] {
        let f = net_force(&mut budget, &pose, delta, threshold);
        let rel = (f - f0).norm() / f0.norm();
        // (Without the unsure weights: 0.20 and 0.37.)
        assert!(
            rel < threshold,
            "threshold {threshold}: {f:?} against {f0:?}, {rel}"
        );
        // Refined where the rim is, not everywhere.
        let n = pairs(&mut budget, threshold);
        assert!(2 * n < all_pairs, "{n} node pairs against {all_pairs} at 0");
    }
}

/// A tube's inner wall of radius `r`, from z = 0 to `h`, facing its axis: `rows` rows of
/// `segments` quads, each split in two, the first vertex of each ring turned by 0.37 of a
/// segment (so that no facet lines up with the x axis).
fn tube(r: Real, h: Real, segments: usize, rows: usize) -> TriMesh {
    turned_tube(r, h, segments, rows, 0.37)
}

/// [`tube`] with the first vertex of each ring turned by `turn` of a segment.
fn turned_tube(r: Real, h: Real, segments: usize, rows: usize, turn: Real) -> TriMesh {
    let n = segments as u32;
    let mut v = Vec::new();
    for k in 0..=rows {
        let z = h * k as Real / rows as Real;
        for s in 0..segments {
            let a = std::f64::consts::TAU * (s as Real + turn) / segments as Real;
            v.push(Vec3::new(r * a.cos(), r * a.sin(), z));
        }
    }
    let mut t = Vec::new();
    for k in 0..rows as u32 {
        for s in 0..n {
            let s1 = (s + 1) % n;
            let (a, b, c, d) = (k * n + s, k * n + s1, (k + 1) * n + s1, (k + 1) * n + s);
            t.push([a, c, b]);
            t.push([a, d, c]);
        }
    }
    mesh(v, t)
}

/// A round peg (radius 4 mm) inside a tube 50 µm wider, pushed 10–30 µm sideways, at three
/// pairs of tessellations that line up nowhere (a peg of 64, 96 or 32 sides in a tube of 48,
/// 40 or 80): the wall's contacts push nearly all ways at once and cancel, so that the net
/// force is a small part of what the regions carry, and the budget with it. Below the
/// regions the budget takes out, the regions written pair by pair are convex pieces of a
/// curved patch whose weights are off by up to three times where they lie. Held to their
/// share of the budget (`refine.rs`), the force's error at 1 % and 2.5 % is within the suite's
/// goals: a median of 0.008 and at most 0.040 of the all-pairs force (without that share: 0.07
/// and 0.36, and 0.25–0.36 on the 32-sided peg at 2.5 %). The peg's ends lie on walls of the
/// 80-sided tube's prisms (its rows are a millimetre apart): without the rule that a polygon on
/// a wall counts half in each prism beside it (`slab.rs`), the reference itself gave the ends'
/// regions once, twice or not at all as roundoff had it, and the 32-sided peg's errors were
/// 0.023–0.073, or 0.09–0.17 in another basis of the obstacle's plane.
#[test]
fn the_budgeted_rule_holds_a_peg_in_a_tube_on_any_tessellation() {
    let (r, clearance) = (0.004, 0.00005);
    let poses: Vec<Pose> = [(3e-5, 0.0), (1e-5, 2e-5), (-2e-5, 5e-6)]
        .iter()
        .map(|&(dx, dy)| Pose {
            position: Vec3::new(dx, dy, 0.002),
            orientation: UnitQuaternion::identity(),
        })
        .collect();
    let mut errors = Vec::new();
    for (peg_sides, tube_sides, rows) in [(64, 48, 8), (96, 40, 6), (32, 80, 10)] {
        let tool = super::testmesh::cylinder(r, 0.006, peg_sides);
        let obstacle = tube(r + clearance, 0.010, tube_sides, rows);
        errors.extend(budget_errors(&tool, obstacle, &poses));
    }
    let (median, worst) = median_and_worst(&errors);
    assert!(median <= 0.02 && worst <= 0.05, "{errors:?}");
}

/// A round peg (radius 4 mm, 6 mm long, its origin at its middle) centred in a tube 50 µm wider
/// and tilted by 0.1°, at three pairs of tessellations that line up nowhere (a peg of 40, 64
/// or 32 sides in 4, 7 or 9 layers, in a tube of 33, 48 or 80 sides in 5, 8 or 10 rows), the
/// tube turned by 0 or 0.37 of a segment: the wall's contacts push all ways and cancel, so that
/// the wrench is the tilt's torque alone, a small part of what the regions carry, and the
/// budget is small with it. The facing pieces of two walls that line up nowhere lie beside
/// each other's prisms within their deviations, and the bands their surfaces may have over
/// each other are where what does not cancel is lost, unless the budget is shown them
/// (`refine.rs`). So are the slivers where two facing pieces meet at a seam of the obstacle's,
/// whose weight the lean of the obstacle's triangles from its piece decides: their weight's
/// error along the prism's walls is shown to the budget too. The wrench `(F, T / r)` of the
/// penalty the contacts stand for against the all-pairs one at 2.5 %: a median of 0.003 and at
/// most 0.021 over the 18 poses; without the walls' term, 0.005 and 0.063 (0.232 on the suite's
/// coarse bushing, where the two walls' first vertices line up at the same angle). (Before that:
/// without the bands, 0.101 and 0.21 rather than 0.081 and 0.17; before the obstacle pieces'
/// normal spread entered the stopping rule, `stopping.rs`, 0.062 and 0.25 with the bands,
/// 0.119 and 0.37 without; half that spread gave 0.105 and 0.35, the tool pieces' spread too
/// 0.184 and 0.33: on walls whose forces cancel, which pieces meet where decides the error more
/// than how fine they are.)
#[test]
fn the_budgeted_rule_holds_a_centred_peg_in_a_tube_on_any_tessellation() {
    let (r, clearance, delta) = (0.004, 0.00005, 0.0005);
    let poses: Vec<Pose> = [(-0.001, 1.0), (0.001, -1.0), (0.0, 1.0)]
        .iter()
        .map(|&(dz, about): &(Real, Real)| Pose {
            position: Vec3::new(0.0, 0.0, 0.005 + dz),
            orientation: UnitQuaternion::from_scaled_axis(
                Vec3::new(0.0, about, 0.0) * 0.1f64.to_radians(),
            ),
        })
        .collect();
    let mut errors = Vec::new();
    for (peg_sides, tube_sides, rows) in [(40, 33, 5), (64, 48, 8), (32, 80, 10)] {
        let tool = super::testmesh::layered_cylinder(r, 0.006, peg_sides, rows - 1)
            .translated(&Vec3::new(0.0, 0.0, -0.003))
            .unwrap();
        for turn in [0.0, 0.37] {
            let bore = turned_tube(r + clearance, 0.010, tube_sides, rows, turn);
            let (mut reference, mut budget) = all_pairs_and_budgeted(&tool, bore);
            let lever = reference.tool_bounding_radius_m();
            for pose in &poses {
                let wrench = |backend: &mut LodBackend, threshold| {
                    let mut out = ContactSet::new();
                    let params = QueryParams::new(delta, threshold).unwrap();
                    backend.query(pose, &params, &mut out).unwrap();
                    integrated_penalty(&out, delta, &pose.position, lever)
                };
                let w0 = wrench(&mut reference, 0.0);
                let w = wrench(&mut budget, 0.025);
                let norm = |v: &[Real; 6]| v.iter().map(|x| x * x).sum::<Real>().sqrt();
                let diff: [Real; 6] = std::array::from_fn(|i| w[i] - w0[i]);
                errors.push(norm(&diff) / norm(&w0));
            }
        }
    }
    let (median, worst) = median_and_worst(&errors);
    assert!(median <= 0.02 && worst <= 0.04, "{errors:?}");
}

/// `tool` against `obstacle` (at the origin): the all-pairs reference (every contact kept), and
/// the budgeted rule with 256 contacts at most.
fn all_pairs_and_budgeted(tool: &TriMesh, obstacle: TriMesh) -> (LodBackend, LodBackend) {
    let obstacles = vec![(obstacle, Pose::identity())];
    let reference = LodBackend::new(tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    let budget = reference
        .clone()
        .with_max_contacts(Some(256))
        .with_stopping_rule(StoppingRule::CoherenceBudget);
    (reference, budget)
}

/// The budgeted rule's error at 1 % and 2.5 % (256 contacts at most) against the all-pairs
/// force ([`net_force`], δ = 0.5 mm), for `tool` against `obstacle` at each of `poses`.
fn budget_errors(tool: &TriMesh, obstacle: TriMesh, poses: &[Pose]) -> Vec<Real> {
    let delta = 0.0005;
    let (mut reference, mut budget) = all_pairs_and_budgeted(tool, obstacle);
    let mut errors = Vec::new();
    for pose in poses {
        let f0 = net_force(&mut reference, pose, delta, 0.0);
        for threshold in [0.01, 0.025] {
            let f = net_force(&mut budget, pose, delta, threshold);
            errors.push((f - f0).norm() / f0.norm());
        }
    }
    errors
}

/// The median and the largest of `errors`.
fn median_and_worst(errors: &[Real]) -> (Real, Real) {
    let mut sorted = errors.to_vec();
    sorted.sort_by(Real::total_cmp);
    (sorted[sorted.len() / 2], sorted[sorted.len() - 1])
}

/// A square plate's top face (z = 0, facing `+z`, half-width `half_m`) around a round hole of
/// radius `r_in`, meshed out to the square's boundary, the rays half a segment off the axes
/// ([`drilled_face`]).
fn drilled_square(r_in: Real, half_m: Real, segments: usize) -> TriMesh {
    drilled_face(r_in, segments, 0.5, |c, d| half_m / c.abs().max(d.abs()))
}

/// A round peg crossing the rim of a hole drilled in a square plate, at three tessellations
/// of the peg (24, 64, 100 sides) and the plate (40, 48, 36 segments), pushed sideways in
/// three directions so that its wall crosses the rim by 20 µm on one side. The plate's coarse
/// pieces have corners at the rim, and past a corner no wall of their prisms separates them
/// from an edge-on piece of the peg's wall: only a side of that piece's shadow tells how
/// near it is (`slab::beside_prism_m`). Without it, the axial force of the band along the
/// crossing was lost in part: errors of 0.09 (median) and up to 0.30 of the all-pairs force;
/// with it, 0.016 and 0.22. (What is left: a piece of the wall over a rim piece's prism in
/// part, whose band lies over a sliver of its length where the wall's lies over most of it,
/// 1.6e-11 against 2.7e-10 m³; refining such regions whatever the budget made this scene
/// exact but the suite's peg and coarse bolt worse without clustering, probe 30.)
#[test]
fn the_budgeted_rule_finds_a_wall_crossing_a_rim_past_the_pieces_corners() {
    let (r, clearance) = (0.004, 0.00005);
    let poses: Vec<Pose> = [0.3, 1.9, 4.0]
        .iter()
        .map(|&angle: &Real| Pose {
            position: Vec3::new(0.00007 * angle.cos(), 0.00007 * angle.sin(), -0.003),
            orientation: UnitQuaternion::identity(),
        })
        .collect();
    let mut errors = Vec::new();
    for (peg_sides, plate_segments) in [(24, 40), (64, 48), (100, 36)] {
        let tool = super::testmesh::cylinder(r, 0.006, peg_sides);
        let plate = drilled_square(r + clearance, 0.012, plate_segments);
        errors.extend(budget_errors(&tool, plate, &poses));
    }
    let (median, worst) = median_and_worst(&errors);
    assert!(median <= 0.05 && worst <= 0.25, "{errors:?}");
}

/// A bar (a fork's tine, 18 cm long) pressed into a bumpy ball smaller than it, whose
/// triangles (about 1.3 mm) are smaller than `δ` (2 mm) and whose surface is curved on that
/// scale (bumps of a tenth of its 2 cm radius): the obstacle's coarse pieces that make `ε`
/// (`δ` here) stand for triangles whose normals spread by tens of degrees, and their prisms do
/// not say which part of the bar lies over their surface. The force at 2.5 % against the
/// all-pairs one over 24 poses: a median of 0.036 and at most 0.089 with the pieces' normal
/// spread in the stopping rule (`stopping.rs`), 0.073 and 0.184 without.
#[test]
fn the_budgeted_rule_holds_bars_on_a_ball_curved_on_the_scale_of_delta() {
    let (r, delta) = (0.02, 0.002);
    let ball = bumpy_sphere(4, r, 0.1, 11);
    let bar = cuboid(Vec3::new(0.09, 0.0015, 0.0015));
    let obstacles = vec![(ball, Pose::identity())];
    let mut reference = LodBackend::new(&bar, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    let mut budget = LodBackend::new(&bar, &obstacles).unwrap();
    let mut rng = Lcg(3);
    let mut errors = Vec::new();
    for _ in 0..24 {
        // Across the top of the ball, in by 0.2–1.6 δ, turned about z and tilted a little.
        let depth = delta * (0.2 + 1.4 * rng.next());
        let turn = UnitQuaternion::from_scaled_axis(Vector3::new(
            0.1 * (rng.next() - 0.5),
            0.1 * (rng.next() - 0.5),
            std::f64::consts::TAU * rng.next(),
        ));
        let side = Vec3::new(0.006 * (rng.next() - 0.5), 0.006 * (rng.next() - 0.5), 0.0);
        let pose = Pose {
            position: side + Vec3::z() * (r + 0.0015 - depth),
            orientation: turn,
        };
        let f0 = net_force(&mut reference, &pose, delta, 0.0);
        let f = net_force(&mut budget, &pose, delta, 0.025);
        if f0.norm() > 0.0 {
            errors.push((f - f0).norm() / f0.norm());
        }
    }
    assert_eq!(errors.len(), 24);
    let (median, worst) = median_and_worst(&errors);
    assert!(median <= 0.05 && worst <= 0.12, "{errors:?}");
}

/// The repository's mesh `name` (`assets/meshes`) at `scale` (m per file unit).
fn asset(name: &str, scale: Real) -> TriMesh {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/meshes");
    TriMesh::load(dir.join(name), &crate::LoadOptions::with_scale(scale))
        .unwrap()
        .0
}

/// [`asset`] in its body frame: moved so that its centre of mass is the origin.
fn asset_tool(name: &str, scale: Real) -> TriMesh {
    let mesh = asset(name, scale);
    let com = mesh.mass_properties(1000.0).unwrap().centre_of_mass_m;
    mesh.translated(&-com).unwrap()
}

/// At a first touch a few triangles come within `δ` while the coarse pieces that make `ε` lie
/// beside each other or beyond the slab, so that the walk writes no region: the net force is
/// then none and so is the budget, and the pairs that came within reach are walked down to
/// their triangles (`query::first_touch`). Three first touches of the suite's fork on the cow
/// (`fork-on-spot`: the repository's fork on Spot at 8.5 cm, `δ` = 2 mm): the all-pairs
/// reference has two shallow regions at each, and LOD at 2.5 % had none (its force none, an
/// error of 1); now it has them, and the same force.
#[test]
fn a_first_touch_pushes_as_the_surfaces_do() {
    let tool = asset_tool("basemesh_fork.stl", 1.0);
    let (mut reference, mut budget) =
        all_pairs_and_budgeted(&tool, asset("spot_keenan_5856.stl", 0.05));
    let delta = 0.002;
    for (p, q) in [
        (
            [2e-3, 7.421_550_571_918_486e-3, 5.549_989_696_209_397e-2],
            [-2.165_061_254_187_312_5e-3, 1.249_998_697_917_073_3e-3],
        ),
        (
            [
                2.143_307_179_915_988e-3,
                7.124_667_738_178_773e-3,
                5.548_412_636_472_293e-2,
            ],
            [-2.110_817_614_985_085e-3, 1.339_565_592_065_649_8e-3],
        ),
        (
            [
                1.927_014_696_406_862_4e-3,
                7.564_857_751_834_469e-3,
                5.549_595_041_895_051_5e-2,
            ],
            [-2.190_764_418_061_725_4e-3, 1.204_382_930_687_821_4e-3],
        ),
    ] {
        let pose = Pose::new(
            Vec3::from(p),
            nalgebra::Quaternion::new(
                (1.0 - q[0] * q[0] - q[1] * q[1] as Real).sqrt(),
                q[0],
                q[1],
                0.0,
            ),
        )
        .unwrap();
        let f0 = net_force(&mut reference, &pose, delta, 0.0);
        let f = net_force(&mut budget, &pose, delta, 0.025);
        assert!(f0.norm() > 0.0);
        assert!((f - f0).norm() <= 1e-6 * f0.norm(), "{f:?} against {f0:?}");
    }
}

/// Facing coarse pieces with no region whose tool piece lies past a corner of the obstacle
/// piece's prism (no single wall separates them) may still have surfaces over each other, within
/// their deviations and the lean of the obstacle surface's own prisms, as pieces that do not face
/// each other may: the repository's fork on Spot at 8.5 cm, `δ` = 3 % of the fork's diagonal
/// (5.6 mm), four first touches of `cargo xtask bench collision --scene
/// basemesh_fork.stl,spot.stl --delta-mm 5.625`. A flat piece of the fork lay 0.8 mm past the
/// corner of a cow piece whose deviation is 0.7 mm and whose triangles lean by up to 16°; the
/// pair was dropped, and LOD at 2.5 % wrote a hundredth of the reference's weight (an error of
/// 0.99 at each). Now the pair is a band at the corner, the budget takes it, and the force is
/// the reference's.
#[test]
fn facing_pieces_past_a_corner_of_the_prism_are_a_band() {
    let tool = asset_tool("basemesh_fork.stl", 1.0);
    let delta = 5.625e-3;
    let (x, y, z) = (
        5.419_917_557_906_644e-3,
        1.144_981_229_506_119_4e-2,
        5.911_916_441_753_379e-2,
    );
    let (x2, y2, z2) = (
        5.726_915_341_271_644e-3,
        1.084_146_850_235_416e-2,
        5.912_748_876_203_987e-2,
    );
    let poses = [
        (
            [x, y, z],
            [2.190_764_418_061_726e-3, 1.204_382_930_687_820_8e-3],
        ),
        (
            [x, y, z],
            [-2.190_764_418_061_725_4e-3, 1.204_382_930_687_821_4e-3],
        ),
        (
            [x2, y2, z2],
            [2.151_852_825_994_864e-3, 1.272_602_213_747_655_5e-3],
        ),
        (
            [x2, y2, z2],
            [-2.151_852_825_994_864e-3, 1.272_602_213_747_656e-3],
        ),
    ];
    let errors = errors_at_bench_poses(&tool, asset("spot_keenan_5856.stl", 0.05), delta, &poses);
    assert!(errors.iter().all(|&e| e <= 0.05), "{errors:?}");
}

/// Where the coarse pieces' spread reaches within `δ` and the surfaces do not, the regions the
/// budget took out push nothing once refined, and the regions left must be held against that
/// force, not the one the budget was taken from (`refine::refine_regions`). The Newell teaspoon
/// (an open sheet, 1,344 triangles) lowered onto a wavy slab (`testmesh::wavy_slab`, waves of
/// 3 to 8 cm and 4 mm), `δ` = 2 mm: at these three poses the all-pairs reference pushes
/// nothing; LOD at 2.5 % pushed up to a thousandth of the reference's force a millimetre
/// further down (an error of 1), with the regions left beside those refined to nothing. Over
/// 25 places on the slab, lowered 0.1 mm at a time down to the first pose where the reference
/// pushes, 35 poses pushed where the surfaces do not; now one does, at 10⁻²² m³.
#[test]
fn a_first_touch_holds_the_regions_left_against_the_force_left() {
    let tool = asset_tool("newell_teaspoon.stl", 1.0);
    let waves = [(0.08, 0.3, 1.1), (0.05, 2.0, 0.4), (0.031, 4.1, 5.0)];
    let slab = super::testmesh::wavy_slab(0.1, 60, 0.004, &waves, 0.01);
    let obstacles = vec![(slab, Pose::identity())];
    let mut reference = LodBackend::new(&tool, &obstacles)
        .unwrap()
        .with_max_contacts(None);
    let mut budget = LodBackend::new(&tool, &obstacles).unwrap();
    let delta = 0.002;
    for p in [[0.0, 0.0, 0.0221], [0.0, 0.0, 0.022], [0.0, 0.01, 0.0212]] {
        let at = |z: Real| Pose::new(Vec3::new(p[0], p[1], z), nalgebra::Quaternion::identity());
        let pose = at(p[2]).unwrap();
        let below = at(p[2] - 1e-3).unwrap();
        let f0 = net_force(&mut reference, &pose, delta, 0.0);
        let f = net_force(&mut budget, &pose, delta, 0.025);
        let in_contact = net_force(&mut reference, &below, delta, 0.0);
        assert_eq!(f0.norm(), 0.0);
        assert!(in_contact.norm() > 0.0);
        assert!(
            f.norm() <= 1e-9 * in_contact.norm(),
            "{f:?} where the surfaces push nothing"
        );
    }
}

/// Where the obstacle piece's triangles face many ways, their own prisms lean from the piece's
/// by up to `δ tan φ_b` at the penalty's reach (the lean the stopping rule counts against `ε`),
/// and reach a tool piece that lies beside the piece's prism: a pair whose pieces do not face
/// each other is descended where it lies beside within that lean and the two deviations, not
/// only within the deviations (`refine.rs`). The Newell teaspoon on Spot (1/20, `δ` = 1 % of
/// the spoon's diagonal: `cargo xtask bench collision --scene newell_teaspoon.stl,spot.stl
/// --scale 1`, Spot written at 1/20 as `spot.stl`; poses 42, 58 and 170 of its path): at
/// these three poses a flat piece of the spoon stood edge-on 0.3–1.7 mm beside a piece of the
/// cow of normal coherence 0.80, and was dropped while 31 of their triangle pairs pushed 7 % of
/// the force, sideways. LOD at 2.5 % was off the all-pairs force by 0.102, 0.102 and 0.076;
/// now by 0.038, 0.036 and 0.025 (probe 39).
#[test]
fn an_edge_on_piece_beside_a_curved_piece_is_reached_by_its_surfaces_lean() {
    let tool = asset_tool("newell_teaspoon.stl", 1.0);
    let obstacle = asset("spot_keenan_5856.stl", 0.05);
    let delta = 2.062_386_224_527_777_8e-3;
    let poses = [
        (
            [
                3.995_185_137_642_515_5e-3,
                1.806_985_293_679_248_1e-3,
                4.202_611_914_026_921_4e-2,
            ],
            [6.217_240_702_824_253e-4, 2.421_455_380_470_384e-3],
        ),
        (
            [
                3.995_185_137_642_515_5e-3,
                1.806_985_293_679_246_8e-3,
                4.202_611_914_026_921_4e-2,
            ],
            [-6.217_240_702_824_245e-4, 2.421_455_380_470_384_2e-3],
        ),
        (
            [
                -3.337_011_009_215_516_8e-3,
                4.146_926_159_759_777e-3,
                4.289_222_160_323_219e-2,
            ],
            [1.469_461_600_040_899_4e-3, -2.022_540_379_122_937_7e-3],
        ),
    ];
    let errors = errors_at_bench_poses(&tool, obstacle, delta, &poses);
    assert!(errors.iter().all(|&e| e <= 0.05), "{errors:?}");
}

/// The budgeted rule's relative error at 2.5 % against the all-pairs force, `tool` against
/// `obstacle` with `δ` = `delta_m`, at poses of the collision bench's path: positions `p` and
/// orientations `(w, qᵢ, qⱼ, 0)`, `w` the path's (a tilt of 0.29°).
fn errors_at_bench_poses(
    tool: &TriMesh,
    obstacle: TriMesh,
    delta_m: Real,
    poses: &[([Real; 3], [Real; 2])],
) -> Vec<Real> {
    moment_errors_at_bench_poses(tool, obstacle, delta_m, poses, net_force)
}

/// [`errors_at_bench_poses`] in the moment `measure` gives of a query's contacts (its
/// arguments: the back-end, the pose, `δ` and the threshold).
fn moment_errors_at_bench_poses(
    tool: &TriMesh,
    obstacle: TriMesh,
    delta_m: Real,
    poses: &[([Real; 3], [Real; 2])],
    measure: fn(&mut LodBackend, &Pose, Real, Real) -> Vec3,
) -> Vec<Real> {
    let (mut reference, mut budget) = all_pairs_and_budgeted(tool, obstacle);
    let w = 9.999_968_750_016_276e-1;
    poses
        .iter()
        .map(|(p, q)| {
            let pose = Pose::new(
                Vec3::from(*p),
                nalgebra::Quaternion::new(w, q[0], q[1], 0.0),
            )
            .unwrap();
            let f0 = measure(&mut reference, &pose, delta_m, 0.0);
            let f = measure(&mut budget, &pose, delta_m, 0.025);
            assert!(f0.norm() > 0.0);
            (f - f0).norm() / f0.norm()
        })
        .collect()
}

/// A plate 4 mm thick whose faces are gridded (a CAD export's), 12 × 12 or 16 × 16 quads a
/// face: the pieces of nodes on one face that cover their triangles (rectangles of the grid,
/// cover 1) are bounded through their children, not through the face beneath: their
/// deviations stay below half the plate's thickness (the node holding a whole face at 0), and
/// no node's cover is short of 1 by roundoff alone, in metres, millimetres or any other units.
/// With the candidates chosen by distance alone, the children lost to the equally near pieces
/// of the face beneath and of the sides: flat nodes of 6 to 224 triangles had deviations of
/// 4–7.4 mm (the thickness, or a cell of the grid), and the whole face one of 8.3 mm under
/// another tree; and covers came out at 1 − 3 · 10⁻¹⁶. The deviations are checked in metres
/// only: the trees built in other units differ (ties of the median cut broken by rounding),
/// and in millimetres one flat node of 112 triangles is still bounded at 3.9 mm (probe 36).
#[test]
fn a_gridded_plates_flat_nodes_are_bounded_through_their_children() {
    let thickness = 0.004;
    for k in [12, 16] {
        let plate = grid_box(Vec3::new(0.05, 0.05, 0.5 * thickness), k);
        let face = k * k * 2;
        for scale in [1.0, 1e-3, 10.0, 0.37] {
            let vertices = plate.vertices().iter().map(|v| v * scale).collect();
            let h = Hierarchy::build(&mesh(vertices, plate.triangles().to_vec()));
            let mut whole_faces = 0;
            for (i, (node, moments)) in h.nodes.iter().zip(&h.moments).enumerate() {
                let cover = moments.cover;
                assert!(
                    cover == 1.0 || cover < 1.0 - 1e-6,
                    "k {k}, scale {scale}, node {i}: cover {cover}"
                );
                let mut below = Vec::new();
                triangles_below(&h, i, &mut below);
                let normal = |t: u32| triangle_normal(&plate.triangle(t as usize)).unwrap();
                if scale != 1.0
                    || cover < 1.0
                    || below.iter().any(|&t| normal(t) != normal(below[0]))
                {
                    continue;
                }
                assert!(
                    node.deviation < 0.5 * thickness * scale,
                    "k {k}, scale {scale}, node {i} of {} triangles: deviation {:e}",
                    below.len(),
                    node.deviation
                );
                if below.len() == face {
                    whole_faces += 1;
                    assert_eq!(node.deviation, 0.0, "k {k}, scale {scale}, node {i}");
                }
            }
            assert!(scale != 1.0 || whole_faces >= 1, "k {k}");
        }
    }
}

/// The all-pairs wrench is the scene's, not its frame's: moved and turned as a whole (twelve
/// rigid motions), three scenes whose tool faces lie on walls of the obstacle's prisms give
/// the same wrench, turned, to roundoff. A box resting flush with its base's sides, a box on
/// a box's corner, and a peg whose layers' rings lie on its hole's rows. Without the rule for
/// polygons on a wall (`slab.rs`), they changed by up to 3 %, 6 % and 19 %.
#[test]
fn the_all_pairs_wrench_holds_under_a_rigid_motion_of_the_scene() {
    let delta = 0.0005;
    let at = |x, y, z| Pose {
        position: Vec3::new(x, y, z),
        orientation: UnitQuaternion::identity(),
    };
    let small = super::testmesh::cuboid(Vec3::new(0.005, 0.005, 0.005));
    let scenes = [
        (
            small.clone(),
            super::testmesh::cuboid(Vec3::new(0.01, 0.01, 0.005)),
            at(0.005, 0.005, 0.0099),
        ),
        (small.clone(), small, at(0.0, 0.0, 0.0099)),
        (
            super::testmesh::layered_cylinder(0.004, 0.006, 40, 6),
            tube(0.00405, 0.010, 40, 10),
            at(3e-5, 0.0, 0.002),
        ),
    ];
    for (tool, obstacle, local) in scenes {
        // The wrench in the scene's own frame, the scene moved by `(rot, shift)`.
        let wrench = |rot: UnitQuaternion<Real>, shift: Vec3| {
            let obstacles = [(
                obstacle.clone(),
                Pose {
                    position: shift,
                    orientation: rot,
                },
            )];
            let mut backend = LodBackend::new(&tool, &obstacles)
                .unwrap()
                .with_max_contacts(None);
            let tool_pose = Pose {
                position: rot * local.position + shift,
                orientation: rot * local.orientation,
            };
            let mut out = ContactSet::new();
            let params = QueryParams::new(delta, 0.0).unwrap();
            backend.query(&tool_pose, &params, &mut out).unwrap();
            let radius = backend.tool_bounding_radius_m();
            let w = integrated_penalty(&out, delta, &tool_pose.position, radius);
            let (f, t) = (Vec3::new(w[0], w[1], w[2]), Vec3::new(w[3], w[4], w[5]));
            [rot.inverse() * f, rot.inverse() * t]
        };
        let w0 = wrench(UnitQuaternion::identity(), Vec3::zeros());
        let size = (w0[0].norm_squared() + w0[1].norm_squared()).sqrt();
        assert!(size > 0.0);
        for k in 1..=12 {
            let s = k as Real;
            let axis = Vec3::new((s * 1.3).sin(), (s * 0.7).cos(), (s * 2.1).sin());
            let rot = UnitQuaternion::from_scaled_axis(axis * (0.3 + s * 0.2));
            let shift = Vec3::new((s * 0.9).sin(), (s * 1.7).cos(), (s * 0.4).sin()) * 0.05;
            let w = wrench(rot, shift);
            let change = ((w[0] - w0[0]).norm_squared() + (w[1] - w0[1]).norm_squared()).sqrt();
            assert!(change <= 1e-9 * size, "motion {k}: {w:?} against {w0:?}");
        }
    }
}

/// A bowl: hemispherical shells of radii 30 mm (outside) and 26 mm (inside) about the origin,
/// open at z = 0 with a flat rim between them, revolved in 64 segments, 24 rows a quarter turn
/// (each quad of the profile split in two, the poles' triangles fans).
fn bowl() -> TriMesh {
    let quarter = |r: Real, i: usize| {
        let a = std::f64::consts::FRAC_PI_2 * i as Real / 24.0;
        (r * a.sin(), -r * a.cos())
    };
    let mut profile: Vec<(Real, Real)> = (0..=24).map(|i| quarter(0.03, i)).collect();
    profile.extend((0..=24).rev().map(|i| quarter(0.026, i)));
    let segments = 64;
    let mut vertices = Vec::new();
    let mut ids = Vec::new();
    for &(r, z) in &profile {
        if r == 0.0 {
            ids.push(vec![vertices.len() as u32; segments]);
            vertices.push(Vec3::new(0.0, 0.0, z));
        } else {
            ids.push((0..segments).map(|j| (vertices.len() + j) as u32).collect());
            for j in 0..segments {
                let a = std::f64::consts::TAU * j as Real / segments as Real;
                vertices.push(Vec3::new(r * a.cos(), r * a.sin(), z));
            }
        }
    }
    let mut triangles = Vec::new();
    for k in 0..profile.len() - 1 {
        for j in 0..segments {
            let j1 = (j + 1) % segments;
            let (a, b) = (ids[k][j], ids[k][j1]);
            let (c, d) = (ids[k + 1][j1], ids[k + 1][j]);
            for t in [[a, b, c], [a, c, d]] {
                if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                    triangles.push(t);
                }
            }
        }
    }
    mesh(vertices, triangles)
}

/// Spot (the repository's cow at 1/20, 8.5 cm) lowered onto the bowl, which it cannot enter,
/// resting its feet on the flat rim, `δ` = 1.29 mm (1 % of its diagonal): three of the bench's
/// poses (`cargo xtask bench collision --scene spot.stl,bowl.stl`, 20 to 22 of its path). The
/// rim's coarse pieces are convex hulls of three segments of the ring: they overhang the bowl's
/// opening by the chord's sagitta (their deviation, 0.25 mm; their cover 0.963), and a foot
/// over the opening lies mostly in that overhang. Counted at the pieces' average cover, the
/// feet's regions weighed up to five times the rim under them (errors of 0.42–0.49 at 2.5 %);
/// bounded by the bands the build measured along the pieces' edges (`overhang.rs`), they are
/// refined where they reach them.
#[test]
fn feet_over_a_bowls_opening_weigh_only_the_rim_under_them() {
    let tool = asset_tool("spot_keenan_5856.stl", 0.05);
    let delta = 1.294_045_034_842_328_9e-3;
    let poses = [
        (
            [
                1.521_241_174_565_241e-3,
                7.997_638_145_056_012e-4,
                3.920_535_141_514_039_4e-2,
            ],
            [2.022_540_379_122_937_2e-3, 1.469_461_600_040_9e-3],
        ),
        (
            [
                1.586_258_659_198_949_9e-3,
                6.436_318_274_023_592e-4,
                3.916_225_726_894_414_4e-2,
            ],
            [1.975_385_473_244_524_4e-3, 1.532_266_038_020_820_7e-3],
        ),
        (
            [
                1.649_710_698_047_358_6e-3,
                4.849_597_195_237_711e-4,
                3.910_862_176_068_414e-2,
            ],
            [1.926_281_100_395_197e-3, 1.593_558_314_413_936_2e-3],
        ),
    ];
    let errors = errors_at_bench_poses(&tool, bowl(), delta, &poses);
    assert!(errors.iter().all(|&e| e <= 0.05), "{errors:?}");
}

/// `Σ a g² n` over a query's contacts (m⁴): the moment of the penalty the clustering's
/// representatives push with (`haptic-cluster`'s stiffness shares), which the compaction keeps.
fn clustering_moment(backend: &mut LodBackend, pose: &Pose, delta: Real, threshold: Real) -> Vec3 {
    let mut out = ContactSet::new();
    let params = QueryParams::new(delta, threshold).unwrap();
    backend.query(pose, &params, &mut out).unwrap();
    out.as_slice().iter().fold(Vec3::zeros(), |sum, c| {
        let g = c.gap_weight_m(delta);
        sum + c.n * (c.area_m2 * g * g)
    })
}

/// Where deep contacts push against each other, the clustering's moment `Σ a g² n` cancels far
/// more than the penalty `Σ a g n`: the Newell teaspoon's bowl 7–10 mm into a wavy terrain
/// (20 cm square, 60 × 60 quads, three waves of 4 mm; `δ` = 5 % of the spoon's diagonal), three
/// poses of `cargo xtask bench collision --scene newell_teaspoon.stl,terrain.stl --delta-mm
/// 10.31`, where `|Σ a g² n|` is a thirtieth of `Σ a g²` and `|Σ a g n|` a sixth of `Σ a g`.
/// Held to the threshold in the penalty's moment alone, the budgeted rule at 2.5 % was off by
/// 0.23–0.30 in the clustering's; held in both, by 0.06–0.09.
#[test]
fn the_clustering_moment_is_held_where_deep_contacts_cancel() {
    let tool = asset_tool("newell_teaspoon.stl", 1.0);
    let waves = [
        (0.08, 4.002_148_315_014_479, 1.695_119_915_993_414_5),
        (0.05, 0.257_444_243_579_269_54, 0.103_846_196_715_273_31),
        (0.031, 5.109_927_617_709_579, 5.735_012_432_197_602),
    ];
    let terrain = super::testmesh::wavy_slab(0.1, 60, 0.004, &waves, 0.01);
    let delta = 10.311_931_122_638_889e-3;
    let poses = [
        (
            [
                2.025_855_694_432_110_8e-2,
                -1.917_558_216_385_775_4e-2,
                7.020_264_101_630_294_5e-3,
            ],
            [4.684_527_984_922_909_6e-4, 2.455_715_568_782_805_4e-3],
        ),
        (
            [
                2.025_855_694_432_110_8e-2,
                -1.917_558_216_385_775e-2,
                7.020_264_101_630_294_5e-3,
            ],
            [-4.684_527_984_922_912e-4, 2.455_715_568_782_805_4e-3],
        ),
        (
            [
                1.940_459_536_814_297_5e-2,
                -1.589_095_897_717_014_7e-2,
                1.047_771_549_653_923_9e-2,
            ],
            [8.468_439_184_835_038e-4, 2.352_199_472_175_993_3e-3],
        ),
    ];
    let errors = moment_errors_at_bench_poses(&tool, terrain, delta, &poses, clustering_moment);
    assert!(errors.iter().all(|&e| e <= 0.12), "{errors:?}");
}

/// `mesh` with every vertex multiplied by `scale` (the same triangles).
fn scaled(mesh: &TriMesh, scale: Real) -> TriMesh {
    super::testmesh::mesh(
        mesh.vertices().iter().map(|v| v * scale).collect(),
        mesh.triangles().to_vec(),
    )
}

/// A scene given in other units (a user's millimetres, inches, kilometres) is the same query:
/// nothing in the build, the walk, the regions or the compaction may depend on the size of a
/// metre. Scaled by a power of two, every length in the computation scales exactly, so the walk
/// must visit the same node pairs and write the same contacts, scaled (to roundoff: the closest
/// approach's contact keeps its fixed, negligible area). Scaled by a thousandth or by 25.4 mm,
/// roundoff may break a tie differently in the build, but the all-pairs penalty does not
/// depend on the hierarchy: at threshold 0 it must agree to roundoff, and so must the smallest
/// separation.
#[test]
fn a_scene_in_other_units_gives_the_same_query() {
    let at = |p: Vec3, axis: Vec3| Pose {
        position: p,
        orientation: UnitQuaternion::from_scaled_axis(axis),
    };
    let scenes = [
        // A box resting tilted on a box, a layered peg in a tube, a bumpy ball on a bowl's rim.
        (
            cuboid(Vec3::new(0.005, 0.005, 0.005)),
            grid_box(Vec3::new(0.01, 0.01, 0.005), 4),
            at(Vec3::new(0.003, 0.002, 0.0104), Vec3::new(0.05, -0.03, 0.2)),
            0.0005,
        ),
        (
            super::testmesh::layered_cylinder(0.004, 0.006, 40, 6),
            tube(0.00405, 0.010, 40, 10),
            at(Vec3::new(3e-5, 1e-5, 0.002), Vec3::new(0.004, 0.0, 0.0)),
            0.0005,
        ),
        (
            bumpy_sphere(2, 0.008, 0.05, 3),
            bowl(),
            at(Vec3::new(0.028, 0.0, 0.0085), Vec3::new(0.3, 0.1, 0.0)),
            0.001,
        ),
    ];
    let query = |tool: &TriMesh, obstacle: &TriMesh, pose: &Pose, params: &QueryParams, cap| {
        let mut backend = LodBackend::new(tool, &[(obstacle.clone(), Pose::identity())])
            .unwrap()
            .with_max_contacts(cap);
        let mut out = ContactSet::new();
        let stats = backend.query(pose, params, &mut out).unwrap();
        (out, stats)
    };
    let scaled_pose = |pose: &Pose, s: Real| Pose {
        position: pose.position * s,
        orientation: pose.orientation,
    };
    for (k, (tool, obstacle, pose, delta)) in scenes.iter().enumerate() {
        for threshold in [0.0, 0.004, 0.025] {
            let params = QueryParams::new(*delta, threshold).unwrap();
            let (base, base_stats) = query(tool, obstacle, pose, &params, Some(256));
            assert!(!base.is_empty(), "scene {k} has no contact");
            for s in [Real::powi(2.0, -10), 0.125, Real::powi(2.0, 7)] {
                let params = QueryParams::new(delta * s, threshold).unwrap();
                let (got, stats) = query(
                    &scaled(tool, s),
                    &scaled(obstacle, s),
                    &scaled_pose(pose, s),
                    &params,
                    Some(256),
                );
                let what = format!("scene {k}, threshold {threshold}, scale {s}");
                assert_eq!(
                    stats.node_pairs_tested, base_stats.node_pairs_tested,
                    "{what}"
                );
                assert_eq!(stats.raw_contacts, base_stats.raw_contacts, "{what}");
                assert_eq!(got.len(), base.len(), "{what}");
                let near = |a: Real, b: Real, size: Real| (a - b).abs() <= 1e-12 * size;
                for (c, c0) in got.iter().zip(base.iter()) {
                    assert!(
                        near(c.depth_m / s, c0.depth_m, *delta),
                        "{what}: {c:?} / {c0:?}"
                    );
                    assert!((c.n - c0.n).norm() <= 1e-12, "{what}: {c:?} / {c0:?}");
                    assert!((c.p_a / s - c0.p_a).norm() <= 1e-12 * 0.05, "{what}");
                    assert!((c.r_a / s - c0.r_a).norm() <= 1e-12 * 0.05, "{what}");
                    if c0.stiffness_share > 0.0 {
                        assert!(near(c.area_m2 / (s * s), c0.area_m2, c0.area_m2), "{what}");
                    }
                }
            }
        }
        // Other units, and the all-pairs penalty at threshold 0.
        let params = QueryParams::new(*delta, 0.0).unwrap();
        let (base, _) = query(tool, obstacle, pose, &params, None);
        let w0 = integrated_penalty(&base, *delta, &pose.position, 0.05);
        let size = w0.iter().map(|x| x * x).sum::<Real>().sqrt();
        let nearest = |set: &ContactSet| set.iter().map(|c| -c.depth_m).fold(Real::MAX, Real::min);
        for s in [1e-3, 25.4e-3, 1e3] {
            let params = QueryParams::new(delta * s, 0.0).unwrap();
            let p = scaled_pose(pose, s);
            let (got, _) = query(&scaled(tool, s), &scaled(obstacle, s), &p, &params, None);
            let w = integrated_penalty(&got, delta * s, &p.position, 0.05 * s);
            // Force `Σ a g n` scales as `s³`; torque over a lever `s` as well.
            let change = w
                .iter()
                .zip(&w0)
                .map(|(x, x0)| (x / (s * s * s) - x0).powi(2))
                .sum::<Real>()
                .sqrt();
            assert!(
                change <= 1e-9 * size,
                "scene {k}, scale {s}: {w:?} / {w0:?}"
            );
            assert!(
                (nearest(&got) / s - nearest(&base)).abs() <= 1e-9 * delta,
                "scene {k}, scale {s}"
            );
        }
    }
}
