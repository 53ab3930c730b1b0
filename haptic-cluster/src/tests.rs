//! Unit and property tests of the clustering.

use super::*;
use proptest::prelude::*;

const DELTA_M: Real = 1e-3;

/// A contact at `p` with normal `n` (normalised) and depth `d`.
fn contact(p: Vec3, n: Vec3, d: Real) -> Contact {
    Contact::new(p, p, p - d * n.normalize(), n.normalize(), d).unwrap()
}

/// A clusterer of at most `k` clusters, the other parameters the defaults.
fn clusterer(k: usize) -> Clusterer {
    Clusterer::new(ClusterParams {
        max_clusters: k,
        ..Default::default()
    })
    .unwrap()
}

/// Contacts around a few patch centres (m), depths in [−δ, 2 mm].
fn arb_contacts() -> impl Strategy<Value = Vec<Contact>> {
    (
        prop::collection::vec(prop::array::uniform3(-0.05..0.05f64), 1..5),
        prop::collection::vec(
            (
                0usize..5,
                prop::array::uniform3(-0.005..0.005f64),
                prop::array::uniform3(-1.0..1.0f64),
                -DELTA_M..2e-3,
            ),
            1..120,
        ),
    )
        .prop_map(|(centres, raw)| {
            raw.into_iter()
                .map(|(c, off, n, d)| {
                    let p = Vec3::from(centres[c % centres.len()]) + Vec3::from(off);
                    let n = Vec3::from(n) + Vec3::new(0.0, 0.0, 1e-3);
                    contact(p, n, d)
                })
                .collect()
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn lloyd_invariants(contacts in arb_contacts(), k in 1usize..9, warm_frames in 0usize..3) {
        let mut clusterer = clusterer(k);
        clusterer.record_costs(true);
        let mut reps = ContactSet::new();
        // Optionally warm up on shifted copies of the same set first.
        for f in 0..warm_frames {
            let shifted: Vec<Contact> = contacts.iter().map(|c| {
                let mut c = *c;
                c.p_a += Vec3::new(1e-3 * (f + 1) as Real, 0.0, 0.0);
                c
            }).collect();
            clusterer.cluster(&shifted, DELTA_M, &mut reps).unwrap();
        }
        let stats = clusterer.cluster(&contacts, DELTA_M, &mut reps).unwrap();
        let n = contacts.len();
        // At most K clusters (and at most N), each non-empty, every contact assigned.
        prop_assert!(reps.len() <= k.min(n));
        prop_assert!(!reps.is_empty());
        prop_assert_eq!(stats.clusters, reps.len());
        let a = clusterer.assignments();
        prop_assert_eq!(a.len(), n);
        let mut count = vec![0usize; reps.len()];
        for &ai in a {
            prop_assert!((ai as usize) < reps.len());
            count[ai as usize] += 1;
        }
        prop_assert!(count.iter().all(|&c| c > 0), "empty cluster: {:?}", count);
        // Representatives inside the contacts' convex hull: for every direction u,
        // u·rep <= max_i u·p_i (checked on the axes and 64 fixed directions).
        let mut dirs = vec![Vec3::x(), Vec3::y(), Vec3::z(), -Vec3::x(), -Vec3::y(), -Vec3::z()];
        for i in 0..64 {
            let t = i as Real * 0.7;
            dirs.push(Vec3::new(t.cos() * (1.3 * t).sin(), t.sin() * (1.3 * t).sin(), (1.3 * t).cos()));
        }
        for r in reps.iter() {
            for u in &dirs {
                let hi = contacts.iter().map(|c| u.dot(&c.p_a)).fold(Real::NEG_INFINITY, Real::max);
                prop_assert!(u.dot(&r.p_a) <= hi + 1e-12, "representative outside the hull");
            }
            prop_assert!((r.n.norm() - 1.0).abs() < 1e-9);
            prop_assert!(r.depth_m >= -DELTA_M - 1e-15);
            prop_assert!(r.validate().is_ok());
        }
        // The cost (eq. 28) never increases from one iteration to the next.
        // Rounding allowance: 1e-12 of the cost of putting everything in one point's cluster.
        let scale: Real = contacts.iter().map(|c| weight(c.depth_m, DELTA_M) * (c.p_a - contacts[0].p_a).norm_squared()).sum();
        prop_assert!(!clusterer.cost_history().is_empty());
        prop_assert!((clusterer.cost_history().last().unwrap() - stats.cost).abs() <= 1e-12 * scale + 1e-30);
        for w in clusterer.cost_history().windows(2) {
            prop_assert!(w[1] <= w[0] + 1e-12 * scale + 1e-30, "cost rose: {:?}", clusterer.cost_history());
        }
    }
}

#[test]
fn fewer_contacts_than_k_give_one_cluster_each() {
    let contacts: Vec<Contact> = (0..3)
        .map(|i| contact(Vec3::new(0.01 * i as Real, 0.0, 0.0), Vec3::z(), 1e-4))
        .collect();
    let mut c = Clusterer::new(ClusterParams::default()).unwrap();
    let mut reps = ContactSet::new();
    c.cluster(&contacts, DELTA_M, &mut reps).unwrap();
    assert_eq!(reps.len(), 3);
    for k in &contacts {
        let r = reps
            .iter()
            .find(|r| (r.p_a - k.p_a).norm() < 1e-15)
            .unwrap();
        assert!((r.depth_m - k.depth_m).abs() < 1e-15);
    }
}

#[test]
fn coincident_contacts_give_one_cluster() {
    let contacts = vec![contact(Vec3::new(0.1, 0.2, 0.3), Vec3::z(), 5e-4); 12];
    let mut c = Clusterer::new(ClusterParams::default()).unwrap();
    let mut reps = ContactSet::new();
    let stats = c.cluster(&contacts, DELTA_M, &mut reps).unwrap();
    assert_eq!(reps.len(), 1);
    assert!(stats.converged);
    assert!((reps.as_slice()[0].depth_m - 5e-4).abs() < 1e-15);
}

#[test]
fn two_patches_are_found_and_representatives_average_them() {
    // Two patches 10 cm apart, depth 1 mm and 0 (weights 2δ and δ); normals tilted either way.
    let mut contacts = Vec::new();
    for i in 0..10 {
        let x = 1e-3 * i as Real;
        contacts.push(contact(
            Vec3::new(x, 0.0, 0.0),
            Vec3::new(0.1, 0.0, 1.0),
            1e-3,
        ));
        contacts.push(contact(
            Vec3::new(x + 0.1, 0.0, 0.0),
            Vec3::new(-0.1, 0.0, 1.0),
            0.0,
        ));
    }
    let mut c = clusterer(2);
    let mut reps = ContactSet::new();
    c.cluster(&contacts, DELTA_M, &mut reps).unwrap();
    // Each representative's weight is its patch's: 10 contacts of 2δ, and 10 of δ.
    let weights = c.representative_weights();
    assert_eq!(weights.len(), 2);
    let by_x: Vec<(Real, Real)> = reps
        .iter()
        .map(|r| r.p_a.x)
        .zip(weights.iter().copied())
        .collect();
    for (x, w) in by_x {
        let expected = if x < 0.05 {
            20.0 * DELTA_M
        } else {
            10.0 * DELTA_M
        };
        approx::assert_relative_eq!(w, expected, max_relative = 1e-12);
    }
    let mut reps: Vec<Contact> = reps.iter().copied().collect();
    reps.sort_by(|a, b| a.p_a.x.total_cmp(&b.p_a.x));
    approx::assert_relative_eq!(reps[0].p_a.x, 4.5e-3, epsilon = 1e-12);
    approx::assert_relative_eq!(reps[1].p_a.x, 0.1045, epsilon = 1e-12);
    approx::assert_relative_eq!(reps[0].depth_m, 1e-3, epsilon = 1e-15);
    approx::assert_relative_eq!(
        reps[0].n,
        Vec3::new(0.1, 0.0, 1.0).normalize(),
        epsilon = 1e-12
    );
    // p_b = p_a − d n.
    approx::assert_relative_eq!(reps[0].p_b, reps[0].p_a - 1e-3 * reps[0].n, epsilon = 1e-15);
}

#[test]
fn bad_input_gives_typed_errors() {
    assert_eq!(
        Clusterer::new(ClusterParams {
            max_clusters: 0,
            ..Default::default()
        })
        .unwrap_err(),
        ClusterError::ZeroClusters
    );
    assert_eq!(
        Clusterer::new(ClusterParams {
            max_iterations: 0,
            ..Default::default()
        })
        .unwrap_err(),
        ClusterError::ZeroIterations
    );
    // Sizes that would reserve terabytes are refused before anything is reserved.
    assert_eq!(
        Clusterer::new(ClusterParams {
            max_clusters: usize::MAX,
            ..Default::default()
        })
        .unwrap_err(),
        ClusterError::TooManyClusters { asked: usize::MAX }
    );
    assert_eq!(
        Clusterer::new(ClusterParams {
            max_iterations: 1 << 40,
            ..Default::default()
        })
        .unwrap_err(),
        ClusterError::TooManyIterations { asked: 1 << 40 }
    );
    let mut c = Clusterer::new(ClusterParams::default()).unwrap();
    let mut reps = ContactSet::new();
    let good = contact(Vec3::zeros(), Vec3::z(), 0.0);
    let mut nan = good;
    nan.p_a.y = Real::NAN;
    assert!(matches!(
        c.cluster(&[good, nan], DELTA_M, &mut reps),
        Err(ClusterError::NonFiniteContact { index: 1, .. })
    ));
    let mut zero_normal = good;
    zero_normal.n = Vec3::zeros();
    assert!(matches!(
        c.cluster(&[zero_normal], DELTA_M, &mut reps),
        Err(ClusterError::BadNormal { index: 0, norm }) if norm == 0.0
    ));
    let mut inf_depth = good;
    inf_depth.depth_m = Real::INFINITY;
    assert!(matches!(
        c.cluster(&[inf_depth], DELTA_M, &mut reps),
        Err(ClusterError::NonFiniteContact {
            index: 0,
            what: "contact depth"
        })
    ));
    for share in [Real::NAN, -0.5] {
        assert!(matches!(
            c.cluster(
                &[good, good.with_stiffness_share(share)],
                DELTA_M,
                &mut reps
            ),
            Err(ClusterError::NonFiniteContact {
                index: 1,
                what: "contact stiffness share"
            })
        ));
    }
    for delta in [0.0, -1e-3, Real::NAN] {
        assert!(matches!(
            c.cluster(&[good], delta, &mut reps),
            Err(ClusterError::BadDelta { .. })
        ));
    }
    assert!(reps.is_empty());
}

#[test]
fn empty_input_gives_no_representative() {
    let mut c = Clusterer::new(ClusterParams::default()).unwrap();
    let mut reps = ContactSet::new();
    reps.push(contact(Vec3::zeros(), Vec3::z(), 0.0));
    let stats = c.cluster(&[], DELTA_M, &mut reps).unwrap();
    assert!(reps.is_empty());
    assert_eq!(stats.clusters, 0);
}

/// A slowly drifting contact set: `n` contacts spread evenly on a ring of radius 1 cm (a set
/// with many near-equivalent clusterings), turning by 0.3 mrad per frame, with depths that vary
/// slowly around it so that the deepest contact wanders.
fn drifting_frame(frame: usize, n: usize) -> Vec<Contact> {
    let t = frame as Real;
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as Real / n as Real + 3e-4 * t;
            let p = Vec3::new(0.01 * a.cos(), 0.01 * a.sin(), 0.0);
            let d = 5e-4 + 2e-4 * (3.0 * a - 0.004 * t).sin();
            contact(p, Vec3::z(), d)
        })
        .collect()
}

