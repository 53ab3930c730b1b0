"""Collision queries from Python: the same contacts, representatives and penalty wrench as the
Rust reference program on the same inputs, bit for bit; contacts as numpy arrays; every bad
argument an exception."""

from __future__ import annotations

import math

import numpy as np
import pytest

import haptic

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
NO_FEATURE = 0xFFFFFFFF

# The jaws scene's contact parameters (xtask/scenes/jaws.toml): δ = 1 mm, K = 5, k_c = 5 kN/m,
# a 10 g tool; the penalty damping is the library default (2 N s/m).
DELTA = 1e-3
CLUSTERS = 5
STIFFNESS = 5000.0
DAMPING = 2.0
MASS = 0.01


def rotation_pose(position, axis, angle) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    s = math.sin(angle / 2)
    return np.array([*position, math.cos(angle / 2), *(s * axis)])


def rotation_matrix(q) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


# The upper jaw as stored sits on the lower one in occlusion: the identity touches. The second
# pose slides it 0.2 mm, lifts it 0.1 mm and turns it by 0.1° about a skew axis.
def random_pose(seed: int) -> np.ndarray:
    """A pose near occlusion with a random axis: its quaternion's norm is 1 only to rounding,
    as a user's would be (the normalisation must give the same bits as in Rust)."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    return rotation_pose(rng.uniform(-2e-4, 2e-4, size=3), axis / np.linalg.norm(axis),
                         math.radians(rng.uniform(0.05, 0.3)))


POSES = {
    "occlusion": IDENTITY,
    "slid": rotation_pose([2e-4, -1e-4, 1e-4], [0.2, 1.0, 0.1], math.radians(0.1)),
    "random-a": random_pose(7),
    "random-b": random_pose(11),
}


def pose_arg(pose) -> str:
    return ",".join(repr(float(v)) for v in pose)


def reference_args(mesh_paths, pose, threshold, backend) -> list[str]:
    return [
        "--tool", str(mesh_paths["jaw_upper"]), "--tool-scale", "0.001",
        "--obstacle", str(mesh_paths["jaw_lower"]), "--obstacle-scale", "0.001",
        f"--obstacle-pose={pose_arg(IDENTITY)}",
        f"--pose={pose_arg(pose)}",
        f"--delta={DELTA!r}", f"--threshold={float(threshold)!r}",
        "--backend", backend,
        "--clusters", str(CLUSTERS),
        f"--stiffness={STIFFNESS!r}", f"--damping={DAMPING!r}", f"--mass={MASS!r}",
    ]


def python_pipeline(backend, tool: haptic.Mesh, pose, threshold) -> dict:
    """What the reference program does, through the Python API."""
    contacts, stats = backend.query(pose, delta=DELTA, threshold=threshold)
    clusterer = haptic.Clusterer(max_clusters=CLUSTERS, warm_start=True)
    reps = clusterer.cluster(contacts, delta=DELTA)
    volume = tool.mass_properties(1.0).volume_m3
    body = haptic.RigidBody.from_mass_properties(
        tool.mass_properties(density_kg_per_m3=MASS / volume)
    )
    model = haptic.PenaltyModel(
        stiffness_n_per_m=STIFFNESS, damping_ns_per_m=DAMPING, delta_m=DELTA
    )
    force, torque = model.wrench(body, pose, reps)
    return {
        "contacts": contacts,
        "stats": stats,
        "representatives": reps,
        "representative_weights": clusterer.representative_weights,
        "force": force,
        "torque": torque,
    }


CONTACT_KEYS = ("p_a", "r_a", "p_b", "n", "depth", "area", "feature_a", "feature_b")


def assert_same_contacts(ours: haptic.Contacts, theirs: dict, what: str) -> None:
    assert len(ours) == len(theirs["depth"]), f"{what}: {len(ours)} contacts in Python, " \
        f"{len(theirs['depth'])} in Rust"
    for key in CONTACT_KEYS:
        mine = getattr(ours, key)
        assert mine.dtype == theirs[key].dtype, f"{what}.{key}: dtype {mine.dtype}"
        assert mine.shape == theirs[key].shape, f"{what}.{key}: shape {mine.shape}"
        if not np.array_equal(mine, theirs[key]):
            bad = np.argwhere(mine != theirs[key])
            raise AssertionError(
                f"{what}.{key} differs from Rust at {len(bad)} places, first {bad[0].tolist()}: "
                f"{mine[tuple(bad[0])]!r} against {theirs[key][tuple(bad[0])]!r}"
            )


@pytest.fixture(scope="module")
def jaws_parry(jaws_meshes) -> haptic.ParryBackend:
    upper, lower = jaws_meshes
    return haptic.ParryBackend(upper, [(lower, IDENTITY)])


@pytest.mark.parametrize(
    "pose_name, threshold",
    [("occlusion", 0.025), ("occlusion", 0.0), ("slid", 0.025), ("random-a", 0.025),
     ("random-b", 0.004)],
)
def test_lod_query_matches_rust_bit_for_bit(
    jaws_meshes, jaws_lod, mesh_paths, rust_reference, pose_name, threshold
):
    pose = POSES[pose_name]
    upper, _ = jaws_meshes
    ours = python_pipeline(jaws_lod, upper, pose, threshold)
    assert len(ours["contacts"]) > 0, (
        f"no contact of the jaws at the {pose_name} pose within δ = {DELTA} m: the pose does "
        "not touch, pick another"
    )
    theirs = rust_reference(*reference_args(mesh_paths, pose, threshold, "lod"))
    assert_same_contacts(ours["contacts"], theirs, "contacts")
    assert_same_contacts(ours["representatives"], theirs["representatives"], "representatives")
    assert np.array_equal(ours["representative_weights"], theirs["representative_weights"])
    assert np.array_equal(ours["force"], theirs["force"]), (ours["force"], theirs["force"])
    assert np.array_equal(ours["torque"], theirs["torque"]), (ours["torque"], theirs["torque"])
    # In occlusion the lower jaw pushes the upper one up and away: a real force.
    assert np.linalg.norm(ours["force"]) > 0


def test_parry_query_matches_rust_bit_for_bit(jaws_meshes, jaws_parry, mesh_paths, rust_reference):
    upper, _ = jaws_meshes
    pose = POSES["occlusion"]
    ours = python_pipeline(jaws_parry, upper, pose, 0.0)
    assert len(ours["contacts"]) > 0, "parry finds no contact of the jaws in occlusion"
    theirs = rust_reference(*reference_args(mesh_paths, pose, 0.0, "parry"))
    assert_same_contacts(ours["contacts"], theirs, "contacts")
    assert_same_contacts(ours["representatives"], theirs["representatives"], "representatives")
    assert np.array_equal(ours["representative_weights"], theirs["representative_weights"])
    assert np.array_equal(ours["force"], theirs["force"])
    assert np.array_equal(ours["torque"], theirs["torque"])


def test_repeated_queries_are_identical(jaws_lod):
    a, _ = jaws_lod.query(POSES["slid"], delta=DELTA, threshold=0.025)
    jaws_lod.query(POSES["occlusion"], delta=DELTA, threshold=0.0)
    b, _ = jaws_lod.query(POSES["slid"], delta=DELTA, threshold=0.025)
    for key in CONTACT_KEYS:
        assert np.array_equal(getattr(a, key), getattr(b, key)), key


def test_coarser_threshold_gives_no_more_contacts(jaws_lod):
    """Fewer contacts found (before compaction), and both within the cap of compact contacts."""
    exact, exact_stats = jaws_lod.query(IDENTITY, delta=DELTA, threshold=0.0)
    coarse, coarse_stats = jaws_lod.query(IDENTITY, delta=DELTA, threshold=0.025)
    assert len(exact) > 0 and len(coarse) > 0
    assert 0 < coarse_stats.raw_contacts < exact_stats.raw_contacts
    assert max(len(exact), len(coarse)) <= 256
    assert exact_stats.broad_phase_hit and coarse_stats.broad_phase_hit
    assert exact_stats.primitive_pairs_tested >= coarse_stats.primitive_pairs_tested


def test_contacts_are_numpy_arrays(jaws_lod):
    pose = POSES["slid"]
    contacts, stats = jaws_lod.query(pose, delta=DELTA, threshold=0.025)
    k = len(contacts)
    assert k > 0
    for key in ("p_a", "r_a", "p_b", "n"):
        a = getattr(contacts, key)
        assert type(a) is np.ndarray, key
        assert a.dtype == np.float64 and a.shape == (k, 3), (key, a.dtype, a.shape)
        assert np.all(np.isfinite(a)), key
    for key, dtype in (
        ("depth", np.float64), ("area", np.float64), ("feature_a", np.uint32),
        ("feature_b", np.uint32),
    ):
        a = getattr(contacts, key)
        assert type(a) is np.ndarray, key
        assert a.dtype == dtype and a.shape == (k,), (key, a.dtype, a.shape)
    # What a contact means: unit normals, depths down to -δ, p_a the body point r_a placed at
    # the pose, p_b on the far side of the normal by the depth.
    assert np.allclose(np.linalg.norm(contacts.n, axis=1), 1.0, rtol=0, atol=1e-6)
    assert np.all(contacts.depth >= -DELTA * (1 + 1e-9))
    placed = pose[:3] + contacts.r_a @ rotation_matrix(pose[3:]).T
    assert np.allclose(contacts.p_a, placed, rtol=0, atol=1e-12)
    # Fresh copies: changing one changes nothing.
    p_a = contacts.p_a
    p_a[:] = 0.0
    assert not np.array_equal(contacts.p_a, p_a)
    # The statistics.
    assert isinstance(stats, haptic.QueryStats)
    assert stats.broad_phase_hit is True
    assert stats.node_pairs_tested > 0 and stats.primitive_pairs_tested > 0
    assert 0 < stats.time_s < 10


def test_contacts_are_compact_and_weighted_by_area(jaws_meshes, jaws_lod):
    # The jaws in occlusion at threshold 0: thousands of triangle pairs within δ, at most 256
    # contacts returned by default, every contact standing for some of the upper jaw's surface;
    # max_contacts=None returns them all, with the same total weight area * (depth + δ).
    upper, lower = jaws_meshes
    pose = POSES["occlusion"]
    compact, stats = jaws_lod.query(pose, delta=DELTA, threshold=0.0)
    assert 0 < len(compact) <= 256 < stats.raw_contacts
    assert np.all(compact.area > 0)
    everything = haptic.LodBackend(upper, [(lower, IDENTITY)], max_contacts=None)
    raw, raw_stats = everything.query(pose, delta=DELTA, threshold=0.0)
    assert len(raw) == stats.raw_contacts and raw_stats.raw_contacts == 0
    weight = lambda c: np.sum(c.area * np.maximum(c.depth + DELTA, 1e-3 * DELTA))
    assert weight(compact) == pytest.approx(weight(raw), rel=1e-9)
    assert compact.depth.max() == raw.depth.max()
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(compact.p_a, compact.r_a, compact.p_b, compact.n, compact.depth,
                        area=-compact.area)
    assert e.value.field == "area"


def test_free_space_query(jaws_lod):
    far = IDENTITY.copy()
    far[2] = 0.5
    contacts, stats = jaws_lod.query(far, delta=DELTA, threshold=0.025)
    assert len(contacts) == 0
    assert stats.broad_phase_hit is False
    assert contacts.p_a.shape == (0, 3) and contacts.p_a.dtype == np.float64
    assert contacts.depth.shape == (0,)
    assert contacts.feature_a.shape == (0,) and contacts.feature_a.dtype == np.uint32


def test_backend_properties(jaws_meshes, jaws_lod):
    upper, _ = jaws_meshes
    assert jaws_lod.node_count > 0
    radius = jaws_lod.tool_bounding_radius_m
    assert radius >= np.linalg.norm(upper.vertices, axis=1).max() * (1 - 1e-12)


# --- Contacts from arrays ---------------------------------------------------------------------


def contact_arrays(k: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    p_a = rng.normal(size=(k, 3)) * 0.01
    r_a = rng.normal(size=(k, 3)) * 0.01
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    depth = rng.uniform(-1e-3, 1e-3, size=k)
    p_b = p_a - depth[:, None] * n
    return p_a, r_a, p_b, n, depth


def test_contacts_from_arrays_round_trip():
    p_a, r_a, p_b, n, depth = contact_arrays(7)
    c = haptic.Contacts(p_a, r_a, p_b, n, depth)
    assert len(c) == 7
    assert np.array_equal(c.p_a, p_a) and np.array_equal(c.r_a, r_a)
    assert np.array_equal(c.p_b, p_b) and np.array_equal(c.n, n)
    assert np.array_equal(c.depth, depth)
    assert np.all(c.feature_a == NO_FEATURE) and np.all(c.feature_b == NO_FEATURE)
    assert c.feature_a.dtype == np.uint32
    f = haptic.Contacts(p_a, r_a, p_b, n, depth, feature_a=np.arange(7), feature_b=[3] * 7)
    assert np.array_equal(f.feature_a, np.arange(7)) and np.all(f.feature_b == 3)
    empty = haptic.Contacts(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
                            np.zeros((0, 3)), np.zeros(0))
    assert len(empty) == 0


def test_contacts_need_unit_normals():
    p_a, r_a, p_b, n, depth = contact_arrays(5)
    long = n.copy()
    long[3] *= 1.001
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(p_a, r_a, p_b, long, depth)
    assert e.value.field == "n"
    zero = n.copy()
    zero[0] = 0.0
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(p_a, r_a, p_b, zero, depth)
    assert e.value.field == "n"
    # Within 1e-6 of unit length is accepted.
    near = n * (1 + 5e-7)
    assert len(haptic.Contacts(p_a, r_a, p_b, near, depth)) == 5


def test_contacts_from_bad_arrays():
    p_a, r_a, p_b, n, depth = contact_arrays(5)
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(p_a, r_a[:4], p_b, n, depth)
    assert e.value.field == "r_a"
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(p_a, r_a, p_b, n, depth[:4])
    assert e.value.field == "depth"
    nan = p_b.copy()
    nan[2, 1] = np.nan
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(p_a, r_a, nan, n, depth)
    assert e.value.field == "p_b"
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(p_a[:, :2], r_a, p_b, n, depth)
    assert e.value.field == "p_a"
    with pytest.raises(haptic.InputError) as e:
        haptic.Contacts(p_a, r_a, p_b, n, np.full(5, np.inf))
    assert e.value.field == "depth"


# --- bad query arguments ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "pose",
    [
        [np.nan, 0, 0, 1, 0, 0, 0],
        [0, 0, 0, 1, 0, np.nan, 0],
        [0, np.inf, 0, 1, 0, 0, 0],
        [0, 0, 0, 1.01, 0, 0, 0],
        [0, 0, 0, 1, 2e-3, 0, 0],
        [0, 0, 0, 0, 0, 0, 0],
        [0, 0, 0, 1, 0, 0],
        [0, 0, 0, 1, 0, 0, 0, 0],
        [[0, 0, 0, 1, 0, 0, 0]],
        ["a", 0, 0, 1, 0, 0, 0],
    ],
    ids=["nan-position", "nan-quaternion", "inf", "norm-1.01", "norm-1+2e-6",
         "zero-quaternion", "six", "eight", "2d", "string"],
)
def test_bad_pose_is_an_input_error(jaws_lod, pose):
    with pytest.raises(haptic.InputError) as e:
        jaws_lod.query(pose, delta=DELTA, threshold=0.025)
    assert e.value.field == "pose"


def test_nearly_unit_quaternion_is_accepted(jaws_lod):
    # |q| - 1 = 5e-7: within the 1e-6 tolerance.
    pose = np.array([0, 0, 0, 1, 1e-3, 0, 0], dtype=np.float64)
    assert abs(np.linalg.norm(pose[3:]) - 1) < 1e-6
    contacts, stats = jaws_lod.query(pose, delta=DELTA, threshold=0.025)
    assert stats.broad_phase_hit and len(contacts) > 0


@pytest.mark.parametrize("delta", [0.0, -1e-3, float("nan"), float("inf")])
def test_bad_delta_is_an_input_error(jaws_lod, delta):
    with pytest.raises(haptic.InputError) as e:
        jaws_lod.query(IDENTITY, delta=delta, threshold=0.025)
    assert e.value.field == "delta"


@pytest.mark.parametrize("threshold", [-0.01, float("nan")])
def test_bad_threshold_is_an_input_error(jaws_lod, threshold):
    with pytest.raises(haptic.InputError) as e:
        jaws_lod.query(IDENTITY, delta=DELTA, threshold=threshold)
    assert e.value.field == "threshold"


@pytest.mark.parametrize("cls", [haptic.LodBackend, haptic.ParryBackend])
def test_bad_obstacles_are_input_errors(make_box, cls):
    tool = haptic.Mesh(*make_box([-0.01] * 3, [0.01] * 3))
    slab = haptic.Mesh(*make_box([-0.1, -0.1, -0.02], [0.1, 0.1, 0.0]))
    with pytest.raises(haptic.InputError) as e:
        cls(tool, [slab])
    assert e.value.field == "obstacles[0]"
    with pytest.raises(haptic.InputError) as e:
        cls(tool, [(slab, IDENTITY), (slab, [0, 0, 0, 1, 0, 0, np.nan])])
    assert e.value.field == "obstacles[1].pose"
    with pytest.raises(haptic.InputError) as e:
        cls(tool, 42)
    assert e.value.field == "obstacles"


def test_stopping_rule(jaws_meshes, jaws_lod, tmp_path):
    # Every rule gives the same contacts at threshold 0. Above it the coherence rule and the
    # budgeted one (the default) stop coarse pairs no earlier than the paper's rule: at least
    # its node pairs. The default is the budgeted rule; an unknown rule is refused.
    upper, lower = jaws_meshes

    def build(rule: str) -> haptic.LodBackend:
        return haptic.LodBackend(upper, [(lower, IDENTITY)], cache_dir=tmp_path, stopping_rule=rule)

    paper, coherent, budget = build("deviation"), build("coherence"), build("coherence-budget")
    pose = POSES["occlusion"]
    exact, _ = paper.query(pose, delta=DELTA, threshold=0.0)
    _, walked = paper.query(pose, delta=DELTA, threshold=0.025)
    for rule in (coherent, budget, jaws_lod):
        same, _ = rule.query(pose, delta=DELTA, threshold=0.0)
        assert np.array_equal(exact.p_a, same.p_a) and np.array_equal(exact.area, same.area)
        _, finer = rule.query(pose, delta=DELTA, threshold=0.025)
        assert finer.node_pairs_tested >= walked.node_pairs_tested
    default, _ = jaws_lod.query(pose, delta=DELTA, threshold=0.025)
    budgeted, _ = budget.query(pose, delta=DELTA, threshold=0.025)
    coarse, _ = paper.query(pose, delta=DELTA, threshold=0.025)
    assert np.array_equal(default.p_a, budgeted.p_a)
    assert len(default.area) != len(coarse.area) or not np.array_equal(default.area, coarse.area)
    # The threshold a query holds: the cap at delta binds above delta / radius, except under
    # the paper's rule.
    cap = DELTA / jaws_lod.tool_bounding_radius_m
    assert jaws_lod.threshold_reached(DELTA, 0.5 * cap) == 0.5 * cap
    assert jaws_lod.threshold_reached(DELTA, 0.1) == pytest.approx(cap, rel=1e-12)
    assert coherent.threshold_reached(DELTA, 0.1) == pytest.approx(cap, rel=1e-12)
    assert paper.threshold_reached(DELTA, 0.1) == 0.1
    with pytest.raises(haptic.InputError) as e:
        jaws_lod.threshold_reached(DELTA, -1.0)
    assert e.value.field == "threshold"
    with pytest.raises(haptic.InputError) as e:
        haptic.LodBackend(upper, [(lower, IDENTITY)], stopping_rule="normals")
    assert e.value.field == "stopping_rule"


def test_box_over_slab(make_box):
    """A 2 cm cube 0.5 mm above a slab, within δ = 1 mm: contacts of its bottom and of the strips
    of its sides within δ of the slab's top, normals down (out of the tool); the bottom's at
    -0.5 mm (apart), the sides' farther, on average."""
    tool = haptic.Mesh(*make_box([-0.01] * 3, [0.01] * 3))
    slab = haptic.Mesh(*make_box([-0.1, -0.1, -0.02], [0.1, 0.1, 0.0]))
    backend = haptic.LodBackend(tool, [(slab, IDENTITY)])
    pose = np.array([0.0, 0.0, 0.0105, 1.0, 0.0, 0.0, 0.0])
    contacts, stats = backend.query(pose, delta=DELTA, threshold=0.0)
    assert stats.broad_phase_hit and len(contacts) > 0
    assert np.allclose(contacts.n, [0.0, 0.0, -1.0], rtol=0, atol=1e-9)
    assert np.isclose(contacts.depth.max(), -5e-4, rtol=0, atol=1e-9)
    assert np.all((contacts.depth <= -5e-4 + 1e-9) & (contacts.depth >= -DELTA))
    assert np.allclose(contacts.p_b[:, 2], 0.0, rtol=0, atol=1e-12)
    assert np.allclose(contacts.p_a[:, 2], -contacts.depth, rtol=0, atol=1e-9)
    # Raised out of δ: nothing.
    pose[2] = 0.0125
    far, _ = backend.query(pose, delta=DELTA, threshold=0.0)
    assert len(far) == 0


def test_saved_hierarchies_are_read_back_and_answer_the_same(jaws_meshes, tmp_path):
    upper, lower = jaws_meshes
    obstacles = [(lower, IDENTITY)]
    first = haptic.LodBackend(upper, obstacles, cache_dir=tmp_path)
    assert [what for what, _ in first.cache_report] == ["built", "built"]
    second = haptic.LodBackend(upper, obstacles, cache_dir=tmp_path)
    assert [what for what, _ in second.cache_report] == ["loaded", "loaded"]
    a, _ = first.query(POSES["slid"], delta=DELTA, threshold=0.025)
    b, _ = second.query(POSES["slid"], delta=DELTA, threshold=0.025)
    assert len(a) > 0
    for key in CONTACT_KEYS:
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    # A file cut short is rebuilt and replaced, never used.
    _, path = second.cache_report[0]
    data = open(path, "rb").read()
    open(path, "wb").write(data[: len(data) // 3])
    third = haptic.LodBackend(upper, obstacles, cache_dir=tmp_path)
    assert third.cache_report[0][0].startswith("rebuilt: "), third.cache_report
    assert "cut short" in third.cache_report[0][0]
    assert haptic.LodBackend(upper, obstacles).cache_report == []
