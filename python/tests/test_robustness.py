"""Inputs that must give an exception, never a crash, a panic or a hang; exceptions that keep
their cause; and objects that several Python threads may use at once."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import haptic


def test_clusterer_sizes_beyond_any_use_are_errors():
    # These would reserve terabytes (an abort) or overflow (a panic) if they were taken.
    for kwargs, field in (({"max_clusters": 2**40}, "max_clusters"),
                          ({"max_clusters": 2**64 - 1}, "max_clusters"),
                          ({"max_iterations": 2**50}, "max_iterations")):
        with pytest.raises(haptic.ClusterError) as e:
            haptic.Clusterer(**kwargs)
        assert e.value.field == field, kwargs
    with pytest.raises(haptic.ClusterError) as e:
        haptic.Clusterer(max_clusters=0)
    assert e.value.field == "max_clusters"


@pytest.mark.parametrize("seconds", [1e7, 1e300])
def test_a_run_too_long_to_record_is_an_input_error(spoon_cup, seconds):
    with pytest.raises(haptic.InputError) as e:
        haptic.run_virtual(spoon_cup, seconds)
    assert e.value.field == "seconds"


@pytest.mark.parametrize("rate", [1e-300, 0.5, 1e9])
def test_a_haptic_rate_out_of_range_is_a_scene_error(make_box, rate):
    v, t = make_box([-0.01] * 3, [0.01] * 3)
    with pytest.raises(haptic.SceneError) as e:
        haptic.Scene.from_parts(tool=haptic.Mesh(v, t), mass_kg=0.1, haptic_rate_hz=rate)
    assert e.value.field == "rates.haptic_hz"


def test_a_callable_that_raises_at_once_keeps_its_cause(spoon_cup):
    def device(t):
        raise ValueError("no handle here")

    with pytest.raises(haptic.PipelineError) as e:
        haptic.run_virtual(spoon_cup, 0.1, device=device)
    assert isinstance(e.value.__cause__, ValueError)
    assert e.value.field == "device"


def test_keyboard_interrupt_from_a_callable_is_not_wrapped(spoon_cup):
    p0 = spoon_cup.tool_pose

    def device(t):
        if t > 0.05:
            raise KeyboardInterrupt
        return p0

    with pytest.raises(KeyboardInterrupt):
        haptic.run_virtual(spoon_cup, 0.2, device=device)


def test_a_non_finite_first_reading_is_a_device_error(spoon_cup):
    with pytest.raises(haptic.DeviceError) as e:
        haptic.run_virtual(spoon_cup, 0.1, device=lambda t: np.full(7, np.nan))
    assert e.value.field == "device"
    assert e.value.kind == "invalid_data"


def test_a_tool_too_large_for_the_hierarchy_is_a_collision_error():
    # A mesh whose every vertex is NaN-free but whose obstacle pose is not finite is refused by
    # the input checks; a bad pose at query time is the back-end's own error.
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64) * 0.01
    t = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    tet = haptic.Mesh(v, t)
    lod = haptic.LodBackend(tet, [(tet, [0.1, 0, 0, 1, 0, 0, 0])])
    with pytest.raises(haptic.InputError) as e:
        lod.query([np.inf, 0, 0, 1, 0, 0, 0], delta=1e-3)
    assert e.value.field == "pose"
    # The same contacts from both back-ends' errors path: a threshold out of range.
    with pytest.raises(haptic.InputError) as e:
        lod.query([0, 0, 0, 1, 0, 0, 0], delta=1e-3, threshold=-1.0)
    assert e.value.field == "threshold"


@pytest.mark.parametrize("bad", [
    np.zeros((4, 3), dtype=complex),
    np.zeros((4, 3), dtype=bool),
    np.array([["a", "b", "c"]] * 4),
    [[0, 0, 0], [1, 0]],
])
def test_arrays_that_are_not_real_numbers_are_input_errors(bad):
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(bad, [[0, 1, 2]])
    assert e.value.field == "vertices"


def test_rigid_body_errors_name_their_field():
    with pytest.raises(haptic.InputError) as e:
        haptic.RigidBody(float("nan"), np.eye(3) * 1e-3)
    assert e.value.field == "mass_kg"
    for mass in (0.0, -1.0):
        with pytest.raises(haptic.DynamicsError) as e:
            haptic.RigidBody(mass, np.eye(3) * 1e-3)
        assert e.value.field == "mass_kg"
    with pytest.raises(haptic.DynamicsError) as e:  # not positive definite
        haptic.RigidBody(1.0, -np.eye(3))
    assert e.value.field == "inertia_kg_m2"
    with pytest.raises(haptic.InputError) as e:
        haptic.RigidBody(1.0, np.eye(4))
    assert e.value.field == "inertia_kg_m2" and "(3, 3)" in str(e.value)


def test_one_backend_serves_several_threads(jaws_lod):
    pose = np.array([0, 0, 0, 1, 0, 0, 0], dtype=np.float64)
    expected, _ = jaws_lod.query(pose, delta=1e-3, threshold=0.025)
    errors, counts = [], []

    def work():
        try:
            for _ in range(10):
                c, _ = jaws_lod.query(pose, delta=1e-3, threshold=0.025)
                counts.append(len(c))
                assert jaws_lod.node_count > 0
        except Exception as e:  # noqa: BLE001 - any failure is the test's failure
            errors.append(e)

    threads = [threading.Thread(target=work) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert counts == [len(expected)] * 30


def test_one_clusterer_serves_several_threads(jaws_lod):
    contacts, _ = jaws_lod.query([0, 0, 0, 1, 0, 0, 0], delta=1e-3, threshold=0.0)
    clusterer = haptic.Clusterer(max_clusters=5, warm_start=False)
    errors = []

    def work():
        try:
            for _ in range(5):
                assert len(clusterer.cluster(contacts, 1e-3)) == 10  # five torque pairs
        except Exception as e:  # noqa: BLE001
            errors.append(e)

    threads = [threading.Thread(target=work) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []


def test_force_server_twist_shape_is_checked(spoon_cup):
    with haptic.ForceServer(spoon_cup) as server:
        with pytest.raises(haptic.InputError) as e:
            server.set_device_pose(spoon_cup.tool_pose, twist=[0, 0, 0])
        assert e.value.field == "twist"
        server.set_device_pose(spoon_cup.tool_pose, twist=np.zeros(6))
        assert np.all(np.isfinite(server.tool_pose()))