/// The largest distance any representative of `now` is from the closest one of `before`.
fn largest_jump(before: &[Contact], now: &[Contact]) -> Real {
    now.iter()
        .map(|r| {
            before
                .iter()
                .map(|b| (r.p_a - b.p_a).norm())
                .fold(Real::INFINITY, Real::min)
        })
        .fold(0.0, Real::max)
}

/// Runs the 1,000-frame drifting sequence and returns the largest representative jump (m).
fn drift_run(warm_start: bool) -> Real {
    let mut c = Clusterer::new(ClusterParams {
        warm_start,
        ..Default::default()
    })
    .unwrap();
    let mut reps = ContactSet::new();
    let mut before: Vec<Contact> = Vec::new();
    let mut jump: Real = 0.0;
    for frame in 0..1000 {
        c.cluster(&drifting_frame(frame, 60), DELTA_M, &mut reps)
            .unwrap();
        let now: Vec<Contact> = reps.iter().copied().collect();
        if frame > 0 {
            jump = jump.max(largest_jump(&before, &now));
        }
        before = now;
    }
    jump
}

#[test]
fn warm_start_moves_representatives_continuously() {
    let warm = drift_run(true);
    let cold = drift_run(false);
    // A contact moves 3 µm per frame, and neighbours are 1.05 mm apart. With warm start a
    // representative jumps only when one contact changes cluster (about half the spacing); cold
    // starts re-seed at the wandering deepest contact and the clusters rotate around the ring.
    println!("largest representative jump over 1000 frames: warm {warm:.3e} m, cold {cold:.3e} m");
    assert!(warm < 1.05e-3, "warm start jumped {warm} m");
    assert!(cold > 5.0 * warm, "cold {cold} m vs warm {warm} m");
}

