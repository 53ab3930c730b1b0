"""6-DOF haptic rendering of rigid polygonal models, from numpy.

Type stubs and docstrings of the extension module :mod:`haptic._haptic`, re-exported by
:mod:`haptic`.

Conventions:

- Units are SI: metres, seconds, newtons, newton-metres, kilograms.
- A *pose* is 7 floats ``[x, y, z, qw, qx, qy, qz]``: position (m) and a unit quaternion, body to
  world. A quaternion off unit length by more than 1e-6 is an :class:`InputError`, not
  normalised silently.
- Arrays are float64 (any array-like numpy accepts); shapes are checked, and a NaN or an
  infinity anywhere in an input is an :class:`InputError` naming the argument.
- Every error is a :class:`HapticError` with ``.field`` and ``.kind``.
"""

import os
from collections.abc import Callable, Iterable
from types import TracebackType
from typing import Any, Literal, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

__version__: str

__all__ = [
    "Mesh",
    "MassProperties",
    "Contacts",
    "QueryStats",
    "LodBackend",
    "ParryBackend",
    "Clusterer",
    "RigidBody",
    "PenaltyModel",
    "Scene",
    "Run",
    "RealtimeResult",
    "ForceServer",
    "run_virtual",
    "run_realtime",
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

_Pose = ArrayLike
"""``[x, y, z, qw, qx, qy, qz]``: position (m) and unit quaternion, body to world."""

_IntegratorName = Literal[
    "backward_euler",
    "linearized_backward_euler",
    "newton_backward_euler",
    "rk4",
    "forward_euler",
]
"""The haptic loop's integrator: ``"backward_euler"`` (the linearized backward Euler of the
paper; alias ``"linearized_backward_euler"``), ``"newton_backward_euler"`` (the implicit step
solved by Newton's method), ``"rk4"`` or ``"forward_euler"``."""

_BackendName = Literal["lod", "parry"]
"""The collision back-end of a run: ``"lod"`` (multiresolution, the scene's error threshold) or
``"parry"`` (parry3d's exact triangle-mesh contacts)."""

_Device = Union[tuple[ArrayLike, ArrayLike], Callable[[float], ArrayLike]]
"""A device for :func:`run_virtual`: ``(times (k,), poses (k, 7))``, a scripted handle through
those poses (minimum-jerk between them), or a callable ``t (s) -> pose``."""

# ---------------------------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------------------------

class HapticError(Exception):
    """The base of every error of haptic.

    Attributes:
        field: The argument or scene field that was wrong (``"vertices"``, ``"pose"``,
            ``"penalty.stiffness_n_per_m"``, ``"tool.mass_kg"``, ...), or ``None``.
        kind: A short machine-readable word (``"io"``, ``"invalid_input"``,
            ``"invalid_parameter"``, ``"disconnected"``, ``"invalid_data"``, ...).
    """

    field: str | None
    kind: str

class InputError(HapticError, ValueError):
    """An argument from Python with a wrong shape, dtype or value (NaN, infinity, empty array,
    non-unit quaternion, out of range, unknown name). Also a :class:`ValueError`."""

class MeshError(HapticError):
    """A mesh file that cannot be read or parsed (``.kind == "io"`` for a missing or unreadable
    file), or an invalid mesh (a triangle index out of range, no triangle left, an open or
    inside-out mesh asked for its mass properties)."""

class SceneError(HapticError):
    """A scene file that cannot be read or parsed, or a scene field out of range (``.field`` is
    its dotted path, as ``"tool.mass_kg"`` or ``"obstacles[0].mesh"``)."""

class CollisionError(HapticError):
    """A collision back-end that cannot be built or queried."""

class ClusterError(HapticError):
    """Clustering parameters (``max_clusters``, ``max_iterations``, ``delta``) or contacts."""

class DynamicsError(HapticError):
    """Penalty, coupling or rigid-body parameters (``.field`` as
    ``"penalty.stiffness_n_per_m"``), or contacts the penalty model cannot evaluate."""

class DeviceError(HapticError):
    """A device that failed; ``.kind`` says how (``"disconnected"``, ``"timeout"``,
    ``"invalid_data"``, ``"other"``, ...)."""

class PipelineError(HapticError):
    """A run that stopped before its end (a device that failed, a panic, an exception raised by
    a device callable: then chained as ``__cause__`` or quoted in the message).

    Attributes:
        summary: The run's summary up to the stop (the keys of :attr:`Run.summary`), or
            ``None`` when the run did not start.
    """

    summary: dict[str, Any] | None

# ---------------------------------------------------------------------------------------------
# Meshes
# ---------------------------------------------------------------------------------------------

class MassProperties:
    """The mass properties of the uniform-density solid a mesh bounds (divergence theorem)."""

    @property
    def volume_m3(self) -> float:
        """Enclosed volume (m³)."""
    @property
    def mass_kg(self) -> float:
        """Mass (kg): density × volume."""
    @property
    def centre_of_mass_m(self) -> NDArray[np.float64]:
        """Centre of mass in the mesh's frame (m), shape ``(3,)``."""
    @property
    def inertia_about_com(self) -> NDArray[np.float64]:
        """Inertia tensor about the centre of mass, mesh axes (kg m²), shape ``(3, 3)``."""
    @property
    def boundary_edges(self) -> int:
        """Edges used by exactly one triangle: 0 for a closed mesh (an open mesh whose holes
        change the volume by at most 1 % still gets mass properties)."""

class Mesh:
    """A validated triangle mesh (m), counter-clockwise triangles (outward normals).

    ``Mesh(vertices, triangles)`` builds one from arrays: ``vertices`` ``(n, 3)`` float,
    ``triangles`` ``(m, 3)`` non-negative integer vertex indices. Degenerate (zero-area or
    repeated-vertex) triangles are dropped and counted in :attr:`dropped_degenerate`. Triangles
    wound against their neighbours are kept as given (:attr:`winding_conflicts` counts them;
    :meth:`with_consistent_winding` turns them); the back-ends refuse such a mesh.

    Raises:
        InputError: a wrong shape or dtype, an empty array, a NaN or infinite vertex
            (``.field == "vertices"``), a negative or fractional index (``"triangles"``).
        MeshError: an index out of range, or no triangle left after dropping.
    """

    def __init__(self, vertices: ArrayLike, triangles: ArrayLike) -> None: ...
    @staticmethod
    def load(path: str | os.PathLike[str], scale: float = 1.0) -> Mesh:
        """Loads an STL (binary or ASCII), OBJ or PLY file, by its extension; vertices are
        multiplied by ``scale`` (metres per file unit: ``1e-3`` for millimetres). STL corners
        that are exactly equal become one vertex; triangles that repeat an earlier one are
        dropped (:attr:`dropped_duplicates`) and those wound against their neighbours turned to
        agree with them (:attr:`rewound_triangles`). The GIL is released
        while reading.

        Raises:
            MeshError: a missing or unreadable file (``.kind == "io"``), an unsupported
                extension, content that does not parse, an invalid mesh.
            InputError: a scale that is not positive and finite (``.field == "scale"``).
        """
    @property
    def vertices(self) -> NDArray[np.float64]:
        """Vertex positions (m), ``(n, 3)`` float64, a copy."""
    @property
    def triangles(self) -> NDArray[np.uint32]:
        """Triangles as vertex indices, ``(m, 3)`` uint32, a copy."""
    @property
    def vertex_count(self) -> int:
        """Number of vertices."""
    @property
    def triangle_count(self) -> int:
        """Number of triangles."""
    @property
    def dropped_degenerate(self) -> int:
        """How many degenerate triangles were dropped when the mesh was made."""
    @property
    def dropped_duplicates(self) -> int:
        """How many triangles :meth:`load` dropped for repeating an earlier one (the same
        vertices, wound the same way: each would have pushed twice)."""
    @property
    def rewound_triangles(self) -> int:
        """How many triangles were turned to agree with their neighbours' winding when the
        mesh was loaded, or by :meth:`with_consistent_winding`."""
    @property
    def winding_conflicts(self) -> int:
        """Edges shared by two triangles wound against each other: 0 for a consistent mesh, 3
        for one triangle turned inside out. A triangle's winding says which side is outside,
        so the contacts on a turned one would push the wrong way."""
    def with_consistent_winding(self) -> Mesh:
        """A copy with every connected part wound consistently, each the way the larger area
        of its triangles is (a part inside out throughout is left so).

        Raises:
            MeshError: a part that cannot be wound consistently (a Möbius band;
                ``.kind == "non_orientable"``).
        """
    def mass_properties(self, density_kg_per_m3: float) -> MassProperties:
        """Volume, mass, centre of mass and inertia of the solid the mesh bounds, filled with a
        uniform density (kg/m³).

        Raises:
            InputError: a density that is not positive and finite.
            MeshError: an open mesh whose holes matter, inward-facing triangles, no volume.
        """
    def translated(self, offset: ArrayLike) -> Mesh:
        """A copy with every vertex moved by ``offset`` (m, 3 floats)."""
    def bounding_box(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The axis-aligned bounding box of the vertices used by triangles: ``(lo (3,),
        hi (3,))`` (m)."""

# ---------------------------------------------------------------------------------------------
# Collision
# ---------------------------------------------------------------------------------------------

class Contacts:
    """A set of contacts between the tool (a) and the obstacles (b), as arrays: no Python object
    per contact. Each property returns a fresh numpy array.

    ``Contacts(p_a, r_a, p_b, n, depth, feature_a=None, feature_b=None, area=None)`` builds one
    from arrays (the features default to none, ``0xFFFFFFFF``, the areas to 0: not measured).

    Raises:
        InputError: a wrong shape, rows that do not match ``p_a``, a NaN, a normal that is
            not unit within 1e-6 (``.field == "n"``), or a negative area (``"area"``).
    """

    def __init__(
        self,
        p_a: ArrayLike,
        r_a: ArrayLike,
        p_b: ArrayLike,
        n: ArrayLike,
        depth: ArrayLike,
        feature_a: ArrayLike | None = None,
        feature_b: ArrayLike | None = None,
        area: ArrayLike | None = None,
    ) -> None: ...
    @property
    def p_a(self) -> NDArray[np.float64]:
        """Points on the tool, world frame (m), ``(k, 3)``."""
    @property
    def r_a(self) -> NDArray[np.float64]:
        """The same points in the tool's body frame (m), ``(k, 3)``: ``p_a = x + R r_a``."""
    @property
    def p_b(self) -> NDArray[np.float64]:
        """Points on the obstacle, world frame (m), ``(k, 3)``."""
    @property
    def n(self) -> NDArray[np.float64]:
        """Unit normals pointing out of the tool, towards the obstacle, ``(k, 3)``."""
    @property
    def depth(self) -> NDArray[np.float64]:
        """Penetration depths (m), ``(k,)``: positive when ``p_a`` is inside the obstacle,
        negative (down to ``-delta``) when apart but within the distance tolerance."""
    @property
    def area(self) -> NDArray[np.float64]:
        """The tool surface each contact stands for (m²), ``(k,)``; 0: not measured. The
        clustering weighs contacts by ``area * (depth + delta)`` when every contact has one."""
    @property
    def feature_a(self) -> NDArray[np.uint32]:
        """The tool triangle (or hierarchy node) of each contact, ``(k,)``; ``0xFFFFFFFF``:
        none."""
    @property
    def feature_b(self) -> NDArray[np.uint32]:
        """The obstacle triangle (or hierarchy node) of each contact, ``(k,)``; ``0xFFFFFFFF``:
        none."""
    def __len__(self) -> int:
        """The number of contacts."""

class QueryStats:
    """What one collision query did."""

    @property
    def broad_phase_hit(self) -> bool:
        """Whether the broad phase found anything within ``delta`` (if not, nothing else was
        done)."""
    @property
    def node_pairs_tested(self) -> int:
        """Bounding-volume (hierarchy node) pairs tested."""
    @property
    def primitive_pairs_tested(self) -> int:
        """Primitive (triangle) pairs tested exactly."""
    @property
    def raw_contacts(self) -> int:
        """Contacts found before the back-end compacted them into the ones returned (0 when
        it does not compact: ``ParryBackend``, or ``LodBackend(max_contacts=None)``)."""
    @property
    def time_s(self) -> float:
        """Wall time of the query (s), measured in Rust around the query alone."""

class LodBackend:
    """The sensation-preserving multiresolution collision back-end (Otaduy & Lin).

    ``LodBackend(tool, obstacles, cache_dir=None, max_contacts=256, stopping_rule="coherence-budget")``:
    ``tool`` the tool mesh in its body frame
    (the frame whose pose the queries give), ``obstacles`` a list of ``(Mesh, pose)`` pairs
    placing each obstacle in the world. With ``cache_dir``, each hierarchy is read back from that
    folder when it was saved there for the same mesh and build (the jaws: 0.06 s instead of about
    1 s), and built and saved there otherwise; a file that cannot be used (cut short, corrupt,
    another version or mesh) is rebuilt and replaced, never used. Building the hierarchies
    releases the GIL.

    A query returns at most ``max_contacts`` contacts: when it finds more, they are merged region
    by region into that many, keeping what the clustering reads of them (their weights
    ``area * (depth + delta)``, weighted centroids and depths) and the deepest contact as it is;
    ``QueryStats.raw_contacts`` says how many were found. ``max_contacts=None`` returns every
    contact found (at ``threshold=0``, the all-pairs reference).

    ``stopping_rule`` says where the walk may stop at coarse pieces: ``"deviation"`` (the
    paper's: the pieces' surface deviations within the threshold), ``"coherence"`` (the
    deviations also within ``delta``, and where a pair writes a contact, each piece's surface
    normals agreeing within the threshold that budget stands for,
    ``1 - |sum a n| / sum a <= min(threshold, delta / radius)``, and a pair dropped only where
    the surfaces its pieces stand for, not the pieces, are beyond ``delta``: more accurate on
    threads, tines, long tools and other features smaller than the threshold, slower where
    coarse curved pieces touch) or ``"coherence-budget"`` (the same cap and cull, and the
    coherence held for the regions together: the regions whose ``weight * (1 - coherence)`` is
    largest are refined until the rest sums to at most ``threshold`` times the net force; close
    to ``"coherence"``'s accuracy at a fraction of its extra cost where many small coarse
    regions touch). The default is ``"coherence-budget"``: its error at a threshold depends
    least on the scene (on long tools with small features, a fork in a mug, the paper's rule at
    2.5 % misses contacts outright); ``"deviation"`` is faster at the same threshold where
    coarse curved pieces touch (the jaws: about 1.4 times) and is what the paper measured.

    Raises:
        InputError: an obstacle that is not a ``(Mesh, pose)`` pair (``.field ==
            "obstacles[i]"``), a bad pose (``"obstacles[i].pose"``), or an unknown
            ``stopping_rule`` (``"stopping_rule"``).
        CollisionError: hierarchies that cannot be built.
    """

    def __init__(
        self,
        tool: Mesh,
        obstacles: Iterable[tuple[Mesh, _Pose]],
        cache_dir: str | os.PathLike[str] | None = None,
        max_contacts: int | None = 256,
        stopping_rule: Literal["deviation", "coherence", "coherence-budget"] = "coherence-budget",
    ) -> None: ...
    @property
    def cache_report(self) -> list[tuple[str, str]]:
        """With ``cache_dir``: for the tool, then each obstacle, ``(what happened, file)``,
        what being ``"loaded"``, ``"built"``, ``"rebuilt: why"`` or ``"not saved: why"``;
        empty without."""
    def query(
        self, pose: _Pose, delta: float, threshold: float = 0.0
    ) -> tuple[Contacts, QueryStats]:
        """Every contact of the tool at ``pose`` within ``delta`` (m) of the obstacles, at the
        error ``threshold`` (a fraction of :attr:`tool_bounding_radius_m`; 0 is exact, 0.025 is
        the paper's 2.5 %), and the query's statistics. The GIL is released during the query.

        Raises:
            InputError: a bad pose (``.field == "pose"``), ``delta`` not positive and finite
                (``"delta"``), a negative ``threshold`` (``"threshold"``).
            CollisionError: a query that failed.
        """
    @property
    def node_count(self) -> int:
        """Nodes in the tool's and the obstacles' hierarchies."""
    @property
    def tool_bounding_radius_m(self) -> float:
        """The tool's bounding radius about its body origin (m): the unit of ``threshold``."""
    def threshold_reached(self, delta: float, threshold: float) -> float:
        """The error threshold a query within ``delta`` (m) at ``threshold`` holds:
        ``threshold``, or at most ``delta / tool_bounding_radius_m`` under the rules that cap a
        piece's deviation at ``delta`` (``"coherence-budget"``, the default, and
        ``"coherence"``): above it a coarser threshold changes nothing. A contact update reports
        this threshold.

        Raises:
            InputError: a ``delta`` that is not positive and finite, or a negative or
                non-finite ``threshold`` (``.field == "threshold"``), as :meth:`query`.
        """

class ParryBackend:
    """The parry3d back-end: exact triangle-mesh contact manifolds, built like
    :class:`LodBackend` from ``(tool, obstacles)``."""

    def __init__(self, tool: Mesh, obstacles: Iterable[tuple[Mesh, _Pose]]) -> None: ...
    def query(
        self, pose: _Pose, delta: float, threshold: float = 0.0
    ) -> tuple[Contacts, QueryStats]:
        """As :meth:`LodBackend.query`; ``threshold`` is accepted and ignored (parry is exact).
        The GIL is released during the query."""
    @property
    def tool_bounding_radius_m(self) -> float:
        """The tool's bounding radius about its body origin (m)."""

# ---------------------------------------------------------------------------------------------
# Clustering and the penalty model
# ---------------------------------------------------------------------------------------------

class Clusterer:
    """k-means contact clustering with temporal coherence (eqs. 28–32).

    Contacts are weighted by ``w = area (depth + delta)`` (the depth term floored at
    ``1e-3 delta``; ``area`` 1 unless every contact has one). A cluster's centroid is the
    weighted mean of its contacts' points, its depth their weighted mean, and its penalty
    ``Σ w (depth + delta) n`` is shared out by stiffness shares (``Contacts.stiffness_share``)
    so that the clustered force is the contacts' own whatever the partition. With
    ``torque_pairs`` (the default) each cluster is written as two springs either side of its
    centroid that keep its contacts' torque as well; otherwise as one spring at the centroid
    (the paper's model). With ``warm_start`` each call is seeded from the previous call's
    clusters, so their identities (their order) persist from call to call; a cold start seeds
    the deepest contact first.

    Args:
        max_clusters: K, the most clusters (default 5).
        max_iterations: cap on Lloyd iterations per call (default 16).
        warm_start: seed from the previous call (default True).
        torque_pairs: two springs per cluster that keep its torque (default True), or one.

    Raises:
        ClusterError: ``max_clusters`` or ``max_iterations`` of 0 (``.field`` names it).
    """

    def __init__(
        self,
        max_clusters: int | None = None,
        max_iterations: int | None = None,
        warm_start: bool | None = None,
        torque_pairs: bool | None = None,
    ) -> None: ...
    def cluster(self, contacts: Contacts, delta: float) -> Contacts:
        """The representatives (at most ``max_clusters``, twice that with ``torque_pairs``) of
        ``contacts`` queried with distance tolerance ``delta`` (m). An empty input gives no
        representative and forgets the history. The GIL is released while clustering.

        Raises:
            ClusterError: ``delta`` not positive and finite (``.field == "delta"``).
        """
    @property
    def representative_weights(self) -> NDArray[np.float64]:
        """Each representative's weight of the last call (m³ with areas, m without), in order:
        the sum of its contacts' ``area (depth + delta)``, half each for a torque pair's two
        springs."""
    @property
    def max_clusters(self) -> int:
        """K."""
    @property
    def torque_pairs(self) -> bool:
        """Whether each cluster is written as a torque pair of two springs."""
    def reset(self) -> None:
        """Forgets the previous representatives: the next call cold-starts."""

class RigidBody:
    """A rigid body: mass (kg) and inertia about its centre of mass in body axes (kg m²,
    ``(3, 3)``, symmetric positive definite and physical).

    Raises:
        InputError: an inertia of the wrong shape or with a NaN.
        DynamicsError: a mass that is not positive, an inertia that is not symmetric, positive
            definite and physical.
    """

    def __init__(self, mass_kg: float, inertia_kg_m2: ArrayLike) -> None: ...
    @staticmethod
    def from_mass_properties(mp: MassProperties) -> RigidBody:
        """The body of a mesh's mass properties (body frame at the centre of mass, mesh
        axes)."""
    @property
    def mass_kg(self) -> float:
        """Mass (kg)."""
    @property
    def inertia_kg_m2(self) -> NDArray[np.float64]:
        """Body-frame inertia about the centre of mass (kg m²), ``(3, 3)``."""

class PenaltyModel:
    """The penalty contact model (eq. 33): per contact a spring and a damper along its normal,
    pushing from ``delta_m`` before the surfaces touch. With ``g = n·(p_a − p_b) + δ`` and
    ``λ = k g + b n·v_a``, the force on the tool is ``−λ n`` (along minus the normal, which
    points out of the tool) while ``g > 0`` and ``λ > 0``, and zero otherwise (it never pulls);
    the torque about the centre of mass is ``ρ × F`` with ``ρ = R r_a``.

    Raises:
        DynamicsError: a stiffness that is not positive, a negative damping or ``delta_m``, a
            NaN (``.field`` as ``"penalty.stiffness_n_per_m"``).
    """

    def __init__(
        self,
        stiffness_n_per_m: float = 2000.0,
        damping_ns_per_m: float = 2.0,
        delta_m: float = 1e-3,
    ) -> None: ...
    def wrench(
        self,
        body: RigidBody,
        pose: _Pose,
        contacts: Contacts,
        velocity: ArrayLike | None = None,
        angular_velocity: ArrayLike | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The contact wrench on the tool, ``(force (3,), torque (3,))`` (N; N m about the
        centre of mass; world frame), of ``contacts`` (body points ``r_a``, obstacle points
        ``p_b``, normals ``n``) with the tool ``body`` at ``pose`` (its centre of mass), moving
        at ``velocity`` (m/s) and ``angular_velocity`` (rad/s, world frame); at rest by default.

        Raises:
            InputError: a bad pose or velocity.
            DynamicsError: contacts the model cannot evaluate.
        """

# ---------------------------------------------------------------------------------------------
# The pipeline
# ---------------------------------------------------------------------------------------------

class Scene:
    """A scene ready to run: the tool (recentred on its centre of mass, with the inertia of a
    uniform solid of its mass), the obstacles, the coupling, contact and rate parameters, the
    device's limits and the simulated hand's target trajectory. Reusable: runs do not change
    it."""

    @staticmethod
    def load(path: str | os.PathLike[str]) -> Scene:
        """Reads a scene file (TOML, as ``xtask/scenes/spoon-cup.toml``; mesh paths relative to
        the file) and loads its meshes. The GIL is released while loading.

        Raises:
            SceneError: a file that cannot be read or parsed, or a bad field (``.field``: its
                dotted path).
        """
    @staticmethod
    def from_parts(
        *,
        tool: Mesh,
        mass_kg: float,
        tool_pose: _Pose | None = None,
        obstacles: Iterable[tuple[Mesh, _Pose]] | None = (),
        name: str = "scene",
        coupling_stiffness_n_per_m: float = 200.0,
        coupling_damping_ns_per_m: float | None = None,
        angular_stiffness_nm_per_rad: float = 0.6,
        angular_damping_nms_per_rad: float | None = None,
        contact_stiffness_n_per_m: float = 2000.0,
        contact_damping_ns_per_m: float | None = None,
        delta_m: float = 1e-3,
        clusters: int = 5,
        error_threshold: float = 0.0,
        linearized: bool = True,
        fixed_frames: bool = True,
        haptic_rate_hz: float = 1000.0,
        contact_rate_hz: float | None = None,
        waypoints: tuple[ArrayLike, ArrayLike] | None = None,
        max_force_n: float = 10.0,
        max_torque_nm: float = 1.0,
        workspace_half_m: float = 0.5,
        time_budget_s: float | None = None,
        stopping_rule: Literal["deviation", "coherence", "coherence-budget"] = "coherence-budget",
        torque_pairs: bool = True,
    ) -> Scene:
        """A scene from meshes and parameters: the fields of a scene file, with the same
        defaults, all by keyword.

        Args:
            tool: the tool mesh in its own frame; the scene recentres it on its centre of mass.
            mass_kg: the tool's mass; its inertia is that of a uniform solid of that mass.
            tool_pose: the initial pose of the tool's centre of mass (identity).
            obstacles: ``(Mesh, pose)`` pairs.
            name: for reports.
            coupling_stiffness_n_per_m, coupling_damping_ns_per_m: the virtual coupling's
                linear spring and damper (``None``: the library's default damping).
            angular_stiffness_nm_per_rad, angular_damping_nms_per_rad: its angular ones.
            contact_stiffness_n_per_m, contact_damping_ns_per_m: the penalty model's.
            delta_m: the distance tolerance (pre-contact) of queries and penalty.
            clusters: K, the most clusters (1 to the linearized model's capacity, 16, or half
                that with ``torque_pairs``).
            error_threshold: the multiresolution error threshold (fraction of the tool's
                bounding radius).
            linearized: a contact model that follows the tool between updates (True) or
                forces held between updates (False, the paper's ablation).
            fixed_frames: with ``linearized``, each representative evaluated on its frame held
                fixed with the tool's exact kinematics (True), or on its tangent (False, the
                paper's eq. 42).
            haptic_rate_hz: the haptic loop's rate.
            contact_rate_hz: the contact updates' rate in virtual time (``None``: as fast as
                it runs).
            waypoints: ``(times (k,), poses (k, 7))``, the simulated hand's target (minimum
                jerk between waypoints); ``None`` holds the handle where the tool starts.
            max_force_n, max_torque_nm: the device's limits (wrenches beyond are clamped).
            workspace_half_m: half the side of the device's cubic workspace.
            time_budget_s: a time budget per contact update (s): the LOD back-end's error
                threshold is then picked update by update to fit it and ``error_threshold`` is
                not used (errors name ``"contact.time_budget_s"``); with a budget, virtual-time
                runs depend on the machine's speed, and the parry back-end is refused.
            stopping_rule: where the LOD back-end may stop at coarse pieces, as
                :class:`LodBackend`'s ``stopping_rule`` (``"coherence-budget"``, the default,
                ``"deviation"``, the paper's, or ``"coherence"``).
            torque_pairs: each cluster written as two springs that keep its contacts' torque
                as well as their force (True), or as one spring (False, the paper's model);
                as :class:`Clusterer`'s ``torque_pairs``.

        Raises:
            InputError: a bad pose or array, an unknown ``stopping_rule``.
            SceneError: a field out of range (``.field``: its scene-file path, as
                ``"tool.mass_kg"``), a tool mesh without mass properties.
        """
    @property
    def name(self) -> str:
        """The scene's name."""
    @property
    def tool_mesh(self) -> Mesh:
        """The tool mesh in its body frame (origin at its centre of mass)."""
    @property
    def tool_pose(self) -> NDArray[np.float64]:
        """The tool's initial pose (its centre of mass), ``(7,)``."""
    @property
    def mass_kg(self) -> float:
        """The tool's mass (kg)."""
    @property
    def haptic_rate_hz(self) -> float:
        """The haptic loop's rate (Hz)."""
    @property
    def contact_rate_hz(self) -> float | None:
        """The contact updates' rate in virtual time (Hz), or ``None`` (as fast as it runs)."""
    @property
    def delta_m(self) -> float:
        """The distance tolerance δ of the queries and the penalty model (m)."""
    @property
    def max_force_n(self) -> float:
        """The device's largest force (N)."""

class Run:
    """The telemetry of a virtual-time run: one row per haptic step."""

    t: NDArray[np.float64]
    """Time of each step (s), ``(N,)``."""
    tool_pose: NDArray[np.float64]
    """The virtual tool's pose (its centre of mass) after each step, ``(N, 7)``."""
    device_pose: NDArray[np.float64]
    """The device handle's pose read at each step, ``(N, 7)``."""
    force: NDArray[np.float64]
    """The force sent to the device (N, world frame), ``(N, 3)``."""
    torque: NDArray[np.float64]
    """The torque sent to the device (N m, world frame), ``(N, 3)``."""
    raw_contact_count: NDArray[np.int64]
    """Raw contacts of the contact update in use at each step, ``(N,)``."""
    cluster_count: NDArray[np.int64]
    """Representatives of the contact update in use at each step, ``(N,)``."""
    penetration_m: NDArray[np.float64]
    """Deepest raw penetration of the contact update in use (m), ``(N,)``."""
    summary: dict[str, Any]
    """The end-of-run summary: what ``cargo xtask demo --json`` writes (``mode``,
    ``duration_s``, ``haptic_steps``, ``haptic_rate_hz``, ``step_p50_s``, ...,
    ``contact_updates``, ``raw_contact_count_max``, ``cluster_count_max``,
    ``max_penetration_m``, ``max_coupling_deviation_m``, ``max_force_n``,
    ``saturation_events``, ``zero_force_steps``, ``solver_failures``, ``solver_fallbacks``,
    ``contact_errors``, ``incidents``, ...)."""
    summary_text: str
    """The summary as ``cargo xtask demo`` prints it."""

class RealtimeResult:
    """The outcome of :func:`run_realtime`."""

    summary: dict[str, Any]
    """The end-of-run summary (the keys of :attr:`Run.summary`; ``mode == "real-time"``)."""
    summary_text: str
    """The summary as ``cargo xtask demo`` prints it (with the scheduling line)."""

class ForceServer:
    """The haptic loop of a scene in the background, at its haptic rate on the wall clock, for
    a simulator that runs slower (the contact thread runs beside it).

    The simulator sets the device handle's pose with :meth:`set_device_pose` whenever it has a
    new one, and reads :meth:`wrench`, the wrench the haptic thread last sent the handle (the
    force on the handle, world frame). The handle starts at the scene's initial tool pose.

    Use it as a context manager (``with ForceServer(scene) as server:`` starts it and stops it
    at the end, setting :attr:`summary`), or call :meth:`start` and :meth:`stop`.

    Args:
        scene: the scene (its waypoints are not used: the handle is yours).
        integrator: ``"backward_euler"`` (alias ``"linearized_backward_euler"``),
            ``"newton_backward_euler"``, ``"rk4"`` or ``"forward_euler"``.
        backend: ``"lod"`` or ``"parry"``.

    Raises:
        InputError: an unknown integrator or back-end (``.field`` names it).
    """

    def __init__(
        self,
        scene: Scene,
        integrator: _IntegratorName | str = "backward_euler",
        backend: _BackendName | str = "lod",
    ) -> None: ...
    def __enter__(self) -> ForceServer:
        """Starts the server and returns it.

        Raises:
            PipelineError: a server that runs already.
        """
    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Stops the server (if it is running); :attr:`summary` is then set."""
    def start(self) -> None:
        """Starts the haptic and contact threads (again after a stop: a new run). The handle
        starts at the scene's tool pose until :meth:`set_device_pose` moves it.

        Raises:
            PipelineError: a server that runs already.
        """
    def stop(self) -> dict[str, Any]:
        """Stops the threads (zero force is commanded) and returns the run's summary (also in
        :attr:`summary`).

        Raises:
            HapticError: a server that is not running.
        """
    def set_device_pose(self, pose: _Pose, twist: ArrayLike | None = None) -> None:
        """The handle's new pose (from your simulator), picked up by the haptic thread at its
        next step, with its twist ``[vx, vy, vz, wx, wy, wz]`` (m/s, rad/s, world frame) for the
        coupling's damper: ``twist`` when given, else the difference from the previous pose
        over the time between the two calls.

        Raises:
            InputError: a bad pose (NaN, non-unit quaternion, wrong length; ``.field ==
                "pose"``) or twist (``.field == "twist"``).
            PipelineError: a server that is not running, or whose run ended on its own (a
                device failure, a panic; ``.summary`` holds the run).
        """
    def wrench(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(force (3,), torque (3,))``: the wrench the haptic thread last sent the handle
        (N, N m, world frame), within the scene's device limits. Never blocks."""
    def tool_pose(self) -> NDArray[np.float64]:
        """The virtual tool's pose (its centre of mass) after the haptic thread's latest step,
        ``(7,)`` (the scene's tool pose before the first), read lock-free."""
    def device_pose(self) -> NDArray[np.float64]:
        """The handle's pose last set with :meth:`set_device_pose`, ``(7,)``."""
    def stats(self) -> dict[str, Any]:
        """Live statistics, read lock-free from the haptic thread's counters: ``steps``
        (haptic steps so far), ``time_s`` (since the start), ``haptic_rate_hz``,
        ``contact_updates``, ``raw_contact_count`` and ``cluster_count`` (of the newest
        contact update), ``max_force_n`` (largest force sent so far), ``deadline_misses``,
        ``zero_force_steps`` and ``running``."""
    @property
    def summary(self) -> dict[str, Any] | None:
        """The run's summary once stopped (the keys of :attr:`Run.summary`), else ``None``."""
    @property
    def summary_text(self) -> str | None:
        """The summary as ``cargo xtask demo`` prints it, once stopped; else ``None``."""

def run_virtual(
    scene: Scene,
    seconds: float,
    device: _Device | None = None,
    integrator: _IntegratorName | str = "backward_euler",
    backend: _BackendName | str = "lod",
    contact_rate_hz: float | None = None,
) -> Run:
    """Runs the scene's pipeline in virtual time: one thread, simulated clock, deterministic
    (the same call gives the same arrays, bit for bit), as ``cargo xtask demo --virtual-time``.
    The GIL is released while it runs (and taken back for each call of a callable device).

    Args:
        scene: the scene.
        seconds: how long (simulated seconds); ``seconds × haptic rate`` steps.
        device: ``None`` (the scene's simulated hand following its waypoints), ``(times (k,),
            poses (k, 7))`` (a scripted handle through those poses) or a callable
            ``t (s) -> pose`` (a NaN in the pose it returns is a bad reading: that step sends
            zero force).
        integrator: ``"backward_euler"`` (the linearized backward Euler; alias
            ``"linearized_backward_euler"``), ``"newton_backward_euler"``, ``"rk4"`` or
            ``"forward_euler"``.
        backend: ``"lod"`` or ``"parry"``.
        contact_rate_hz: contact updates per simulated second (``None``: the scene's, else
            250 Hz).

    Raises:
        InputError: a negative or non-finite ``seconds``, an unknown integrator or back-end, a
            device of the wrong shape.
        PipelineError: a run that stopped (a callable that raised: chained as ``__cause__``;
            ``.summary`` holds the run up to the stop).
        DeviceError: a device that failed.
    """

def run_realtime(
    scene: Scene,
    seconds: float,
    integrator: _IntegratorName | str = "backward_euler",
    backend: _BackendName | str = "lod",
) -> RealtimeResult:
    """Runs the scene in real time with the scene's simulated hand, as ``cargo xtask demo``: the
    haptic thread at the scene's rate on the wall clock, the contact thread as fast as it runs.
    The GIL is released while it runs.

    Raises:
        InputError: a bad ``seconds``, integrator or back-end.
        PipelineError: a run that stopped (``.summary`` holds the run up to the stop).
    """
