//! Unit and property tests of the clustering.

use super::*;
use proptest::prelude::*;

const DELTA_M: Real = 1e-3;

/// A contact at `p` with normal `n` (normalised) and depth `d`.
fn contact(p: Vec3, n: Vec3, d: Real) -> Contact {
    Contact::new(p, p, p - d * n.normalize(), n.normalize(), d).unwrap()
}

/// The paper's model: the default parameters with one spring per cluster (no torque pairs),
/// for the tests of the clustering itself and of one representative per cluster.
fn paper() -> ClusterParams {
    ClusterParams {
        torque_pairs: false,
        ..Default::default()
    }
}

/// A clusterer of at most `k` clusters, one spring each, the other parameters the defaults.
fn clusterer(k: usize) -> Clusterer {
    Clusterer::new(ClusterParams {
        max_clusters: k,
        ..paper()
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
    let mut c = Clusterer::new(paper()).unwrap();
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
    let mut c = Clusterer::new(paper()).unwrap();
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
    let mut c = Clusterer::new(paper()).unwrap();
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
    let mut c = Clusterer::new(paper()).unwrap();
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
        ..paper()
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

/// Seeds at the old centroids: a warm start on contacts that have not moved begins at a fixed
/// point of Lloyd's method, so its first assignment is the last one (one iteration), where
/// seeds at the contacts closest to the old centroids would start elsewhere and iterate back.
#[test]
fn a_warm_start_on_unmoved_contacts_is_converged_at_once() {
    for (frame, n) in [(0, 50), (300, 40), (7, 200)] {
        let contacts = drifting_frame(frame, n);
        let mut c = Clusterer::new(paper()).unwrap();
        let mut reps = ContactSet::new();
        c.cluster(&contacts, DELTA_M, &mut reps).unwrap();
        let first: Vec<Contact> = reps.iter().copied().collect();
        let stats = c.cluster(&contacts, DELTA_M, &mut reps).unwrap();
        assert!(stats.warm && stats.converged);
        assert_eq!(stats.iterations, 1, "frame {frame}, {n} contacts");
        assert_eq!(reps.as_slice(), first.as_slice());
    }
}

/// An old cluster whose contacts have all gone makes the warm start fall back to the paper's
/// seeds, at the contacts nearest the old centroids, so a warm start still gives K clusters,
/// none empty: when part of the contacts lift off, and when they all jump elsewhere.
#[test]
fn an_old_cluster_whose_contacts_have_gone_is_seeded_at_a_contact() {
    let patch = |x0: Real| -> Vec<Contact> {
        (0..12)
            .map(|i| {
                let p = Vec3::new(x0 + 1e-3 * (i % 4) as Real, 1e-3 * (i / 4) as Real, 0.0);
                contact(p, Vec3::z(), 5e-4)
            })
            .collect()
    };
    let mut both = patch(0.0);
    both.extend(patch(0.1));
    let mut c = clusterer(2);
    let mut reps = ContactSet::new();
    assert_eq!(c.cluster(&both, DELTA_M, &mut reps).unwrap().clusters, 2);
    // The second patch lifts off; the first stays.
    let left = patch(0.0);
    let stats = c.cluster(&left, DELTA_M, &mut reps).unwrap();
    assert!(stats.warm);
    assert_eq!(stats.clusters, 2);
    let mut count = [0usize; 2];
    for &a in c.assignments() {
        count[a as usize] += 1;
    }
    assert!(count.iter().all(|&n| n > 0), "{count:?}");
    // Both representatives lie on the remaining patch.
    for r in reps.iter() {
        assert!(r.p_a.x <= 3e-3 + 1e-12, "{:?}", r.p_a);
    }

    // A tool that jumps: the contacts of a ring, then of the same ring 5 cm away and turned.
    let mut c = clusterer(5);
    c.cluster(&drifting_frame(0, 40), DELTA_M, &mut reps)
        .unwrap();
    let moved: Vec<Contact> = drifting_frame(500, 40)
        .into_iter()
        .map(|mut k| {
            k.p_a += Vec3::new(0.05, 0.0, 0.0);
            k.p_b += Vec3::new(0.05, 0.0, 0.0);
            k
        })
        .collect();
    let stats = c.cluster(&moved, DELTA_M, &mut reps).unwrap();
    assert!(stats.warm);
    assert_eq!(stats.clusters, 5);
}

#[test]
fn same_input_gives_same_output() {
    let run = || {
        let mut c = Clusterer::new(paper()).unwrap();
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
    let mut c = Clusterer::new(paper()).unwrap();
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
    let mut chained = Clusterer::new(paper()).unwrap();
    let (mut reps_a, mut reps_b) = (ContactSet::new(), ContactSet::new());
    chained.cluster(&a, DELTA_M, &mut reps_a).unwrap();
    chained.cluster(&b, DELTA_M, &mut reps_b).unwrap();

    let mut told = Clusterer::new(paper()).unwrap();
    told.warm_start_from(reps_a.as_slice());
    let mut reps = ContactSet::new();
    let stats = told.cluster(&b, DELTA_M, &mut reps).unwrap();
    assert!(stats.warm);
    assert_eq!(reps.as_slice(), reps_b.as_slice());

    // An empty history means a cold start.
    told.warm_start_from(&[]);
    assert!(!told.cluster(&b, DELTA_M, &mut reps).unwrap().warm);

    // A history with a non-finite centre seeds nothing there: K finite representatives.
    let nan = Vec3::new(Real::NAN, 0.0, 0.0);
    for centres in [vec![(nan, 1e-3)], vec![(nan, 1e-3), (Vec3::zeros(), 1e-3)]] {
        told.warm_start_from_centres(&centres);
        let stats = told.cluster(&b, DELTA_M, &mut reps).unwrap();
        assert_eq!(stats.clusters, paper().max_clusters);
        assert!(reps.iter().all(|r| r.validate().is_ok()));
    }
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
        ..paper()
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The stiffness shares make the clustered penalty the contacts' own, whatever the
    /// partition: cold, warm-started from elsewhere, at any K, and however many clusters are
    /// written. The shares add up to at most K, so the stiffness stays within K k_c.
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
        let expected = contacts_wrench(&contacts, k).0;
        let scale = contacts_wrench(&contacts, 1).0.norm().max(1e-12) + expected.norm();
        let got = representatives_wrench(reps.as_slice()).0;
        prop_assert!((got - expected).norm() <= 1e-9 * scale, "cold: {got:?} against {expected:?}");
        let shares: Real = reps.iter().map(|r| r.stiffness_share).sum();
        prop_assert!(shares <= k as Real * (1.0 + 1e-9), "shares add up to {shares}");
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
        let got = representatives_wrench(other.as_slice()).0;
        prop_assert!((got - expected).norm() <= 1e-9 * scale, "warm: {got:?} against {expected:?}");
    }
}

#[test]
fn one_cluster_of_one_face_has_the_papers_stiffness() {
    // Contacts of one depth and one normal: the shares are the clusters' parts of the weight and
    // add up to K (with equal parts, each is 1: the paper's model); a lone cluster of opposed
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
        // Each share is K times the part of the weight its cluster stands for.
        let total: Real = c.representative_weights().iter().sum();
        for (r, w) in reps.iter().zip(c.representative_weights()) {
            let expected = k as Real * w / total;
            assert!((r.stiffness_share - expected).abs() < 1e-9, "k = {k}");
        }
        let sum: Real = reps.iter().map(|r| r.stiffness_share).sum();
        assert!((sum - k as Real).abs() < 1e-9, "k = {k}: {sum}");
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

/// A face pushes the same clustered whether it reaches the clusterer as two contacts (one
/// region per coarse piece) or as forty (its triangles): contacts with areas share `K`
/// springs' stiffness however few clusters are written, rather than `K'`, which made two
/// contacts push 2/5 of the forty's force at `K = 5`. Points without areas are springs each,
/// the paper's model: two push as two springs.
#[test]
fn a_face_pushes_the_same_as_few_contacts_or_many() {
    let points = |n: usize| -> Vec<Contact> {
        (0..n)
            .map(|i| {
                let p = Vec3::new(8e-3 * (i as Real + 0.5) / n as Real, 0.0, 0.0);
                contact(p, -Vec3::z(), 3e-4)
            })
            .collect()
    };
    let face = |n: usize| -> Vec<Contact> {
        points(n)
            .iter()
            .map(|c| c.with_area(1e-4 / n as Real))
            .collect()
    };
    for params in [paper(), ClusterParams::default()] {
        let push = |contacts: &[Contact]| {
            let mut c = Clusterer::new(ClusterParams {
                max_clusters: 5,
                ..params
            })
            .unwrap();
            let mut reps = ContactSet::new();
            let stats = c.cluster(contacts, DELTA_M, &mut reps).unwrap();
            (representatives_wrench(reps.as_slice()).0, stats.clusters)
        };
        let ((few, k_few), (many, k_many)) = (push(&face(2)), push(&face(40)));
        assert_eq!((k_few, k_many), (2, 5));
        assert!(
            (few - many).norm() <= 1e-12 * many.norm(),
            "{few:?} vs {many:?}"
        );
        // The paper's stiffness for five equal clusters of one face: each spring k_c.
        let (f0, _) = contacts_wrench(&face(40), 5);
        assert!((many - f0).norm() <= 1e-12 * f0.norm());
        // Points: two springs of k_c, against five.
        let ((two, _), (five, _)) = (push(&points(2)), push(&points(40)));
        assert!((five - many).norm() <= 1e-12 * many.norm());
        assert!(
            (two - many * 0.4).norm() <= 1e-12 * many.norm(),
            "{two:?} vs {many:?}"
        );
    }
}

/// A contact with no stiffness share (a back-end's closest approach, which reports a distance
/// and stands for no surface) pushes nothing: alone, its representative has no share; beside
/// others, the clustered penalty is theirs.
#[test]
fn a_contact_without_a_share_pushes_nothing() {
    let marker = contact(Vec3::zeros(), -Vec3::z(), 5e-4)
        .with_area(1e-18)
        .with_stiffness_share(0.0);
    for params in [paper(), ClusterParams::default()] {
        let mut c = Clusterer::new(params).unwrap();
        let mut reps = ContactSet::new();
        c.cluster(&[marker], DELTA_M, &mut reps).unwrap();
        assert!(!reps.is_empty());
        assert!(reps.iter().all(|r| r.stiffness_share == 0.0), "{reps:?}");
        let face: Vec<Contact> = (0..10)
            .map(|i| {
                let p = Vec3::new(1e-3 * i as Real, 0.0, 0.0);
                contact(p, -Vec3::z(), 2e-4).with_area(1e-6)
            })
            .collect();
        let mut with = face.clone();
        with.push(marker);
        let push = |contacts: &[Contact]| {
            let mut c = Clusterer::new(params).unwrap();
            let mut reps = ContactSet::new();
            c.cluster(contacts, DELTA_M, &mut reps).unwrap();
            representatives_wrench(reps.as_slice()).0
        };
        let (f0, f) = (push(&face), push(&with));
        assert!((f - f0).norm() <= 1e-9 * f0.norm(), "{f:?} vs {f0:?}");
    }
}

/// The penalty wrench the representatives make at their own state (unit `k_c`, the sign
/// aside): `Σ_k s_k g_k n_k` and its torque about the origin, `Σ_k p_k × s_k g_k n_k`.
fn representatives_wrench(reps: &[Contact]) -> (Vec3, Vec3) {
    reps.iter()
        .fold((Vec3::zeros(), Vec3::zeros()), |(f, t), r| {
            let push = r.n * (r.stiffness_share * weight(r.depth_m, DELTA_M));
            (f + push, t + r.p_a.cross(&push))
        })
}

/// The contacts' own penalty wrench that the shares and the torque pairs keep:
/// `K Σ_i w_i g_i n_i / W` (`K` the clusters asked for) and its torque about the origin.
fn contacts_wrench(contacts: &[Contact], clusters: usize) -> (Vec3, Vec3) {
    let with_areas = contacts.iter().all(|c| c.area_m2 > 0.0);
    let w = |c: &Contact| weight(c.depth_m, DELTA_M) * if with_areas { c.area_m2 } else { 1.0 };
    let total: Real = contacts.iter().map(w).sum();
    let scale = clusters as Real / total;
    contacts
        .iter()
        .fold((Vec3::zeros(), Vec3::zeros()), |(f, t), c| {
            let push = c.n * (w(c) * weight(c.depth_m, DELTA_M) * scale);
            (f + push, t + c.p_a.cross(&push))
        })
}

/// A clusterer of at most `k` clusters written as torque pairs.
fn paired(k: usize) -> Clusterer {
    Clusterer::new(ClusterParams {
        max_clusters: k,
        torque_pairs: true,
        ..Default::default()
    })
    .unwrap()
}

#[test]
fn contacts_at_one_point_far_from_the_origin_get_no_torque_pair() {
    // Five contacts at one point 3.5 cm out, with different normals, depths and areas (the
    // shrunk case of the property test below): no spread, so one spring where they are, and
    // none placed by the rounding of a covariance taken about another point.
    let p = Vec3::new(
        0.019454679097535697,
        -9.571798657132067e-5,
        -0.029397302818075913,
    );
    let contacts: Vec<Contact> = (0..5)
        .map(|i| {
            let n = Vec3::new(0.1 * i as Real, -0.2, 1.0);
            contact(p, n, 1e-4 * i as Real).with_area(1e-7 * (1.0 + i as Real))
        })
        .collect();
    let mut c = paired(1);
    let mut reps = ContactSet::new();
    c.cluster(&contacts, DELTA_M, &mut reps).unwrap();
    assert_eq!(reps.len(), 1, "{reps:?}");
    let r = &reps.as_slice()[0];
    // Their weighted mean, to rounding.
    assert!(
        (r.p_a - p).norm() <= 1e-16 && (r.r_a - p).norm() <= 1e-16,
        "{r:?}"
    );
}

#[test]
fn torque_pairs_give_a_tilted_faces_wrench_whatever_the_partition() {
    // A face pressed deeper at one side: its centre of pressure is off every cluster's centroid,
    // so one spring per cluster loses a couple, and how much depends on the partition.
    let face = tilted_face(12, true);
    for k in 1..=5 {
        let mut c = paired(k);
        let mut reps = ContactSet::new();
        let stats = c.cluster(&face, DELTA_M, &mut reps).unwrap();
        let (f, t) = representatives_wrench(reps.as_slice());
        let (f0, t0) = contacts_wrench(&face, k);
        assert!(
            (f - f0).norm() <= 1e-12 * f0.norm(),
            "k = {k}: {f:?} vs {f0:?}"
        );
        assert!(
            (t - t0).norm() <= 1e-9 * t0.norm(),
            "k = {k}: {t:?} vs {t0:?}"
        );
        assert_eq!(reps.len(), 2 * stats.clusters);
        let shares: Real = reps.iter().map(|r| r.stiffness_share).sum();
        assert!(shares <= stats.clusters as Real * (1.0 + 1e-12), "{shares}");
        // One spring per cluster, same partition: the force, not the couple.
        let mut one = clusterer(k);
        let mut single = ContactSet::new();
        one.cluster(&face, DELTA_M, &mut single).unwrap();
        let (fs, ts) = representatives_wrench(single.as_slice());
        assert!((fs - f0).norm() <= 1e-12 * f0.norm());
        if k == 1 {
            assert!(
                (ts - t0).norm() > 1e-3 * t0.norm(),
                "one spring kept the couple"
            );
        }
    }
}

/// Contacts on a thread: a ring of radius 4 mm, 3 mm long, pressed on both flanks (normals
/// tilted ±30° out of the radial direction and ±10° round it, as a helix's), the upper flanks
/// deeper, so the contacts turn the tool about the axis while their forces nearly cancel.
fn thread_contacts() -> Vec<Contact> {
    let mut out = Vec::new();
    for i in 0..72 {
        for j in 0..6 {
            let a = std::f64::consts::TAU * i as Real / 72.0;
            let z = 0.5e-3 * j as Real;
            let radial = Vec3::new(a.cos(), a.sin(), 0.0);
            let round = Vec3::new(-a.sin(), a.cos(), 0.0);
            let upper = j % 2 == 0;
            let s = if upper { 1.0 } else { -1.0 };
            let n = (radial + Vec3::z() * (0.58 * s) + round * (0.18 * s)).normalize();
            let d = if upper { 3e-4 } else { 1e-4 };
            out.push(contact(radial * 4e-3 + Vec3::z() * z, n, d).with_area(1e-8));
        }
    }
    out
}

#[test]
fn torque_pairs_keep_a_threads_torque_about_its_axis() {
    let thread = thread_contacts();
    for k in [1, 3, 5] {
        let mut c = paired(k);
        let mut reps = ContactSet::new();
        c.cluster(&thread, DELTA_M, &mut reps).unwrap();
        let (f, t) = representatives_wrench(reps.as_slice());
        let (f0, t0) = contacts_wrench(&thread, k);
        assert!(
            t0.z.abs() > 0.5 * t0.norm(),
            "the thread turns the tool: {t0:?}"
        );
        assert!((f - f0).norm() <= 1e-9 * f0.norm().max(1e-3 * t0.norm() / 4e-3));
        assert!(
            (t - t0).norm() <= 1e-9 * t0.norm(),
            "k = {k}: {t:?} vs {t0:?}"
        );
        let mut one = clusterer(k);
        let mut single = ContactSet::new();
        one.cluster(&thread, DELTA_M, &mut single).unwrap();
        let (_, ts) = representatives_wrench(single.as_slice());
        println!(
            "k = {k}: axial torque {:.3e} (pairs {:.3e}, one spring {:.3e})",
            t0.z, t.z, ts.z
        );
        assert!(
            (ts.z - t0.z).abs() > 0.1 * t0.z.abs(),
            "k = {k}: one spring kept the torque"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// With torque pairs, on contacts of a rigid tool at any pose: the force is the contacts'
    /// whatever the partition, the shares stay within K, every spring's `p_a` is its `r_a`
    /// placed by the tool's pose, and (one cluster) what the pair adds to one spring's torque is
    /// a part `t ∈ [0, 1]` of the cluster's couple.
    #[test]
    fn torque_pairs_keep_the_force_and_a_part_of_the_couple(
        contacts in arb_contacts(),
        areas in prop::collection::vec(1e-7..1e-5f64, 120),
        k in 1usize..9,
        axis in prop::array::uniform3(-3.0..3.0f64),
        shift in prop::array::uniform3(-0.1..0.1f64),
    ) {
        let rot = nalgebra::Rotation3::new(Vec3::from(axis));
        let x = Vec3::from(shift);
        let contacts: Vec<Contact> = contacts
            .iter()
            .zip(&areas)
            .map(|(c, &a)| Contact { r_a: rot.inverse() * (c.p_a - x), ..c.with_area(a) })
            .collect();
        let mut c = paired(k);
        let mut reps = ContactSet::new();
        let stats = c.cluster(&contacts, DELTA_M, &mut reps).unwrap();
        let (f, _) = representatives_wrench(reps.as_slice());
        let (f0, _) = contacts_wrench(&contacts, k);
        let scale = contacts_wrench(&contacts, 1).0.norm().max(1e-12) + f0.norm();
        prop_assert!((f - f0).norm() <= 1e-9 * scale, "{f:?} against {f0:?}");
        let shares: Real = reps.iter().map(|r| r.stiffness_share).sum();
        prop_assert!(shares <= k as Real * (1.0 + 1e-9), "shares add up to {shares}");
        prop_assert!(reps.len() <= 2 * stats.clusters);
        for r in reps.iter() {
            prop_assert!(r.validate().is_ok());
            prop_assert!((rot * r.r_a + x - r.p_a).norm() <= 1e-12, "{:?} vs {:?}", rot * r.r_a + x, r.p_a);
        }
        // One cluster: the pair's torque is one spring's plus t times the couple.
        let mut one = paired(1);
        let mut pair = ContactSet::new();
        one.cluster(&contacts, DELTA_M, &mut pair).unwrap();
        let (f1, t1) = representatives_wrench(pair.as_slice());
        let (f0, t0_one) = contacts_wrench(&contacts, 1);
        let centre = one.cluster_centres()[0].0;
        let spring = centre.cross(&f0);
        let couple = t0_one - spring;
        let added = t1 - spring;
        let t = added.dot(&couple) / couple.norm_squared().max(1e-300);
        let size = couple.norm() + 1e-9 * (t0_one.norm() + spring.norm()) + 1e-30;
        prop_assert!((f1 - f0).norm() <= 1e-9 * scale);
        // Along the couple, by a part in [0, 1], to rounding (relative to the torques' sizes:
        // where the couple is small beside them, t itself is known only roughly).
        let t_in = t.clamp(0.0, 1.0);
        prop_assert!((added - couple * t_in).norm() <= 1e-6 * size, "t = {t}: {added:?} not along {couple:?}");
    }
}