#[test]
fn same_input_gives_same_output() {
    let run = || {
        let mut c = Clusterer::new(ClusterParams::default()).unwrap();
        let mut reps = ContactSet::new();
        let mut all = Vec::new();
        for frame in 0..50 {
            c.cluster(&drifting_frame(frame * 7, 40), DELTA_M, &mut reps)
                .unwrap();
            all.extend(reps.iter().copied());
        }
        all
    };
    let (a, b) = (run(), run());
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        // Bit-identical.
        assert_eq!(x, y);
    }
    // And the same input in consecutive calls, once warm, is a fixed point.
    let mut c = Clusterer::new(ClusterParams::default()).unwrap();
    let frame = drifting_frame(0, 40);
    let (mut r1, mut r2) = (ContactSet::new(), ContactSet::new());
    c.cluster(&frame, DELTA_M, &mut r1).unwrap();
    c.cluster(&frame, DELTA_M, &mut r1).unwrap();
    c.cluster(&frame, DELTA_M, &mut r2).unwrap();
    assert_eq!(r1.as_slice(), r2.as_slice());
}

#[test]
fn warm_start_from_given_representatives_replays_that_history() {
    // Clustering frame B after frame A, and clustering B in a fresh clusterer told A's
    // representatives, give the same output; a cold start on B need not.
    let (a, b) = (drifting_frame(0, 40), drifting_frame(300, 40));
    let mut chained = Clusterer::new(ClusterParams::default()).unwrap();
    let (mut reps_a, mut reps_b) = (ContactSet::new(), ContactSet::new());
    chained.cluster(&a, DELTA_M, &mut reps_a).unwrap();
    chained.cluster(&b, DELTA_M, &mut reps_b).unwrap();

    let mut told = Clusterer::new(ClusterParams::default()).unwrap();
    told.warm_start_from(reps_a.as_slice());
    let mut reps = ContactSet::new();
    let stats = told.cluster(&b, DELTA_M, &mut reps).unwrap();
    assert!(stats.warm);
    assert_eq!(reps.as_slice(), reps_b.as_slice());

    // An empty history means a cold start.
    told.warm_start_from(&[]);
    assert!(!told.cluster(&b, DELTA_M, &mut reps).unwrap().warm);
}

