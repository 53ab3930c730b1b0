"""Shared fixtures of the Python tests: the repository's paths, the jaws and spoon-cup meshes and
scenes, generated box meshes, and the Rust reference programs whose results the package must
reproduce bit for bit."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import haptic

IDENTITY = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)

# The faces of an axis-aligned box, counter-clockwise seen from outside. Corner `i + 2 j + 4 k`
# is at (x_i, y_j, z_k), index 0 the low side and 1 the high side of each axis.
_BOX_TRIANGLES = np.array(
    [
        [0, 4, 6], [0, 6, 2],  # -x
        [1, 3, 7], [1, 7, 5],  # +x
        [0, 1, 5], [0, 5, 4],  # -y
        [2, 6, 7], [2, 7, 3],  # +y
        [0, 2, 3], [0, 3, 1],  # -z
        [4, 5, 7], [4, 7, 6],  # +z
    ],
    dtype=np.uint32,
)


def box_arrays(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (8, 3) and outward triangles (12, 3) of the box `[lo, hi]`."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    vertices = np.array(
        [[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
         for k in range(2) for j in range(2) for i in range(2)],
        dtype=np.float64,
    )
    return vertices, _BOX_TRIANGLES.copy()


def axis_angle_pose(position, axis, angle) -> np.ndarray:
    """`[x, y, z, qw, qx, qy, qz]` of a rotation by `angle` about `axis`, at `position`."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    s = math.sin(angle / 2.0)
    return np.array([*position, math.cos(angle / 2.0), *(s * axis)], dtype=np.float64)


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The workspace root: two levels above this directory (python/tests)."""
    root = Path(__file__).resolve().parents[2]
    assert (root / "Cargo.toml").is_file(), f"{root} is not the workspace root"
    return root


@pytest.fixture(scope="session")
def meshes_dir(repo_root: Path) -> Path:
    return repo_root / "assets" / "meshes"


@pytest.fixture(scope="session")
def scenes_dir(repo_root: Path) -> Path:
    return repo_root / "xtask" / "scenes"


@pytest.fixture(scope="session")
def mesh_paths(meshes_dir: Path) -> dict[str, Path]:
    """The shared meshes by short name; every one must exist."""
    paths = {
        "teaspoon": meshes_dir / "newell_teaspoon.stl",
        "teacup": meshes_dir / "newell_teacup.stl",
        "jaw_upper": meshes_dir / "jaw_upper_openfulljaw_p26.stl",
        "jaw_lower": meshes_dir / "jaw_lower_openfulljaw_p26.stl",
        "peg": meshes_dir / "factory_round_peg_8mm_tight.stl",
        "hole": meshes_dir / "factory_round_hole_8mm.stl",
    }
    for name, path in paths.items():
        assert path.is_file(), f"mesh {name} missing: {path}"
    return paths


@pytest.fixture(scope="session")
def spoon_cup_path(scenes_dir: Path) -> Path:
    path = scenes_dir / "spoon-cup.toml"
    assert path.is_file(), path
    return path


@pytest.fixture(scope="session")
def jaws_scene_path(scenes_dir: Path) -> Path:
    path = scenes_dir / "jaws.toml"
    assert path.is_file(), path
    return path


@pytest.fixture(scope="session")
def spoon_cup(spoon_cup_path: Path) -> haptic.Scene:
    """The README's demo scene (a Scene is not changed by the runs that use it)."""
    return haptic.Scene.load(spoon_cup_path)


# The jaws as xtask/scenes/jaws.toml has them: both stored in millimetres, in occlusion in their
# file frames; the lower jaw at the identity.
JAWS_SCALE = 1e-3


@pytest.fixture(scope="session")
def jaws_meshes(mesh_paths: dict[str, Path]) -> tuple[haptic.Mesh, haptic.Mesh]:
    """(upper, lower) jaw, loaded as the Rust reference loads them (the tool not recentred)."""
    upper = haptic.Mesh.load(mesh_paths["jaw_upper"], JAWS_SCALE)
    lower = haptic.Mesh.load(mesh_paths["jaw_lower"], JAWS_SCALE)
    return upper, lower


