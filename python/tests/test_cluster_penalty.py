"""haptic.Clusterer (weighted k-means with warm start, eqs. 28–32) and haptic.PenaltyModel
(eq. 33): what they compute, their sign conventions, and their parameter errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

import haptic

DELTA = 1e-3
DOWN = np.array([0.0, 0.0, -1.0])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])


def patch(centre, count, rng, depths) -> tuple[np.ndarray, np.ndarray]:
    """`count` contact points within 1 mm of `centre` and their depths."""
    p = np.asarray(centre, dtype=np.float64) + rng.uniform(-1e-3, 1e-3, size=(count, 3))
    p[:, 2] = centre[2]
    return p, np.asarray(depths, dtype=np.float64)


def floor_contacts(points: np.ndarray, depths: np.ndarray) -> haptic.Contacts:
    """Contacts of a tool resting at the identity on a floor below it: normals down, out of the
    tool; p_b above p_a by the depth."""
    k = len(points)
    n = np.tile(DOWN, (k, 1))
    p_b = points - depths[:, None] * n
    return haptic.Contacts(points, points.copy(), p_b, n, depths)


def two_patches(rng, deepest_in_b: bool):
    """Ten contacts around A = (0, 0, 0) and twelve around B = (0.1, 0, 0); the deepest contact
    in B (or in A)."""
    da = np.linspace(0.0, 4e-4, 10)
    db = np.linspace(-5e-4, 3e-4, 12)
    if deepest_in_b:
        db[7] = 6e-4
    else:
        da[3] = 6e-4
    pa, da = patch([0.0, 0.0, 0.0], 10, rng, da)
    pb, db = patch([0.1, 0.0, 0.0], 12, rng, db)
    return np.vstack([pa, pb]), np.concatenate([da, db])


def weighted_centroid(points, depths):
    w = np.maximum(depths + DELTA, 1e-3 * DELTA)
    return (w[:, None] * points).sum(axis=0) / w.sum(), w


def test_two_patches_give_two_weighted_representatives():
    rng = np.random.default_rng(3)
    points, depths = two_patches(rng, deepest_in_b=True)
    contacts = floor_contacts(points, depths)
    # The paper's model: one spring per cluster at its weighted centroid.
    clusterer = haptic.Clusterer(max_clusters=2, torque_pairs=False)
    assert not clusterer.torque_pairs
    reps = clusterer.cluster(contacts, delta=DELTA)
    assert isinstance(reps, haptic.Contacts)
    assert len(reps) == 2
    weights = clusterer.representative_weights
    assert weights.shape == (2,) and weights.dtype == np.float64
    assert weights.sum() == pytest.approx(np.sum(depths + DELTA), rel=1e-12)
    # A cold start seeds the deepest contact first: B's cluster comes first.
    assert reps.p_a[0, 0] > 0.05 and reps.p_a[1, 0] < 0.05
    for i, sl in ((0, slice(10, 22)), (1, slice(0, 10))):
        centroid, w = weighted_centroid(points[sl], depths[sl])
        assert np.allclose(reps.p_a[i], centroid, rtol=0, atol=1e-15)
        assert weights[i] == pytest.approx(w.sum(), rel=1e-12)
        assert reps.depth[i] == pytest.approx((w * depths[sl]).sum() / w.sum(), rel=1e-9, abs=1e-15)
    assert np.allclose(reps.n, DOWN, atol=1e-12)
    # The representative's obstacle point sits its depth along the normal: p_b = p_a − d n.
    assert np.allclose(reps.p_b, reps.p_a - reps.depth[:, None] * reps.n, rtol=0, atol=1e-15)


def test_k_caps_the_representatives_and_few_contacts_give_few():
    rng = np.random.default_rng(4)
    points, depths = two_patches(rng, deepest_in_b=True)
    contacts = floor_contacts(points, depths)
    five = haptic.Clusterer(max_clusters=5, torque_pairs=False)
    assert len(five.cluster(contacts, delta=DELTA)) == 5
    assert five.max_clusters == 5
    # With torque pairs (the default), two springs per cluster.
    paired = haptic.Clusterer(max_clusters=5)
    assert paired.torque_pairs
    assert len(paired.cluster(contacts, delta=DELTA)) == 10
    one = haptic.Clusterer(max_clusters=1, torque_pairs=False)
    reps = one.cluster(contacts, delta=DELTA)
    assert len(reps) == 1
    centroid, _ = weighted_centroid(points, depths)
    assert np.allclose(reps.p_a[0], centroid, rtol=0, atol=1e-14)
    three = floor_contacts(points[:3], depths[:3])
    assert len(haptic.Clusterer(max_clusters=5).cluster(three, delta=DELTA)) == 3, (
        "a cluster of one contact is one spring"
    )
    empty = floor_contacts(np.zeros((0, 3)), np.zeros(0))
    assert len(five.cluster(empty, delta=DELTA)) == 0
    assert five.representative_weights.shape == (0,)


def test_warm_start_keeps_the_order_and_reset_forgets_it():
    rng = np.random.default_rng(5)
    points, depths = two_patches(rng, deepest_in_b=True)
    first = floor_contacts(points, depths)
    # The next frame: jittered by 10 µm, shuffled, and now the deepest contact is in A, so a
    # cold start would put A's cluster first.
    points2, depths2 = two_patches(np.random.default_rng(6), deepest_in_b=False)
    order = rng.permutation(len(points2))
    points2 = points2[order] + rng.uniform(-1e-5, 1e-5, size=points2.shape) * [1, 1, 0]
    depths2 = depths2[order]
    second = floor_contacts(points2, depths2)

    warm = haptic.Clusterer(max_clusters=2, warm_start=True, torque_pairs=False)
    reps1 = warm.cluster(first, delta=DELTA)
    assert reps1.p_a[0, 0] > 0.05, "a cold start puts the deepest contact's cluster (B) first"
    reps2 = warm.cluster(second, delta=DELTA)
    assert reps2.p_a[0, 0] > 0.05 and reps2.p_a[1, 0] < 0.05, "warm start kept B first"

    cold = haptic.Clusterer(max_clusters=2, warm_start=False, torque_pairs=False)
    cold.cluster(first, delta=DELTA)
    reps_cold = cold.cluster(second, delta=DELTA)
    assert reps_cold.p_a[0, 0] < 0.05, "without warm start the deepest (A) comes first"

    warm.reset()
    reps_reset = warm.cluster(second, delta=DELTA)
    assert reps_reset.p_a[0, 0] < 0.05, "after reset() the clusterer cold-starts"
    assert np.array_equal(reps_reset.p_a, reps_cold.p_a)


@pytest.mark.parametrize("torque_pairs", [False, True])
def test_shares_keep_the_penalty_whatever_the_partition(torque_pairs):
    # Five clusters of the same contacts, cold and warm-started from another frame: different
    # partitions, the same force, K' k_c Σ w g n / W (w = g = d + δ without areas, so the
    # K' = 5 clusters written); the shares add up to at most K' and are 1 for a contact built
    # from arrays. With torque pairs the
    # torque is the contacts' own too.
    rng = np.random.default_rng(7)
    points, depths = two_patches(rng, deepest_in_b=True)
    contacts = floor_contacts(points, depths)
    assert np.array_equal(contacts.stiffness_share, np.ones(len(contacts)))
    cold = haptic.Clusterer(max_clusters=5, torque_pairs=torque_pairs).cluster(contacts, delta=DELTA)
    warm = haptic.Clusterer(max_clusters=5, torque_pairs=torque_pairs)
    warm.cluster(floor_contacts(points[::-1] + [0.02, 0.0, 0.0], depths[::-1]), delta=DELTA)
    other = warm.cluster(contacts, delta=DELTA)
    springs = 2 if torque_pairs else 1
    assert len(cold) == len(other) == 5 * springs
    assert not np.allclose(np.sort(cold.p_a[:, 0]), np.sort(other.p_a[:, 0]), rtol=0, atol=1e-6)
    model = haptic.PenaltyModel()
    g = np.maximum(depths + DELTA, 1e-3 * DELTA)
    push = 5 * 2000.0 * (g * g)[:, None] / g.sum() * -DOWN
    expected = push.sum(axis=0)
    expected_torque = np.cross(points, push).sum(axis=0)
    for reps in (cold, other):
        assert reps.stiffness_share.sum() <= 5 * (1 + 1e-12)
        f, t = model.wrench(body(), IDENTITY, reps)
        assert np.allclose(f, expected, rtol=1e-9, atol=0)
        if torque_pairs:
            assert np.allclose(t, expected_torque, rtol=1e-9, atol=1e-9 * np.abs(expected_torque).max())
        else:
            assert not np.allclose(t, expected_torque, rtol=1e-3, atol=0)


def test_bad_cluster_parameters():
    with pytest.raises(haptic.ClusterError) as e:
        haptic.Clusterer(max_clusters=0)
    assert e.value.field == "max_clusters"
    with pytest.raises(haptic.ClusterError) as e:
        haptic.Clusterer(max_iterations=0)
    assert e.value.field == "max_iterations"
    contacts = floor_contacts(np.zeros((2, 3)) + [[0, 0, 0], [0.1, 0, 0]], np.zeros(2))
    clusterer = haptic.Clusterer()
    for delta in (0.0, -1e-3, float("nan")):
        with pytest.raises(haptic.ClusterError) as e:
            clusterer.cluster(contacts, delta=delta)
        assert e.value.field == "delta"


def test_large_sets_cluster_the_same_as_small_ones():
    rng = np.random.default_rng(8)
    centres = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0]])
    k = 20000
    points = centres[rng.integers(0, 3, size=k)] + rng.normal(scale=1e-3, size=(k, 3)) * [1, 1, 0]
    depths = rng.uniform(0.0, 5e-4, size=k)
    reps = haptic.Clusterer(max_clusters=3, max_iterations=50, torque_pairs=False).cluster(
        floor_contacts(points, depths), delta=DELTA
    )
    assert len(reps) == 3
    found = sorted(tuple(np.round(p, 2)) for p in reps.p_a)
    assert found == sorted(tuple(np.round(c, 2)) for c in centres)


# --- the penalty model ------------------------------------------------------------------------


def body() -> haptic.RigidBody:
    return haptic.RigidBody(0.05, np.diag([2e-5, 3e-5, 4e-5]))


def one_contact(pose, r_a, n, depth) -> tuple[haptic.Contacts, np.ndarray]:
    """One contact at body point `r_a` of a tool at `pose`, normal `n` out of the tool, `depth`
    deep (p_b = p_a − depth n), and the lever arm ρ = R r_a."""
    pose = np.asarray(pose, dtype=np.float64)
    w, x, y, z = pose[3:]
    rot = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
    r_a = np.asarray(r_a, dtype=np.float64)
    n = np.asarray(n, dtype=np.float64)
    p_a = pose[:3] + rot @ r_a
    p_b = p_a - depth * n
    return haptic.Contacts([p_a], [r_a], [p_b], [n], [depth]), rot @ r_a


def test_one_contact_pushes_the_tool_along_minus_n():
    k, b, delta = 2000.0, 2.0, 1e-3
    model = haptic.PenaltyModel(stiffness_n_per_m=k, damping_ns_per_m=b, delta_m=delta)
    pose = np.array([0.0, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0])
    # Under the centre, the floor below: n points down out of the tool; 0.5 mm deep.
    contacts, rho = one_contact(pose, [0.0, 0.0, -0.01], DOWN, 5e-4)
    force, torque = model.wrench(body(), pose, contacts)
    assert force.shape == (3,) and torque.shape == (3,) and force.dtype == np.float64
    assert np.allclose(force, -k * (5e-4 + delta) * DOWN, rtol=1e-12, atol=0)  # 3 N up
    assert force[2] == pytest.approx(3.0, rel=1e-12)
    assert np.allclose(torque, 0.0, atol=1e-15)

    # Off the centre: the torque about the centre of mass is ρ × F.
    contacts, rho = one_contact(pose, [0.02, 0.0, -0.01], DOWN, 5e-4)
    force, torque = model.wrench(body(), pose, contacts)
    assert force[2] == pytest.approx(3.0, rel=1e-12)
    assert np.allclose(torque, np.cross(rho, force), rtol=1e-12, atol=1e-15)
    assert torque[1] == pytest.approx(-0.06, rel=1e-12)


def test_sign_follows_the_normal_in_any_direction():
    model = haptic.PenaltyModel(stiffness_n_per_m=1000.0, damping_ns_per_m=0.0, delta_m=1e-3)
    pose = np.array([0.1, -0.2, 0.3, *[math.cos(0.4), 0.0, math.sin(0.4), 0.0]])
    n = np.array([1.0, -2.0, 0.5])
    n /= np.linalg.norm(n)
    contacts, rho = one_contact(pose, [0.01, 0.02, -0.005], n, 2e-4)
    force, torque = model.wrench(body(), pose, contacts)
    assert np.allclose(force, -1000.0 * 1.2e-3 * n, rtol=1e-12, atol=1e-15)
    assert np.allclose(torque, np.cross(rho, force), rtol=1e-12, atol=1e-15)


def test_pre_contact_band_and_beyond():
    k, delta = 2000.0, 1e-3
    model = haptic.PenaltyModel(stiffness_n_per_m=k, damping_ns_per_m=0.0, delta_m=delta)
    pose = IDENTITY
    # 0.4 mm apart: inside the pre-contact band δ, pushes with k (δ − 0.4 mm).
    apart, _ = one_contact(pose, [0.0, 0.0, -0.01], DOWN, -4e-4)
    force, _ = model.wrench(body(), pose, apart)
    assert force[2] == pytest.approx(k * 6e-4, rel=1e-9)
    # 1.5 mm apart: beyond δ, nothing.
    far, _ = one_contact(pose, [0.0, 0.0, -0.01], DOWN, -1.5e-3)
    force, torque = model.wrench(body(), pose, far)
    assert np.array_equal(force, np.zeros(3)) and np.array_equal(torque, np.zeros(3))


def test_damping_and_never_pulling():
    k, b, delta = 2000.0, 2.0, 1e-3
    model = haptic.PenaltyModel(stiffness_n_per_m=k, damping_ns_per_m=b, delta_m=delta)
    pose = np.array([0.0, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0])
    contacts, _ = one_contact(pose, [0.0, 0.0, -0.01], DOWN, 5e-4)
    # Moving into the floor at 0.1 m/s: λ = k g + b n·v = 3 + 0.2.
    force, _ = model.wrench(body(), pose, contacts, velocity=[0.0, 0.0, -0.1])
    assert force[2] == pytest.approx(3.2, rel=1e-12)
    # Leaving fast (2 m/s): λ = 3 − 4 < 0, and the force never pulls.
    force, torque = model.wrench(body(), pose, contacts, velocity=[0.0, 0.0, 2.0])
    assert np.array_equal(force, np.zeros(3)) and np.array_equal(torque, np.zeros(3))
    # Spinning about z moves an off-centre point sideways: no normal velocity, no change.
    off, _ = one_contact(pose, [0.02, 0.0, -0.01], DOWN, 5e-4)
    still, _ = model.wrench(body(), pose, off)
    spun, _ = model.wrench(body(), pose, off, angular_velocity=[0.0, 0.0, 5.0])
    assert np.allclose(spun, still, rtol=1e-12, atol=0)
    # Rolling about y moves it down into the floor: ω × ρ = (0, 5, 0) × (0.02, 0, -0.01).
    rolled, _ = model.wrench(body(), pose, off, angular_velocity=[0.0, 5.0, 0.0])
    v_a = np.cross([0.0, 5.0, 0.0], [0.02, 0.0, -0.01])
    assert rolled[2] == pytest.approx(3.0 + b * np.dot(DOWN, v_a), rel=1e-12)


def test_wrench_of_a_set_is_the_sum():
    model = haptic.PenaltyModel()
    pose = np.array([0.0, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0])
    a, _ = one_contact(pose, [0.02, 0.0, -0.01], DOWN, 5e-4)
    b, _ = one_contact(pose, [-0.01, 0.015, -0.01], DOWN, 2e-4)
    both = haptic.Contacts(
        np.vstack([a.p_a, b.p_a]), np.vstack([a.r_a, b.r_a]), np.vstack([a.p_b, b.p_b]),
        np.vstack([a.n, b.n]), np.concatenate([a.depth, b.depth]),
    )
    fa, ta = model.wrench(body(), pose, a)
    fb, tb = model.wrench(body(), pose, b)
    f, t = model.wrench(body(), pose, both)
    assert np.allclose(f, fa + fb, rtol=1e-14, atol=0)
    assert np.allclose(t, ta + tb, rtol=1e-12, atol=1e-16)
    none = haptic.Contacts(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
                           np.zeros((0, 3)), np.zeros(0))
    f0, t0 = model.wrench(body(), pose, none)
    assert np.array_equal(f0, np.zeros(3)) and np.array_equal(t0, np.zeros(3))


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"stiffness_n_per_m": 0.0}, "penalty.stiffness_n_per_m"),
        ({"stiffness_n_per_m": -5.0}, "penalty.stiffness_n_per_m"),
        ({"stiffness_n_per_m": float("nan")}, "penalty.stiffness_n_per_m"),
        ({"damping_ns_per_m": -1.0}, "penalty.damping_ns_per_m"),
        ({"delta_m": -1e-3}, "penalty.delta_m"),
        ({"delta_m": float("inf")}, "penalty.delta_m"),
    ],
)
def test_bad_penalty_parameters_are_dynamics_errors(kwargs, field):
    with pytest.raises(haptic.DynamicsError) as e:
        haptic.PenaltyModel(**kwargs)
    assert e.value.field == field
    assert isinstance(e.value, haptic.HapticError) and not isinstance(e.value, ValueError)


def test_bad_wrench_arguments():
    model = haptic.PenaltyModel()
    contacts, _ = one_contact(IDENTITY, [0.0, 0.0, -0.01], DOWN, 5e-4)
    with pytest.raises(haptic.InputError) as e:
        model.wrench(body(), [0, 0, 0, 1, 0, 0, np.nan], contacts)
    assert e.value.field == "pose"
    with pytest.raises(haptic.InputError) as e:
        model.wrench(body(), IDENTITY, contacts, velocity=[0.0, np.inf, 0.0])
    assert e.value.field == "velocity"
    with pytest.raises(haptic.InputError) as e:
        model.wrench(body(), IDENTITY, contacts, angular_velocity=[0.0, 1.0])
    assert e.value.field == "angular_velocity"


def test_rigid_bodies():
    b = haptic.RigidBody(0.05, np.diag([2e-5, 3e-5, 4e-5]))
    assert b.mass_kg == 0.05
    assert np.array_equal(b.inertia_kg_m2, np.diag([2e-5, 3e-5, 4e-5]))
    cube = haptic.Mesh(
        [[x, y, z] for z in (0, 0.1) for y in (0, 0.1) for x in (0, 0.1)],
        [[0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5], [0, 1, 5], [0, 5, 4],
         [2, 6, 7], [2, 7, 3], [0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6]],
    )
    mp = cube.mass_properties(1000.0)
    from_mp = haptic.RigidBody.from_mass_properties(mp)
    assert from_mp.mass_kg == mp.mass_kg
    assert np.allclose(from_mp.inertia_kg_m2, mp.inertia_about_com, rtol=1e-15, atol=1e-20)
    with pytest.raises(haptic.DynamicsError):
        haptic.RigidBody(-1.0, np.eye(3) * 1e-5)
    with pytest.raises(haptic.DynamicsError):
        haptic.RigidBody(0.0, np.eye(3) * 1e-5)
    with pytest.raises(haptic.DynamicsError):
        haptic.RigidBody(1.0, np.diag([1e-5, 1e-5, 1e-3]))  # I1 + I2 < I3: not physical
    with pytest.raises(haptic.DynamicsError):
        haptic.RigidBody(1.0, [[1e-5, 1e-6, 0], [0, 1e-5, 0], [0, 0, 1e-5]])  # not symmetric
    with pytest.raises(haptic.InputError) as e:
        haptic.RigidBody(1.0, np.eye(2))
    assert e.value.field == "inertia_kg_m2"
    with pytest.raises(haptic.InputError) as e:
        haptic.RigidBody(1.0, np.full((3, 3), np.nan))
    assert e.value.field == "inertia_kg_m2"