/// The contacts of a 2 cm square face at tilted depth, one per cell of an `n × n` grid whose
/// columns are split unevenly (a third of them a quarter as wide), each with its cell's area.
fn tilted_face(n: usize, with_areas: bool) -> Vec<Contact> {
    let side = 0.02;
    // Column edges: the first third of the columns four times narrower than the rest.
    let narrow = n / 3;
    let unit = side / (narrow as Real * 0.25 + (n - narrow) as Real);
    let mut edges = vec![0.0];
    for i in 0..n {
        let w = if i < narrow { 0.25 * unit } else { unit };
        edges.push(edges[i] + w);
    }
    let mut out = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let x = 0.5 * (edges[i] + edges[i + 1]);
            let y = (j as Real + 0.5) * side / n as Real;
            let area = (edges[i + 1] - edges[i]) * side / n as Real;
            let c = contact(Vec3::new(x, y, 0.0), -Vec3::z(), 2e-4 + 0.02 * x);
            out.push(if with_areas { c.with_area(area) } else { c });
        }
    }
    out
}

#[test]
fn area_weights_make_the_representative_independent_of_the_tessellation() {
    // One cluster: its representative is the weighted mean. With areas it is the same for a
    // coarse and a finer, uneven grid of the same face (to rounding); without, the narrow
    // columns' extra contacts pull it towards them.
    let one = ClusterParams {
        max_clusters: 1,
        ..Default::default()
    };
    let rep = |contacts: &[Contact]| {
        let mut c = Clusterer::new(one).unwrap();
        let mut reps = ContactSet::new();
        c.cluster(contacts, DELTA_M, &mut reps).unwrap();
        (reps.as_slice()[0], c.representative_weights()[0])
    };
    let (coarse, w_coarse) = rep(&tilted_face(6, true));
    let (fine, w_fine) = rep(&tilted_face(24, true));
    assert!(
        (coarse.p_a - fine.p_a).norm() < 2e-4,
        "{:?} {:?}",
        coarse.p_a,
        fine.p_a
    );
    assert!((coarse.depth_m - fine.depth_m).abs() < 1e-5);
    assert!((coarse.area_m2 - 4e-4).abs() < 1e-12 && (fine.area_m2 - 4e-4).abs() < 1e-12);
    // Weight in m³: area times depth plus δ.
    assert!((w_coarse / w_fine - 1.0).abs() < 0.02);
    let (unweighted, _) = rep(&tilted_face(24, false));
    assert!((unweighted.p_a - fine.p_a).norm() > 2e-3);
    // One contact without an area makes the whole call unweighted.
    let mut mixed = tilted_face(24, true);
    mixed[0].area_m2 = 0.0;
    let (m, _) = rep(&mixed);
    assert!((m.p_a - unweighted.p_a).norm() < 1e-12);
}

