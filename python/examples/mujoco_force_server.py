#!/usr/bin/env python3
"""Haptic contact forces for a simulator that runs slower than the hand: MuJoCo at 200 Hz, haptic
at 1 kHz.

A MuJoCo model holds one free-floating body, the "handle": the device of haptic's virtual tool.
A simulated hand drags it with a soft spring and damper (applied by this script) along the
motion of `xtask/scenes/spoon-cup.toml`: down into the Newell teacup, then sideways into its wall.
Each MuJoCo step, paced to the wall clock at `--rate`:

1. the handle's pose is read from MuJoCo (`data.xpos`, `data.xquat`; MuJoCo's quaternions are
   `[w, x, y, z]`, as haptic's) and mapped into the haptic scene's frame;
2. `server.set_device_pose(pose)` hands it to the haptic thread, which renders the spoon against
   the cup at 1 kHz with the linearized contact model (`haptic.ForceServer`);
3. `server.wrench()` is the wrench the haptic thread last sent the device: the force and torque on
   the handle, which go back to MuJoCo through `data.xfrc_applied`, with the hand's.

The two frames differ by a translation only: the handle starts at MuJoCo's `HANDLE_START`, and the
offset maps it onto the scene's initial tool pose; the axes are the same (gravity is off in the
MuJoCo model, as the scene has none).

At the end it prints the rates of both loops, the contact update rate, the largest force rendered
and the force server's summary, and exits non-zero if the haptic loop ran below 900 Hz or no
contact force was rendered (CI runs it through `python/tests/test_example.py`).

    pip install ./python        # MuJoCo comes with the package
    python python/examples/mujoco_force_server.py --seconds 3 --rate 200
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import haptic

try:
    import mujoco
except ImportError:  # pragma: no cover - the example needs MuJoCo
    sys.exit("this example needs MuJoCo: pip install mujoco")

REPO_ROOT = Path(__file__).resolve().parents[2]
SCENE = REPO_ROOT / "xtask" / "scenes" / "spoon-cup.toml"

# Where the handle starts in MuJoCo's world (m); the scene frame is this frame moved by OFFSET.
HANDLE_START = np.array([0.0, 0.0, 0.3])
HANDLE_MASS_KG = 0.3
HANDLE_INERTIA_KG_M2 = 1e-3

# The simulated hand: a spring and damper from the handle to the target, linear and angular.
# Stiffer than the haptic coupling (200 N/m) so that the hand pushes the handle past the wall.
HAND_STIFFNESS_N_PER_M = 1000.0
HAND_DAMPING_NS_PER_M = 30.0
HAND_ANGULAR_STIFFNESS_NM_PER_RAD = 2.0
HAND_ANGULAR_DAMPING_NMS_PER_RAD = 0.08

# The scene's hand motion (xtask/scenes/spoon-cup.toml, positions of the tool's centre of mass):
# from y = 0.185 m down to y = 0.115 m, then 35 mm along +x, then hold.
DOWN_TO_Y_M = 0.115
SIDEWAYS_X_M = 0.035

MIN_HAPTIC_RATE_HZ = 900.0
MIN_FORCE_N = 0.5  # a contact force, well above the coupling's free-space forces


def handle_model(rate_hz: float, quat_wxyz: np.ndarray) -> mujoco.MjModel:
    """The MuJoCo model: the handle, a small box with its own mass, free in space."""
    pos = " ".join(repr(float(v)) for v in HANDLE_START)
    quat = " ".join(repr(float(v)) for v in quat_wxyz)
    i = HANDLE_INERTIA_KG_M2
    xml = f"""
<mujoco model="haptic handle">
  <option timestep="{1.0 / rate_hz!r}" gravity="0 0 0"/>
  <worldbody>
    <body name="handle" pos="{pos}" quat="{quat}">
      <freejoint/>
      <inertial pos="0 0 0" mass="{HANDLE_MASS_KG!r}" diaginertia="{i!r} {i!r} {i!r}"/>
      <geom type="box" size="0.03 0.01 0.01" contype="0" conaffinity="0" rgba="0.8 0.3 0.2 1"/>
    </body>
  </worldbody>
</mujoco>
"""
    return mujoco.MjModel.from_xml_string(xml)


def min_jerk(s: float) -> float:
    """The minimum-jerk profile the scene's waypoints use, on s in [0, 1]."""
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def target_position(t: float, start: np.ndarray, leg_s: float) -> np.ndarray:
    """The hand's target (scene frame): down for `leg_s`, sideways for `leg_s`, then hold."""
    p = start.copy()
    p[1] += (DOWN_TO_Y_M - start[1]) * min_jerk(t / leg_s)
    p[0] += SIDEWAYS_X_M * min_jerk((t - leg_s) / leg_s)
    return p


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])


