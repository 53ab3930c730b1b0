"""The pipeline in virtual time from Python: telemetry arrays, determinism, the same summary as
`cargo xtask demo --virtual-time`, devices given as poses over time or as a callable, scenes from
parts, and the errors of bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

import haptic

MAX_FORCE_N = 10.0  # xtask/scenes/spoon-cup.toml: the device's default limits
MAX_TORQUE_NM = 1.0

# The summary fields that do not depend on the wall clock: in virtual time they must be the same
# in Python as in the demo, exactly.
DETERMINISTIC_KEYS = (
    "mode",
    "duration_s",
    "haptic_steps",
    "contact_updates",
    "broad_phase_only_queries",
    "raw_contact_count_max",
    "cluster_count_max",
    "max_penetration_m",
    "max_coupling_deviation_m",
    "max_force_n",
    "saturation_events",
    "zero_force_steps",
    "solver_failures",
    "solver_fallbacks",
    "contact_errors",
    "contact_stale_steps",
)

RUN_ARRAYS = ("t", "tool_pose", "device_pose", "force", "torque", "raw_contact_count",
              "cluster_count", "penetration_m")


@pytest.fixture(scope="module")
def half_second(spoon_cup) -> haptic.Run:
    return haptic.run_virtual(spoon_cup, 0.5)


def check_run_arrays(run: haptic.Run, n: int, dt: float = 1e-3) -> None:
    assert isinstance(run, haptic.Run)
    shapes = {
        "t": ((n,), np.float64), "tool_pose": ((n, 7), np.float64),
        "device_pose": ((n, 7), np.float64), "force": ((n, 3), np.float64),
        "torque": ((n, 3), np.float64), "raw_contact_count": ((n,), np.int64),
        "cluster_count": ((n,), np.int64), "penetration_m": ((n,), np.float64),
    }
    for name, (shape, dtype) in shapes.items():
        a = getattr(run, name)
        assert type(a) is np.ndarray, name
        assert a.shape == shape and a.dtype == dtype, (name, a.shape, a.dtype)
    assert np.allclose(np.diff(run.t), dt, rtol=0, atol=1e-12)
    assert 0.0 <= run.t[0] <= dt


def test_run_virtual_telemetry(spoon_cup, half_second):
    run = half_second
    check_run_arrays(run, 500)
    for name in ("t", "tool_pose", "device_pose", "force", "torque", "penetration_m"):
        assert np.all(np.isfinite(getattr(run, name))), name
    assert np.allclose(np.linalg.norm(run.tool_pose[:, 3:], axis=1), 1.0, atol=1e-9)
    assert np.allclose(np.linalg.norm(run.device_pose[:, 3:], axis=1), 1.0, atol=1e-9)
    force_norm = np.linalg.norm(run.force, axis=1)
    assert force_norm.max() <= MAX_FORCE_N * (1 + 1e-12)
    assert np.linalg.norm(run.torque, axis=1).max() <= MAX_TORQUE_NM * (1 + 1e-12)
    assert np.all(run.raw_contact_count >= 0)
    assert np.all(run.cluster_count <= np.minimum(run.raw_contact_count, 5))
    assert np.all(run.penetration_m >= 0)
    # The hand starts where the tool is and lowers it: by t = 0.5 s the minimum-jerk target is
    # halfway down (3.5 cm) and both the handle and the tool have followed.
    assert np.allclose(run.tool_pose[0, :3], spoon_cup.tool_pose[:3], atol=1e-3)
    assert run.device_pose[-1, 1] < run.device_pose[0, 1] - 0.02
    assert run.tool_pose[-1, 1] < run.tool_pose[0, 1] - 0.02
    # The summary agrees with the series.
    s = run.summary
    assert isinstance(s, dict)
    assert s["mode"] == "virtual-time"
    assert s["haptic_steps"] == 500
    assert s["max_force_n"] == pytest.approx(force_norm.max(), rel=1e-12, abs=1e-15)
    assert s["raw_contact_count_max"] >= run.raw_contact_count.max()
    assert s["cluster_count_max"] >= run.cluster_count.max()
    assert isinstance(run.summary_text, str)
    assert "haptic loop" in run.summary_text and "virtual-time" in run.summary_text
    assert f"{s['contact_updates']} updates" in run.summary_text


def test_run_virtual_is_deterministic(spoon_cup, half_second):
    again = haptic.run_virtual(spoon_cup, 0.5)
    for name in RUN_ARRAYS:
        assert np.array_equal(getattr(again, name), getattr(half_second, name)), name
    for key in DETERMINISTIC_KEYS:
        assert again.summary[key] == half_second.summary[key], key


@pytest.mark.parametrize("seconds", [0.5, 2.5])
def test_summary_matches_the_rust_demo(spoon_cup, rust_demo, seconds):
    run = haptic.run_virtual(spoon_cup, seconds)
    demo = rust_demo(seconds)
    if seconds > 2:
        assert demo["raw_contact_count_max"] > 0, "the spoon never touched the cup by 2.5 s"
    assert run.summary["haptic_steps"] == demo["haptic_steps"] == round(seconds * 1000)
    for key in DETERMINISTIC_KEYS:
        assert run.summary[key] == demo[key], f"{key}: Python {run.summary[key]!r}, " \
            f"demo {demo[key]!r}"


def test_integrators_and_backends(spoon_cup):
    runs = {}
    for name in ("backward_euler", "linearized_backward_euler", "newton_backward_euler", "rk4",
                 "forward_euler"):
        run = haptic.run_virtual(spoon_cup, 0.2, integrator=name)
        check_run_arrays(run, 200)
        assert np.all(np.isfinite(run.tool_pose)) and np.all(np.isfinite(run.force)), name
        runs[name] = run
    # The alias is the same integrator; the others are other integrators.
    for key in RUN_ARRAYS:
        assert np.array_equal(getattr(runs["backward_euler"], key),
                              getattr(runs["linearized_backward_euler"], key)), key
    # In free space the coupling is linear in position: Newton's backward Euler converges to
    # the linearized step; the explicit methods differ from it.
    assert np.allclose(runs["newton_backward_euler"].tool_pose, runs["backward_euler"].tool_pose,
                       atol=1e-9)
    for name in ("rk4", "forward_euler"):
        assert not np.array_equal(runs[name].tool_pose, runs["backward_euler"].tool_pose), name
    parry = haptic.run_virtual(spoon_cup, 0.2, backend="parry")
    check_run_arrays(parry, 200)
    assert np.all(np.isfinite(parry.force))


def test_contact_rate(spoon_cup):
    default = haptic.run_virtual(spoon_cup, 0.2)
    assert default.summary["contact_updates"] == pytest.approx(0.2 * 250, abs=2)
    fast = haptic.run_virtual(spoon_cup, 0.2, contact_rate_hz=1000.0)
    assert fast.summary["contact_updates"] == pytest.approx(0.2 * 1000, abs=2)


# --- devices ----------------------------------------------------------------------------------


def test_device_as_poses_over_time(spoon_cup):
    p0 = spoon_cup.tool_pose.copy()
    p1 = p0.copy()
    p1[1] -= 0.01
    times = np.array([0.0, 0.2, 0.4])
    poses = np.vstack([p0, p1, p1])
    run = haptic.run_virtual(spoon_cup, 0.4, device=(times, poses))
    check_run_arrays(run, 400)
    assert np.allclose(run.device_pose[0], p0, atol=1e-9)
    i = int(np.argmin(np.abs(run.t - 0.2)))
    assert abs(run.t[i] - 0.2) < 1e-9
    assert np.allclose(run.device_pose[i], p1, atol=1e-9)
    assert np.allclose(run.device_pose[-1], p1, atol=1e-9)
    # The scripted handle, not the scene's hand (which would be 2 cm lower by now); the tool
    # followed it.
    assert abs(run.tool_pose[-1, 1] - p1[1]) < 2e-3
    # Lists work too.
    listed = haptic.run_virtual(spoon_cup, 0.4, device=(times.tolist(), poses.tolist()))
    assert np.array_equal(listed.device_pose, run.device_pose)


def test_device_as_a_callable(spoon_cup):
    p0 = spoon_cup.tool_pose.copy()
    calls: list[float] = []
    returned_y: list[float] = []

    def handle(t: float) -> np.ndarray:
        calls.append(t)
        p = p0.copy()
        p[1] -= 0.02 * t
        returned_y.append(p[1])
        return p

    run = haptic.run_virtual(spoon_cup, 0.3, device=handle)
    check_run_arrays(run, 300)
    assert len(calls) >= 300
    assert min(calls) >= 0.0 and max(calls) <= 0.3
    assert np.all(np.isin(run.device_pose[:, 1], returned_y)), "a pose the callable did not give"
    assert np.all(np.diff(run.device_pose[:, 1]) <= 0)
    assert np.allclose(run.device_pose[:, 1], p0[1] - 0.02 * run.t, rtol=0, atol=0.02e-3 + 1e-12)
    # Any sequence of 7 floats will do.
    as_list = haptic.run_virtual(spoon_cup, 0.05, device=lambda t: p0.tolist())
    assert np.allclose(as_list.device_pose, p0, atol=1e-12)


def test_a_callable_that_raises_stops_the_run(spoon_cup):
    p0 = spoon_cup.tool_pose.copy()

    class Boom(RuntimeError):
        pass

    def handle(t: float) -> np.ndarray:
        if t >= 0.1:
            raise Boom("boom-4711 from the device callable")
        return p0

    with pytest.raises(haptic.PipelineError) as e:
        haptic.run_virtual(spoon_cup, 0.5, device=handle)
    err = e.value
    assert isinstance(err.__cause__, Boom) or "boom-4711" in str(err), err
    assert isinstance(err.summary, dict)
    assert 95 <= err.summary["haptic_steps"] <= 105


def test_a_callable_returning_nan_gives_zero_force_steps(spoon_cup):
    p0 = spoon_cup.tool_pose.copy()

    def handle(t: float) -> np.ndarray:
        p = p0.copy()
        p[1] -= 0.05 * t  # moving, so that the coupling sends some force
        if 0.1 <= t < 0.15:
            p[0] = np.nan
        return p

    run = haptic.run_virtual(spoon_cup, 0.3, device=handle)
    check_run_arrays(run, 300)
    assert 45 <= run.summary["zero_force_steps"] <= 55
    bad = (run.t >= 0.1 + 1e-9) & (run.t < 0.15 - 1e-9)
    assert np.all(run.force[bad] == 0.0) and np.all(run.torque[bad] == 0.0)
    assert np.any(run.force[~bad] != 0.0)
    assert np.all(np.isfinite(run.tool_pose))


def test_bad_device_arguments(spoon_cup):
    p0 = spoon_cup.tool_pose
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, 0.1, device=([0.0, 1.0], np.vstack([p0, p0])[:, :6]))
    assert e.value.field.startswith("device")
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, 0.1, device=([0.0, 1.0, 2.0], np.vstack([p0, p0])))
    assert e.value.field.startswith("device")
    nan = np.vstack([p0, p0])
    nan[1, 2] = np.nan
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, 0.1, device=([0.0, 1.0], nan))
    assert e.value.field.startswith("device")
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, 0.1, device=42)
    assert e.value.field.startswith("device")


# --- scenes -----------------------------------------------------------------------------------


def test_scene_file_reads_back(spoon_cup, jaws_scene_path):
    assert spoon_cup.name == "spoon into cup"
    assert spoon_cup.mass_kg == 0.02
    assert spoon_cup.haptic_rate_hz == 1000.0
    assert spoon_cup.contact_rate_hz == 250.0
    assert spoon_cup.delta_m == 1e-3
    pose = spoon_cup.tool_pose
    assert pose.shape == (7,) and pose.dtype == np.float64
    assert np.allclose(pose[:3], [0.0, 0.185, 0.0], atol=1e-15)
    assert np.allclose(np.abs(pose[3:]), [0.0, 1.0, 0.0, 0.0], atol=1e-12)  # π about x
    # The tool mesh is in its body frame: its centre of mass at the origin.
    com = spoon_cup.tool_mesh.mass_properties(1000.0).centre_of_mass_m
    assert np.allclose(com, 0.0, atol=1e-12)
    jaws = haptic.Scene.load(str(jaws_scene_path))
    assert jaws.name == "jaws in occlusion"
    assert jaws.contact_rate_hz == 200.0 and jaws.mass_kg == 0.01


def test_scene_from_parts_box_pressed_on_a_slab(make_box):
    tool = haptic.Mesh(*make_box([-0.02] * 3, [0.02] * 3))  # a 4 cm cube
    slab = haptic.Mesh(*make_box([-0.2, -0.2, -0.02], [0.2, 0.2, 0.0]))  # its top at z = 0
    start = np.array([0.0, 0.0, 0.03, 1.0, 0.0, 0.0, 0.0])  # 1 cm above the slab
    pressed = start.copy()
    pressed[2] = 0.0  # the hand aims 2 cm below where the slab stops the cube
    scene = haptic.Scene.from_parts(
        tool=tool, mass_kg=0.05, tool_pose=start,
        obstacles=[(slab, [0, 0, 0, 1, 0, 0, 0])], name="box on slab",
        waypoints=([0.0, 0.2, 0.6], np.vstack([start, start, pressed])),
    )
    assert scene.name == "box on slab"
    assert scene.mass_kg == 0.05
    assert np.allclose(scene.tool_pose, start, atol=1e-15)
    assert scene.haptic_rate_hz == 1000.0 and scene.contact_rate_hz is None
    assert scene.delta_m == 1e-3
    assert np.allclose(scene.tool_mesh.vertices, tool.vertices, atol=1e-15)

    run = haptic.run_virtual(scene, 1.0)
    check_run_arrays(run, 1000)
    early = run.t < 0.15
    late = run.t > 0.9
    assert np.all(run.raw_contact_count[early] == 0)
    assert np.all(run.raw_contact_count[late] > 0)
    assert np.linalg.norm(run.force[early], axis=1).max() < 0.2
    # Pressed down, the handle is pushed back up: hand 300 N/m in series with the 200 N/m
    # coupling over 2 cm, about 2.4 N.
    assert run.force[late, 2].mean() > 1.0
    assert run.force[late, 2].min() > 0.0
    assert run.force[late, 2].mean() > 5 * np.linalg.norm(run.force[early], axis=1).mean()
    # The slab holds the cube up; the handle went below it.
    assert run.tool_pose[late, 2].min() > 0.02 - 2e-3
    assert np.all(run.device_pose[late, 2] < run.tool_pose[late, 2] - 5e-3)
    assert run.summary["max_force_n"] <= 10.0 and run.summary["raw_contact_count_max"] > 0


def test_scene_from_parts_contact_models_between_updates(make_box):
    """`fixed_frames` (the default) and the paper's tangents both hold the cube on the slab with
    contact updates at 300 Hz, and are different models; `linearized=False` holds the forces
    between updates, and the cube bounces."""
    tool = haptic.Mesh(*make_box([-0.02] * 3, [0.02] * 3))
    slab = haptic.Mesh(*make_box([-0.2, -0.2, -0.02], [0.2, 0.2, 0.0]))
    start = np.array([0.0, 0.0, 0.03, 1.0, 0.0, 0.0, 0.0])
    pressed = start.copy()
    pressed[2] = 0.0
    common = dict(
        tool=tool, mass_kg=0.05, tool_pose=start, obstacles=[(slab, [0, 0, 0, 1, 0, 0, 0])],
        waypoints=([0.0, 0.2, 0.6], np.vstack([start, start, pressed])), contact_rate_hz=300.0,
    )
    runs = {
        name: haptic.run_virtual(haptic.Scene.from_parts(**common, **kw), 0.8)
        for name, kw in {
            "fixed_frames": {},
            "tangents": {"fixed_frames": False},
            "constant": {"linearized": False},
        }.items()
    }
    default = haptic.run_virtual(haptic.Scene.from_parts(**common, fixed_frames=True), 0.8)
    assert np.array_equal(default.tool_pose, runs["fixed_frames"].tool_pose)
    # The stopping rule is the LOD back-end's: at threshold 0 both rules give the same run.
    coherent = haptic.run_virtual(haptic.Scene.from_parts(**common, stopping_rule="coherence"), 0.8)
    assert np.array_equal(coherent.tool_pose, runs["fixed_frames"].tool_pose)
    late = runs["tangents"].t > 0.7
    for name in ("fixed_frames", "tangents"):
        run = runs[name]
        assert run.summary["zero_force_steps"] == 0, name
        assert run.tool_pose[late, 2].min() > 0.02 - 2e-3, name  # held up by the slab
        assert run.force[late, 2].mean() > 1.0, name
    assert not np.array_equal(runs["fixed_frames"].tool_pose, runs["tangents"].tool_pose)
    # Held constant between updates, the cube is not held (the paper's ablation).
    heights = {name: np.ptp(run.tool_pose[late, 2]) for name, run in runs.items()}
    assert heights["constant"] > 10 * max(heights["fixed_frames"], heights["tangents"]), heights


def test_scene_errors(tmp_path, mesh_paths, make_box):
    with pytest.raises(haptic.SceneError):
        haptic.Scene.load(tmp_path / "missing.toml")
    bad_mass = tmp_path / "bad-mass.toml"
    bad_mass.write_text(
        f'name = "bad"\n[tool]\nmesh = "{mesh_paths["teaspoon"].as_posix()}"\nmass_kg = -1.0\n'
    )
    with pytest.raises(haptic.SceneError) as e:
        haptic.Scene.load(bad_mass)
    assert e.value.field == "tool.mass_kg"
    unknown = tmp_path / "unknown-field.toml"
    unknown.write_text(
        f'[tool]\nmesh = "{mesh_paths["teaspoon"].as_posix()}"\nmass_kg = 0.02\nmass_g = 20\n'
    )
    with pytest.raises(haptic.SceneError):
        haptic.Scene.load(unknown)
    no_mesh = tmp_path / "no-mesh.toml"
    no_mesh.write_text('[tool]\nmesh = "nowhere.stl"\nmass_kg = 0.02\n')
    with pytest.raises(haptic.SceneError) as e:
        haptic.Scene.load(no_mesh)
    assert e.value.field == "tool.mesh"
    tool = haptic.Mesh(*make_box([-0.02] * 3, [0.02] * 3))
    with pytest.raises(haptic.SceneError) as e:
        haptic.Scene.from_parts(tool=tool, mass_kg=0.0)
    assert e.value.field == "tool.mass_kg"
    with pytest.raises(haptic.SceneError) as e:
        haptic.Scene.from_parts(tool=tool, mass_kg=0.05, clusters=0)
    assert e.value.field == "contact.clusters"
    with pytest.raises(haptic.InputError) as e:
        haptic.Scene.from_parts(tool=tool, mass_kg=0.05, tool_pose=[0, 0, 0, 2, 0, 0, 0])
    assert e.value.field == "tool_pose"
    with pytest.raises(haptic.InputError) as e:
        haptic.Scene.from_parts(tool=tool, mass_kg=0.05, stopping_rule="normals")
    assert e.value.field == "stopping_rule"
    bad_rule = tmp_path / "bad-rule.toml"
    bad_rule.write_text(
        f'[tool]\nmesh = "{mesh_paths["teaspoon"].as_posix()}"\nmass_kg = 0.02\n'
        '[contact]\nstopping_rule = "normals"\n'
    )
    with pytest.raises(haptic.SceneError):
        haptic.Scene.load(bad_rule)


# --- bad run arguments ------------------------------------------------------------------------


def test_bad_run_arguments(spoon_cup):
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, 0.1, integrator="verlet")
    assert e.value.field == "integrator"
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, 0.1, backend="bullet")
    assert e.value.field == "backend"
    for seconds in (-1.0, float("nan"), float("inf")):
        with pytest.raises(haptic.InputError) as e:
            haptic.run_virtual(spoon_cup, seconds)
        assert e.value.field == "seconds"
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, 0.1, contact_rate_hz=0.0)
    assert e.value.field == "contact_rate_hz"
    with pytest.raises(haptic.InputError) as e:
        haptic.run_realtime(spoon_cup, -1.0)
    assert e.value.field == "seconds"
    with pytest.raises(haptic.InputError) as e:
        haptic.run_realtime(spoon_cup, 0.1, integrator="verlet")
    assert e.value.field == "integrator"


def test_a_time_budget_picks_the_threshold(make_box):
    v, t = make_box([-0.01] * 3, [0.01] * 3)
    slab_v, slab_t = make_box([-0.05, -0.05, -0.01], [0.05, 0.05, 0.0])
    times = np.array([0.0, 0.3])
    poses = np.array([[0, 0, 0.011, 1, 0, 0, 0], [0, 0, 0.0095, 1, 0, 0, 0]], dtype=np.float64)
    common = dict(tool=haptic.Mesh(v, t), mass_kg=0.1, tool_pose=poses[0],
                  obstacles=[(haptic.Mesh(slab_v, slab_t), [0, 0, 0, 1, 0, 0, 0])],
                  waypoints=(times, poses), error_threshold=0.05)
    # A nanosecond fits no update: the threshold climbs past the scene's 5 % to the coarsest the
    # back-end reaches: under the default rule, whose pieces never stray beyond delta, delta over
    # the cube's radius (1 mm / 17.3 mm); under the paper's rule, the budget's ceiling (10 %).
    scene = haptic.Scene.from_parts(time_budget_s=1e-9, **common)
    run = haptic.run_virtual(scene, 0.5)
    assert run.summary["raw_contact_count_max"] > 0
    assert run.summary["error_threshold_max"] == pytest.approx(1e-3 / (0.01 * np.sqrt(3.0)))
    paper = haptic.Scene.from_parts(time_budget_s=1e-9, stopping_rule="deviation", **common)
    assert haptic.run_virtual(paper, 0.5).summary["error_threshold_max"] == pytest.approx(0.1)
    # Without a budget, the scene's threshold.
    fixed = haptic.run_virtual(haptic.Scene.from_parts(**common), 0.5)
    assert fixed.summary["error_threshold_median"] == pytest.approx(0.05)
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(scene, 0.1, backend="parry")
    assert e.value.field == "backend"
    with pytest.raises(haptic.SceneError) as e:
        haptic.Scene.from_parts(time_budget_s=-1.0, **common)
    assert e.value.field == "contact.time_budget_s"