/// The penalty the representatives make at their own state (eq. 33 with each one's stiffness
/// share, unit `k_c`): `Σ_k s_k g_k n_k`, pushing along `n` (the sign aside).
fn representatives_penalty(reps: &ContactSet) -> Vec3 {
    reps.iter()
        .map(|r| r.n * (r.stiffness_share * weight(r.depth_m, DELTA_M)))
        .sum()
}

/// `K' Σ_i w_i g_i n_i / W` over the raw contacts: the area-weighted penalty the shares keep.
fn contacts_penalty(contacts: &[Contact], written: usize) -> Vec3 {
    let w = |c: &Contact| weight(c.depth_m, DELTA_M) * c.area_m2.max(0.0);
    let with_areas = contacts.iter().all(|c| c.area_m2 > 0.0);
    let w = |c: &Contact| {
        if with_areas {
            w(c)
        } else {
            weight(c.depth_m, DELTA_M)
        }
    };
    let total: Real = contacts.iter().map(w).sum();
    let sum: Vec3 = contacts
        .iter()
        .map(|c| c.n * (w(c) * weight(c.depth_m, DELTA_M)))
        .sum();
    sum * (written as Real / total)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The stiffness shares make the clustered penalty the contacts' own, whatever the
    /// partition: cold, warm-started from elsewhere, and at any K. The shares add up to at most
    /// K', so the stiffness stays within K k_c.
    #[test]
    fn shares_keep_the_penalty_whatever_the_partition(
        contacts in arb_contacts(),
        areas in prop::collection::vec(1e-7..1e-5f64, 120),
        k in 1usize..9,
        seeds in prop::collection::vec(prop::array::uniform3(-0.06..0.06f64), 1..9),
    ) {
        let contacts: Vec<Contact> = contacts.iter().zip(&areas).map(|(c, &a)| c.with_area(a)).collect();
        let mut reps = ContactSet::new();
        let mut cold = clusterer(k);
        cold.cluster(&contacts, DELTA_M, &mut reps).unwrap();
        let expected = contacts_penalty(&contacts, reps.len());
        let scale = contacts_penalty(&contacts, 1).norm().max(1e-12) + expected.norm();
        let got = representatives_penalty(&reps);
        prop_assert!((got - expected).norm() <= 1e-9 * scale, "cold: {got:?} against {expected:?}");
        let shares: Real = reps.iter().map(|r| r.stiffness_share).sum();
        prop_assert!(shares <= reps.len() as Real * (1.0 + 1e-9), "shares add up to {shares}");
        prop_assert!(reps.iter().all(|r| r.validate().is_ok()));
        // The same contacts, seeded elsewhere: another partition, the same penalty.
        let seeds: Vec<Contact> = seeds
            .iter()
            .map(|p| contact(Vec3::from(*p), Vec3::z(), 0.0))
            .collect();
        let mut warm = clusterer(k);
        warm.warm_start_from(&seeds);
        let mut other = ContactSet::new();
        warm.cluster(&contacts, DELTA_M, &mut other).unwrap();
        prop_assume!(other.len() == reps.len());
        let got = representatives_penalty(&other);
        prop_assert!((got - expected).norm() <= 1e-9 * scale, "warm: {got:?} against {expected:?}");
    }
}

