"""Real time from Python: the demo's real-time run, and the force server a slower simulator
drives (the haptic loop at 1 kHz in the background, the handle's pose set from Python)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

import haptic

MAX_FORCE_N = 10.0
MAX_TORQUE_NM = 1.0
STATS_KEYS = {"steps", "time_s", "haptic_rate_hz", "contact_updates", "raw_contact_count",
              "cluster_count", "max_force_n", "running"}


def test_run_realtime(spoon_cup):
    result = haptic.run_realtime(spoon_cup, 0.5)
    assert isinstance(result, haptic.RealtimeResult)
    s = result.summary
    assert isinstance(s, dict)
    assert s["mode"] == "real-time"
    assert s["haptic_rate_hz"] == pytest.approx(1000.0, rel=0.05)
    assert s["haptic_steps"] == pytest.approx(500, rel=0.05)
    assert s["contact_updates"] > 0
    assert 0.0 <= s["max_force_n"] <= MAX_FORCE_N
    assert s["zero_force_steps"] == 0
    assert isinstance(result.summary_text, str)
    assert "haptic" in result.summary_text
    assert "real-time" in result.summary_text and "scheduling" in result.summary_text


def test_force_server_follows_a_handle_from_python(spoon_cup):
    p0 = spoon_cup.tool_pose.copy()
    server = haptic.ForceServer(spoon_cup)
    assert server.summary is None
    server.start()
    try:
        first = server.stats()
        assert STATS_KEYS <= set(first), set(first)
        assert first["running"] is True
        rate_hz, seconds = 200.0, 0.5
        n = int(rate_hz * seconds)
        forces, torques, steps = [], [], []
        start = time.perf_counter()
        for k in range(n):
            # 2 cm straight down, in free space above the cup.
            pose = p0.copy()
            pose[1] -= 0.02 * 0.5 * (1 - math.cos(math.pi * k / (n - 1)))
            server.set_device_pose(pose)
            force, torque = server.wrench()
            assert force.shape == (3,) and torque.shape == (3,)
            assert force.dtype == np.float64 and torque.dtype == np.float64
            forces.append(force)
            torques.append(torque)
            steps.append(server.stats()["steps"])
            delay = start + (k + 1) / rate_hz - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        forces, torques = np.array(forces), np.array(torques)
        assert np.all(np.isfinite(forces)) and np.all(np.isfinite(torques))
        assert np.linalg.norm(forces, axis=1).max() <= MAX_FORCE_N * (1 + 1e-12)
        assert np.linalg.norm(torques, axis=1).max() <= MAX_TORQUE_NM * (1 + 1e-12)
        assert np.linalg.norm(forces, axis=1).max() > 0.0, "the moving handle felt no coupling"
        assert np.all(np.diff(steps) >= 0)
        assert steps[-1] - steps[0] > 0.8 * 1000 * seconds * (n - 1) / n
        time.sleep(0.3)  # the tool settles on the handle; the live figures follow within 0.1 s
        tool = server.tool_pose()
        assert tool.shape == (7,) and np.all(np.isfinite(tool))
        assert abs(tool[1] - (p0[1] - 0.02)) < 2e-3, tool
        stats = server.stats()
        assert stats["steps"] > steps[-1]
        assert stats["haptic_rate_hz"] == pytest.approx(1000.0, rel=0.1)
        assert stats["time_s"] > seconds
        assert stats["contact_updates"] > 0
        assert stats["max_force_n"] >= np.linalg.norm(forces, axis=1).max() * (1 - 1e-12)
    finally:
        summary = server.stop()
    assert isinstance(summary, dict)
    assert summary["mode"] == "real-time"
    assert summary["haptic_steps"] >= stats["steps"]
    assert summary["haptic_rate_hz"] == pytest.approx(1000.0, rel=0.05)
    assert server.summary == summary
    # A stopped server takes no more poses.
    with pytest.raises(haptic.HapticError):
        server.set_device_pose(p0)


def test_force_server_as_a_context_manager(spoon_cup):
    p0 = spoon_cup.tool_pose.copy()
    with haptic.ForceServer(spoon_cup, integrator="backward_euler", backend="lod") as server:
        assert server.stats()["running"] is True
        server.set_device_pose(p0)
        time.sleep(0.35)  # the live figures are updated ten times a second
        assert server.stats()["steps"] > 100
        assert server.summary is None
    assert isinstance(server.summary, dict)
    assert server.summary["haptic_steps"] > 100
    with pytest.raises(haptic.HapticError):
        server.set_device_pose(p0)


def test_force_server_renders_the_cup_wall(spoon_cup):
    """The scene's motion from Python: down into the cup, then sideways into its wall."""
    p0 = spoon_cup.tool_pose.copy()
    rate_hz = 200.0
    with haptic.ForceServer(spoon_cup) as server:
        start = time.perf_counter()
        peak = 0.0
        for k in range(int(2.5 * rate_hz)):
            t = k / rate_hz
            down = min(t / 1.0, 1.0)
            side = min(max(t - 1.0, 0.0) / 1.0, 1.0)
            pose = p0.copy()
            pose[1] = 0.185 - 0.07 * (down * down * (3 - 2 * down))
            pose[0] = 0.035 * (side * side * (3 - 2 * side))
            server.set_device_pose(pose)
            force, _ = server.wrench()
            peak = max(peak, float(np.linalg.norm(force)))
            delay = start + (k + 1) / rate_hz - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        stats = server.stats()
    assert stats["raw_contact_count"] > 0, "the spoon does not touch the cup at the end"
    assert peak > 1.0, f"the cup wall pushed back with {peak:.2f} N at most"
    assert server.summary["raw_contact_count_max"] > 0
    assert server.summary["max_force_n"] <= MAX_FORCE_N


@pytest.mark.parametrize(
    "pose",
    [[0, 0.185, 0, 0, 1, 0, np.nan], [np.inf, 0.185, 0, 0, 1, 0, 0], [0, 0.185, 0, 0, 2, 0, 0],
     [0, 0.185, 0, 0, 1, 0]],
)
def test_force_server_rejects_bad_poses(spoon_cup, pose):
    with haptic.ForceServer(spoon_cup) as server:
        with pytest.raises(haptic.InputError) as e:
            server.set_device_pose(pose)
        assert e.value.field == "pose"
        assert server.stats()["running"] is True
        assert np.all(np.isfinite(server.tool_pose()))


def test_force_server_bad_arguments(spoon_cup):
    with pytest.raises(haptic.InputError) as e:
        haptic.ForceServer(spoon_cup, integrator="verlet")
    assert e.value.field == "integrator"
    with pytest.raises(haptic.InputError) as e:
        haptic.ForceServer(spoon_cup, backend="bullet")
    assert e.value.field == "backend"
