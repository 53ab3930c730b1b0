"""6-DOF haptic rendering of rigid polygonal models, from numpy.

The meshes, the collision back-ends, the contact clustering, the penalty model and the multirate
pipeline of the ``haptic`` Rust workspace (Otaduy & Lin's sensation-preserving haptic rendering),
compiled into one extension module, :mod:`haptic._haptic`.

- Meshes: :class:`Mesh` (STL, OBJ, PLY with a unit scale, or numpy arrays), :class:`MassProperties`.
- Collision: :class:`LodBackend` (the multiresolution back-end) and :class:`ParryBackend`;
  ``query(pose, delta, threshold)`` returns :class:`Contacts` (numpy arrays, no Python object per
  contact) and :class:`QueryStats`.
- Clustering and contact forces: :class:`Clusterer` (k-means with warm start),
  :class:`RigidBody`, :class:`PenaltyModel`.
- The pipeline: :class:`Scene` (a scene file or parts), :func:`run_virtual` (virtual time,
  deterministic, telemetry as numpy arrays in a :class:`Run`), :func:`run_realtime` (the demo's
  real-time run, a :class:`RealtimeResult`) and :class:`ForceServer` (the haptic loop at 1 kHz in
  the background for a slower simulator).

Conventions: SI units; a pose is ``[x, y, z, qw, qx, qy, qz]`` (body to world, unit quaternion);
arrays are float64; every error is a :class:`HapticError` with ``.field`` and ``.kind``. The GIL is
released during queries, clustering and pipeline runs. Full signatures and docstrings are in the
type stubs, ``haptic/__init__.pyi``.
"""

from . import _haptic
from ._haptic import *  # noqa: F401,F403
from ._haptic import (
    ClusterError,
    Clusterer,
    CollisionError,
    Contacts,
    DeviceError,
    DynamicsError,
    ForceServer,
    HapticError,
    InputError,
    LodBackend,
    MassProperties,
    Mesh,
    MeshError,
    ParryBackend,
    PenaltyModel,
    PipelineError,
    QueryStats,
    RealtimeResult,
    RigidBody,
    Run,
    Scene,
    SceneError,
    run_realtime,
    run_virtual,
)

__version__: str = _haptic.__version__

__all__ = [
    # Meshes
    "Mesh",
    "MassProperties",
    # Collision
    "Contacts",
    "QueryStats",
    "LodBackend",
    "ParryBackend",
    # Clustering and contact forces
    "Clusterer",
    "RigidBody",
    "PenaltyModel",
    # The pipeline
    "Scene",
    "Run",
    "RealtimeResult",
    "ForceServer",
    "run_virtual",
    "run_realtime",
    # Errors
    "HapticError",
    "InputError",
    "MeshError",
    "SceneError",
    "CollisionError",
    "ClusterError",
    "DynamicsError",
    "DeviceError",
    "PipelineError",
]