#[test]
fn one_cluster_of_one_face_has_the_papers_stiffness() {
    // Contacts of one depth and one normal: the shares are the clusters' parts of the weight and
    // add up to K' (with equal parts, each is 1: the paper's model); a lone cluster of opposed
    // contacts pushes as little as they do.
    let flat: Vec<Contact> = (0..40)
        .map(|i| {
            let p = Vec3::new(1e-3 * (i % 8) as Real, 1e-3 * (i / 8) as Real, 0.0);
            contact(p, -Vec3::z(), 3e-4).with_area(1e-6)
        })
        .collect();
    for k in [1, 3, 5] {
        let mut c = clusterer(k);
        let mut reps = ContactSet::new();
        c.cluster(&flat, DELTA_M, &mut reps).unwrap();
        // Each share is K' times the part of the weight its cluster stands for.
        let total: Real = c.representative_weights().iter().sum();
        for (r, w) in reps.iter().zip(c.representative_weights()) {
            let expected = reps.len() as Real * w / total;
            assert!((r.stiffness_share - expected).abs() < 1e-9, "k = {k}");
        }
        let sum: Real = reps.iter().map(|r| r.stiffness_share).sum();
        assert!((sum - reps.len() as Real).abs() < 1e-9, "k = {k}: {sum}");
    }
    let opposed = [
        contact(Vec3::zeros(), Vec3::z(), 2e-4).with_area(1e-6),
        contact(Vec3::new(1e-4, 0.0, 0.0), -Vec3::z(), 2e-4).with_area(1e-6),
    ];
    let mut c = clusterer(1);
    let mut reps = ContactSet::new();
    c.cluster(&opposed, DELTA_M, &mut reps).unwrap();
    assert_eq!(reps.len(), 1);
    assert!(reps.as_slice()[0].stiffness_share < 1e-9);
}
