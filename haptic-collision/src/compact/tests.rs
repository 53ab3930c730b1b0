use super::*;
use proptest::prelude::*;

const DELTA: Real = 1e-3;

fn contact(p: Vec3, n: Vec3, d: Real, area: Real) -> Contact {
    let n = n.normalize();
    Contact::new(p, p * 2.0, p - n * d, n, d)
        .unwrap()
        .with_area(area)
}

/// The sums the clustering reads, over all contacts: `Σ w`, `Σ w p`, `Σ w r`, `Σ w d`,
/// `Σ w n`.
fn moments(cs: &[Contact]) -> (Real, Vec3, Vec3, Real, Vec3) {
    let mut s = (0.0, Vec3::zeros(), Vec3::zeros(), 0.0, Vec3::zeros());
    for c in cs {
        let w = c.area_m2 * (c.depth_m + DELTA);
        s.0 += w;
        s.1 += c.p_a * w;
        s.2 += c.r_a * w;
        s.3 += w * c.depth_m;
        s.4 += c.n * w;
    }
    s
}

fn arb_contacts() -> impl Strategy<Value = Vec<Contact>> {
    prop::collection::vec(
        (
            prop::array::uniform3(-0.05..0.05f64),
            prop::array::uniform3(-1.0..1.0f64),
            -0.9 * DELTA..2e-3,
            1e-8..1e-5f64,
        ),
        1..2000,
    )
    .prop_map(|raw| {
        raw.into_iter()
            .filter(|(_, n, _, _)| Vec3::from(*n).norm() > 0.1)
            .map(|(p, n, d, a)| contact(Vec3::from(p), Vec3::from(n), d, a))
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// At most `max` contacts come out; `Σ w`, `Σ w p`, `Σ w r` and `Σ w d` are kept, and
    /// `Σ w n` too when `max` leaves room to split every cell whose normals disagree; the
    /// area never grows; the deepest contact is kept as it is; every contact is valid.
    #[test]
    fn compaction_keeps_the_moments_and_the_deepest_contact(
        raw in arb_contacts(),
        max in 2usize..300,
    ) {
        let mut set = ContactSet::new();
        set.extend(raw.iter().copied());
        let mut compactor = Compactor::new();
        let before = compactor.compact(&mut set, &Pose::identity(), DELTA, max);
        prop_assert_eq!(before, raw.len());
        prop_assert!(set.len() <= max.max(2));
        if raw.len() <= max.max(2) {
            prop_assert_eq!(set.as_slice(), &raw[..]);
        }
        let (w0, p0, r0, d0, n0) = moments(&raw);
        let (w1, p1, r1, d1, n1) = moments(set.as_slice());
        prop_assert!((w1 / w0 - 1.0).abs() < 1e-9, "{w0} {w1}");
        prop_assert!((p1 - p0).norm() <= 1e-9 * w0, "{p0:?} {p1:?}");
        prop_assert!((r1 - r0).norm() <= 1e-9 * w0);
        prop_assert!((d1 - d0).abs() <= 1e-9 * w0 * 2e-3);
        // Every merged cell was split (or agreed): the force the contacts stand for is kept.
        if compactor.splits.len() <= max.max(2) - 1 - compactor.used.len() {
            prop_assert!((n1 - n0).norm() <= 1e-9 * w0, "{n0:?} {n1:?}");
        }
        let area = |cs: &[Contact]| cs.iter().map(|c| c.area_m2).sum::<Real>();
        prop_assert!(area(set.as_slice()) <= area(&raw) * (1.0 + 1e-9), "area ratio {}", area(set.as_slice()) / area(&raw));
        let deepest = raw.iter().map(|c| c.depth_m).fold(Real::NEG_INFINITY, Real::max);
        prop_assert!(set.iter().any(|c| c.depth_m == deepest && raw.contains(c)));
        for c in set.iter() {
            prop_assert!(c.validate().is_ok());
            prop_assert!((c.p_a - c.p_b - c.n * c.depth_m).norm() < 1e-12);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// One split cell (a patch of contacts whose normals lean up to 45° from `z`, all but
    /// the deepest merged into two halves): the halves' offset along their split `u`
    /// leaves the torque of the penalty over the contacts, `Σ w (p − p̄) × n`, as the offset
    /// across `u` alone gives it, and never takes the torque of the penalty the clustering
    /// reads, `Σ w g (p − p̄) × n`, further from the cell's.
    #[test]
    fn a_split_cells_offset_along_its_split_keeps_more_of_the_clusterings_torque(
        seed in 0u64..1_000_000,
        count in 8usize..60,
    ) {
        let mut rng = haptic_test_support::rng::Lcg(seed);
        let mut raw = Vec::new();
        for _ in 0..count {
            let p = Vec3::new(rng.next(), rng.next(), 0.2 * rng.next()) * 1e-3;
            let tilt = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, 0.0) * 1.4;
            let n = (Vec3::z() + tilt).normalize();
            let d = (2.0 * rng.next() - 1.0) * 0.9 * DELTA;
            raw.push(contact(p, n, d, 1e-8 * (0.2 + rng.next())));
        }
        let mut set = ContactSet::new();
        set.extend(raw.iter().copied());
        Compactor::new().compact(&mut set, &Pose::identity(), DELTA, 3);
        prop_assume!(set.len() == 3);
        let out = set.as_slice();
        let deepest = out[0];
        let cell: Vec<Contact> = raw.iter().copied().filter(|c| *c != deepest).collect();
        let (h0, h1) = (out[1], out[2]);
        let w = |c: &Contact| c.area_m2 * (c.depth_m + DELTA);
        let centre = (h0.p_a + h1.p_a) * 0.5;
        let v = (h0.p_a - h1.p_a) * 0.5;
        let u = (h0.n - h1.n).normalize();
        let across = v - u * u.dot(&v);
        // The halves' torques about their centre with the offset `x`, and the cell's.
        let halves = |x: Vec3, g_power: i32| {
            let g = |c: &Contact| (c.depth_m + DELTA).powi(g_power);
            x.cross(&h0.n) * (w(&h0) * g(&h0)) - x.cross(&h1.n) * (w(&h1) * g(&h1))
        };
        let of_cell = |g_power: i32| {
            cell.iter()
                .map(|c| {
                    let g = (c.depth_m + DELTA).powi(g_power);
                    (c.p_a - centre).cross(&c.n) * (w(c) * g)
                })
                .sum::<Vec3>()
        };
        let size = of_cell(0).norm() + v.norm() * cell.iter().map(w).sum::<Real>();
        prop_assert!((halves(v, 0) - halves(across, 0)).norm() <= 1e-9 * size);
        let (kept, across_only) = (
            (of_cell(1) - halves(v, 1)).norm(),
            (of_cell(1) - halves(across, 1)).norm(),
        );
        let slack = 1e-9 * across_only + 1e-12 * size * DELTA;
        prop_assert!(kept <= across_only + slack, "{kept} {across_only}");
    }
}

/// `Σ w g n`, the penalty the clustering reads (`g = d + δ`).
fn penalty(cs: &[Contact]) -> Vec3 {
    cs.iter()
        .map(|c| c.n * (c.area_m2 * (c.depth_m + DELTA).powi(2)))
        .sum()
}

#[test]
fn a_threads_flanks_keep_the_penalty_the_clustering_reads() {
    // Both flanks of a thread in every cell (one normal bin: their normals lean either way
    // along z), the upper flanks pressed deeper: merging them at one depth would push as if
    // both were equally deep, and lose the axial force their depths make. (The flanks'
    // weights `a g` are equal, so the cells' mean normals are radial and the depths'
    // lean is all across them: the part the split keeps exactly.)
    let mut set = ContactSet::new();
    let (g_upper, g_lower) = (3e-4 + DELTA, 1e-4 + DELTA);
    for i in 0..2000 {
        let (y, z) = ((i % 40) as Real * 1e-4, (i / 40) as Real * 1e-4);
        let upper = (i / 40) % 2 == 0;
        let n = Vec3::new(1.0, 0.0, if upper { 0.5 } else { -0.5 });
        let (d, a) = if upper {
            (3e-4, 1e-8 * g_lower / g_upper)
        } else {
            (1e-4, 1e-8)
        };
        set.push(contact(Vec3::new(0.0, y, z), n, d, a));
    }
    let raw: Vec<Contact> = set.iter().copied().collect();
    Compactor::new().compact(&mut set, &Pose::identity(), DELTA, 16);
    assert!(set.len() <= 16);
    // Merged at one depth, the balanced flanks would push with no axial force at all. (Not
    // to rounding: the deepest contact is kept apart, which unbalances its cell.)
    let (p0, p1) = (penalty(&raw), penalty(set.as_slice()));
    assert!((p1 - p0).norm() <= 1e-4 * p0.norm(), "{p0:?} {p1:?}");
    assert!((p1.z / p0.z - 1.0).abs() < 1e-3, "{p0:?} {p1:?}");
    let (_, _, _, _, n0) = moments(&raw);
    let (_, _, _, _, n1) = moments(set.as_slice());
    assert!((n1 - n0).norm() <= 1e-9 * n0.norm());
    let area = |cs: &[Contact]| cs.iter().map(|c| c.area_m2).sum::<Real>();
    assert!(area(set.as_slice()) <= area(&raw) * (1.0 + 1e-12));
}

#[test]
fn opposed_flanks_never_merge() {
    // Two faces of a 1 mm wall, pressed from both sides: 400 contacts each, normals opposed.
    let mut set = ContactSet::new();
    for i in 0..400 {
        let (x, y) = ((i % 20) as Real * 1e-3, (i / 20) as Real * 1e-3);
        set.push(contact(Vec3::new(x, y, 0.0), Vec3::z(), 1e-4, 1e-6));
        set.push(contact(Vec3::new(x, y, 1e-3), -Vec3::z(), 1e-4, 1e-6));
    }
    Compactor::new().compact(&mut set, &Pose::identity(), DELTA, 16);
    assert!(set.len() <= 16);
    let up: Real = set.iter().filter(|c| c.n.z > 0.0).map(|c| c.area_m2).sum();
    let down: Real = set.iter().filter(|c| c.n.z < 0.0).map(|c| c.area_m2).sum();
    assert!((up - 4e-4).abs() < 1e-12 && (down - 4e-4).abs() < 1e-12);
    assert!(set.iter().all(|c| c.n.z.abs() == 1.0));
}

#[test]
fn a_curved_patch_keeps_its_force_and_splits_along_its_curvature() {
    // A cap of ±0.5 rad of a 1 cm sphere, 900 contacts, merged into at most 32: the normals of a
    // cell disagree, so each merged cell is two contacts whose normals keep `Σ w n`.
    let mut set = ContactSet::new();
    for i in 0..30 {
        for j in 0..30 {
            let (u, v) = (i as Real / 29.0 - 0.5, j as Real / 29.0 - 0.5);
            let n = Vec3::new(u.sin(), v.sin(), 1.0).normalize();
            set.push(contact(n * 0.01, n, 2e-4, 1e-7));
        }
    }
    let raw = set.clone();
    Compactor::new().compact(&mut set, &Pose::identity(), DELTA, 32);
    assert!(set.len() <= 32);
    let (w0, _, _, _, n0) = moments(raw.as_slice());
    let (w1, _, _, _, n1) = moments(set.as_slice());
    assert!((w1 - w0).abs() <= 1e-12 * w0);
    assert!((n1 - n0).norm() <= 1e-12 * w0, "{n0:?} {n1:?}");
    // With one normal per cell the force would have grown: the normals do disagree.
    let one_per_cell: Real = set.iter().map(|c| c.area_m2 * (c.depth_m + DELTA)).sum();
    assert!(n0.norm() < 0.99 * one_per_cell);
    // The two halves of a split cell straddle the cell's point (within the cell) and the
    // cell's mean normal within the cap, at one depth (the depths do not lean with the
    // normals).
    // (The first contact is the deepest raw one; merged cells follow as pairs.)
    let rest = &set.as_slice()[1..];
    assert!(rest.len() >= 2 && rest.len() % 2 == 0);
    for pair in rest.chunks(2) {
        assert_eq!(pair[0].depth_m, pair[1].depth_m);
        let mid = (pair[0].p_a + pair[1].p_a) * 0.5;
        assert!((pair[0].p_a - mid).norm() < 1e-3, "{mid:?}");
        assert!(pair[0].n.z > 0.8 && pair[1].n.z > 0.8 && pair[0].n != pair[1].n);
    }
}

/// A thread's flank: contacts on a helical band about `z` (radius 5 mm, pitch 1 mm, one
/// turn), normals radial and tilted along the axis by the flank's angle, weights growing
/// along the band. Merged into 32, the halves of each cell are placed apart so that they
/// keep its torque across their split, which one point per cell loses, and along it what
/// they can of the torque of the penalty the clustering reads, `Σ w g n`.
#[test]
fn a_helical_flank_keeps_its_torque() {
    let mut set = ContactSet::new();
    for i in 0..600 {
        for j in 0..3 {
            let theta = i as Real / 600.0 * std::f64::consts::TAU;
            let (r, z) = (
                5e-3 + j as Real * 1e-4,
                1e-3 * theta / std::f64::consts::TAU,
            );
            let radial = Vec3::new(theta.cos(), theta.sin(), 0.0);
            let n = (radial + Vec3::z() * 0.6).normalize();
            let d = 1e-4 + 2e-4 * theta.sin();
            set.push(contact(radial * r + Vec3::z() * z, n, d, 1e-8));
        }
    }
    let raw = set.clone();
    Compactor::new().compact(&mut set, &Pose::identity(), DELTA, 32);
    assert!(set.len() <= 32);
    let wrench = |cs: &[Contact], at_mid: bool| {
        let (mut f, mut t) = (Vec3::zeros(), Vec3::zeros());
        let mut rest = cs.iter();
        // The deepest contact alone, then merged cells in pairs (halves) where split.
        let mut push = |c: &Contact, p: Vec3| {
            let fi = c.n * (c.area_m2 * (c.depth_m + DELTA));
            f += fi;
            t += p.cross(&fi);
        };
        if let Some(c) = rest.next() {
            push(c, c.p_a);
        }
        let rest: Vec<_> = rest.collect();
        for pair in rest.chunks(2) {
            let mid = (pair[0].p_a + pair[pair.len() - 1].p_a) * 0.5;
            for c in pair {
                push(c, if at_mid { mid } else { c.p_a });
            }
        }
        (f, t)
    };
    let (f0, t0) = wrench(raw.as_slice(), false);
    let (f1, t1) = wrench(set.as_slice(), false);
    let (_, t_mid) = wrench(set.as_slice(), true);
    assert!((f1 - f0).norm() < 1e-9 * f0.norm());
    let (kept, at_one_point) = (
        (t1 - t0).norm() / t0.norm(),
        (t_mid - t0).norm() / t0.norm(),
    );
    // 5.7e-4 against 2.6e-2.
    assert!(kept < 0.05 * at_one_point, "{kept} {at_one_point}");
    // The torque of the penalty the clustering reads, `Σ w g n`.
    let clustering_torque = |cs: &[Contact]| {
        cs.iter()
            .map(|c| {
                let g = c.depth_m + DELTA;
                c.p_a.cross(&c.n) * (c.area_m2 * g * g)
            })
            .sum::<Vec3>()
    };
    let (g0, g1) = (
        clustering_torque(raw.as_slice()),
        clustering_torque(set.as_slice()),
    );
    // 3.5e-4; 1.2e-2 with the halves' offset across `u` alone.
    let kept_g = (g1 - g0).norm() / g0.norm();
    assert!(kept_g < 2e-3, "{kept_g}");
}

#[test]
fn a_warm_compactor_allocates_no_more() {
    let mut set = ContactSet::new();
    for i in 0..5000 {
        let p = Vec3::new((i % 71) as Real * 1e-4, (i / 71) as Real * 1e-4, 0.0);
        set.push(contact(p, Vec3::z(), 1e-4, 1e-8));
    }
    let raw = set.clone();
    let mut compactor = Compactor::new();
    compactor.compact(&mut set, &Pose::identity(), DELTA, 256);
    let caps = (
        compactor.table.capacity(),
        compactor.used.capacity(),
        compactor.merged.capacity(),
        compactor.splits.capacity(),
    );
    let mut again = raw.clone();
    compactor.compact(&mut again, &Pose::identity(), DELTA, 256);
    assert_eq!(again.as_slice(), set.as_slice());
    assert_eq!(
        caps,
        (
            compactor.table.capacity(),
            compactor.used.capacity(),
            compactor.merged.capacity(),
            compactor.splits.capacity()
        )
    );
}