def rotation_vector(q_from: np.ndarray, q_to: np.ndarray) -> np.ndarray:
    """The world-frame rotation vector (axis × angle) that turns `q_from` into `q_to`."""
    conj = q_from * np.array([1.0, -1.0, -1.0, -1.0])
    e = quat_mul(q_to, conj)
    if e[0] < 0.0:
        e = -e
    v = e[1:]
    norm = float(np.linalg.norm(v))
    if norm < 1e-12:
        return 2.0 * v
    return 2.0 * np.arctan2(norm, e[0]) * v / norm


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="wall-clock seconds to run")
    parser.add_argument("--rate", type=float, default=200.0, help="MuJoCo steps per second")
    parser.add_argument("--integrator", default="backward_euler", help="haptic's integrator")
    parser.add_argument("--backend", default="lod", help="collision back-end: lod or parry")
    args = parser.parse_args()
    if not (args.seconds > 0 and args.rate > 0):
        parser.error("--seconds and --rate must be positive")

    scene = haptic.Scene.load(SCENE)
    start_pose = np.array(scene.tool_pose, dtype=np.float64)
    offset = start_pose[:3] - HANDLE_START  # MuJoCo world -> scene frame
    orientation = start_pose[3:]
    # The scene takes 1 s down and 1 s sideways; a short run takes both faster, so that it still
    # ends pressed against the wall for a while.
    leg_s = min(1.0, 0.4 * args.seconds)

    model = handle_model(args.rate, orientation)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    hid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "handle")
    dt = model.opt.timestep
    steps = max(1, int(round(args.seconds * args.rate)))
    velocity = np.zeros(6)  # [angular, linear], world frame

    peak_force = 0.0
    late_steps = 0
    with haptic.ForceServer(scene, integrator=args.integrator, backend=args.backend) as server:
        start = time.perf_counter()
        for k in range(steps):
            # 1. The handle's pose, in the scene's frame.
            pose = np.concatenate([data.xpos[hid] + offset, data.xquat[hid]])
            # 2. To the haptic thread.
            server.set_device_pose(pose)
            # 3. The wrench it renders on the handle.
            force, torque = server.wrench()
            peak_force = max(peak_force, float(np.linalg.norm(force)))
            # The hand's spring and damper towards its target.
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, hid, velocity, 0)
            target = target_position(data.time, start_pose[:3], leg_s) - offset
            hand_force = (HAND_STIFFNESS_N_PER_M * (target - data.xpos[hid])
                          - HAND_DAMPING_NS_PER_M * velocity[3:])
            hand_torque = (HAND_ANGULAR_STIFFNESS_NM_PER_RAD
                           * rotation_vector(data.xquat[hid], orientation)
                           - HAND_ANGULAR_DAMPING_NMS_PER_RAD * velocity[:3])
            data.xfrc_applied[hid, :3] = force + hand_force
            data.xfrc_applied[hid, 3:] = torque + hand_torque
            mujoco.mj_step(model, data)
            # Paced to the wall clock.
            delay = start + (k + 1) * dt - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            else:
                late_steps += 1
        elapsed = time.perf_counter() - start
        stats = server.stats()
        tool_end = server.tool_pose()
    summary = server.summary or {}

    mujoco_rate = steps / elapsed
    haptic_rate = float(summary.get("haptic_rate_hz", stats["haptic_rate_hz"]))
    contact_rate = stats["contact_updates"] / stats["time_s"] if stats["time_s"] > 0 else 0.0
    max_force = max(peak_force, float(stats["max_force_n"]))
    handle_end = data.xpos[hid] + offset
    print(f"mujoco rate   {mujoco_rate:8.1f} Hz   ({steps} steps in {elapsed:.2f} s, "
          f"target {args.rate:.0f} Hz, {late_steps} late)")
    print(f"haptic rate   {haptic_rate:8.1f} Hz   ({stats['steps']} steps, "
          f"{args.integrator}, {args.backend})")
    print(f"contact rate  {contact_rate:8.1f} Hz   ({stats['contact_updates']} updates; "
          f"last: {stats['raw_contact_count']} raw contacts, {stats['cluster_count']} clusters)")
    print(f"max force     {max_force:8.2f} N    (read by MuJoCo {peak_force:.2f} N, "
          f"sent by the haptic thread {stats['max_force_n']:.2f} N)")
    print(f"at the end    handle ({handle_end[0]:.4f}, {handle_end[1]:.4f}, {handle_end[2]:.4f}) m, "
          f"tool ({tool_end[0]:.4f}, {tool_end[1]:.4f}, {tool_end[2]:.4f}) m, scene frame")
    print(server.summary_text or "", end="")

    failures = []
    if haptic_rate < MIN_HAPTIC_RATE_HZ:
        failures.append(f"the haptic loop ran at {haptic_rate:.0f} Hz (< {MIN_HAPTIC_RATE_HZ:.0f})")
    if max_force < MIN_FORCE_N:
        failures.append(f"no contact force was rendered (max {max_force:.3f} N < {MIN_FORCE_N} N)")
    if int(summary.get("raw_contact_count_max", 0)) == 0:
        failures.append("the tool never touched the cup (no raw contact in the run)")
    for f in failures:
        print(f"FAIL: {f}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