@pytest.fixture(scope="session")
def jaws_lod(jaws_meshes) -> haptic.LodBackend:
    """The LOD back-end of the upper jaw over the lower (it keeps no state between queries)."""
    upper, lower = jaws_meshes
    return haptic.LodBackend(upper, [(lower, IDENTITY)])


@pytest.fixture(scope="session")
def make_box() -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """`make_box(lo, hi)`: vertices and outward triangles of an axis-aligned box."""
    return box_arrays


@pytest.fixture(scope="session")
def make_pose() -> Callable[..., np.ndarray]:
    """`make_pose(position, axis, angle)`: a pose array."""
    return axis_angle_pose


def _run_checked(cmd: list[str], cwd: Path, what: str) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, text=True)
    except subprocess.CalledProcessError as e:
        raise AssertionError(
            f"{what} failed (exit {e.returncode}): {' '.join(cmd)}\n"
            f"--- stdout ---\n{e.stdout}\n--- stderr ---\n{e.stderr}"
        ) from e


def pose_arg(pose) -> str:
    """A pose as the Rust programs take it: `x,y,z,qw,qx,qy,qz`, each float in its shortest
    round-trip form (so that Rust parses the very same f64)."""
    return ",".join(repr(float(v)) for v in pose)


@pytest.fixture(scope="session")
def rust_reference(repo_root: Path) -> Callable[..., dict]:
    """Runs the Rust reference of one query (`haptic-collision`'s example `query_contacts`) with
    the given arguments and returns its JSON output, with the arrays as numpy arrays:
    contacts (`p_a`, `r_a`, `p_b`, `n` (k, 3) float64, `depth`, `area` (k,) float64, `feature_a`,
    `feature_b` (k,) uint32), `representatives` (the same keys), `representative_weights`,
    `force`, `torque`. Results are cached per argument list."""
    cache: dict[tuple[str, ...], dict] = {}

    def contacts_of(raw: dict) -> dict:
        out = {}
        for key in ("p_a", "r_a", "p_b", "n"):
            out[key] = np.array(raw[key], dtype=np.float64).reshape(-1, 3)
        out["depth"] = np.array(raw["depth"], dtype=np.float64).reshape(-1)
        out["area"] = np.array(raw["area"], dtype=np.float64).reshape(-1)
        for key in ("feature_a", "feature_b"):
            out[key] = np.array(raw[key], dtype=np.uint32).reshape(-1)
        return out

    def run(*args: str) -> dict:
        key = tuple(str(a) for a in args)
        if key not in cache:
            cmd = [
                "cargo", "run", "--quiet", "--release", "-p", "haptic-collision",
                "--example", "query_contacts", "--", *key,
            ]
            done = _run_checked(cmd, repo_root, "the Rust reference query_contacts")
            raw = json.loads(done.stdout)
            result = contacts_of(raw)
            result["representatives"] = contacts_of(raw["representatives"])
            result["representative_weights"] = np.array(
                raw["representative_weights"], dtype=np.float64
            ).reshape(-1)
            result["force"] = np.array(raw["force"], dtype=np.float64)
            result["torque"] = np.array(raw["torque"], dtype=np.float64)
            cache[key] = result
        return cache[key]

    return run


@pytest.fixture(scope="session")
def rust_demo(repo_root: Path, tmp_path_factory) -> Callable[..., dict]:
    """`rust_demo(seconds, scene="spoon-cup")`: the summary `cargo xtask demo --virtual-time`
    writes with `--json` (cached)."""
    cache: dict[tuple[float, str], dict] = {}

    def run(seconds: float, scene: str = "spoon-cup") -> dict:
        key = (float(seconds), scene)
        if key not in cache:
            out = tmp_path_factory.mktemp("demo") / "summary.json"
            cmd = [
                "cargo", "run", "--quiet", "--release", "-p", "xtask", "--",
                "demo", "--scene", scene, "--seconds", repr(float(seconds)), "--virtual-time",
                "--json", str(out),
            ]
            _run_checked(cmd, repo_root, "cargo xtask demo")
            cache[key] = json.loads(out.read_text())
        return cache[key]

    return run
