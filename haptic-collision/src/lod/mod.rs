//! `LodBackend`: sensation-preserving multiresolution collision detection after Otaduy & Lin,
//! *Sensation preserving simplification for haptic rendering* (SIGGRAPH 2003), the paper's
//! ref. \[9\] (formulation.md, last section).
//!
//! Preprocessing ([`Hierarchy::build`]) turns each mesh into one binary hierarchy that is both a
//! bounding-volume hierarchy (spheres and slabs) and a level-of-detail hierarchy: every node
//! carries a simplified convex piece of the surface below it (a planar convex polygon, a leaf's
//! piece being its triangle) and the piece's surface deviation `s`, an upper bound on the
//! two-sided Hausdorff distance between piece and surface (every point of the node's triangles is
//! within `s` of the piece, and every point of the piece within `s` of the mesh surface).
//!
//! A query places the tool, runs a broad phase (root spheres inflated by `δ`), then walks the
//! tool's hierarchy against each obstacle's. A node pair is culled when its bounding volumes are
//! farther apart than `δ`; it stops when `s_a + s_b <= ε`, with `ε = error_threshold ×`
//! [`LodBackend::tool_bounding_radius_m`], or at two triangles; otherwise the node with the
//! larger deviation is split: that is the paper's rule, [`StoppingRule::Deviation`].
//! [`StoppingRule::DeviationAndCoherence`]
//! ([`LodBackend::with_stopping_rule`]) caps `ε` at `δ` and also bounds, where a pair writes a
//! contact, how many ways each piece's surface faces (its normal coherence, `stopping.rs`),
//! descending the pair otherwise; it drops a stopped pair only where the surfaces its pieces
//! stand for, not the pieces, are beyond `δ`. [`StoppingRule::CoherenceBudget`] holds that
//! bound for the regions' sum against the net force instead of region by region, refining
//! after the walk the regions that hold most of it (`refine.rs`); it is the default
//! (`docs/decisions.md`, "Stopping rule").
//!
//! A stopped pair writes one contact: the penalty integrated over the part of the tool piece
//! that lies over the obstacle piece within `δ` of its plane (`slab.rs`,
//! `docs/formulation.md` §7). Most stopped pairs lie beside each other, seen along the obstacle
//! piece's normal, so that no region comes of them: a ball about each piece (derived from the
//! pieces when a hierarchy is built or read) finds them before the tool piece is placed, and they
//! are dropped unless their balls are nearer than the nearest distance found so far. At two
//! triangles the integral is exact; a coarse pair integrates over its pieces with the heights
//! shifted and spread by where the surfaces they simplify lie about them (each node's
//! area-weighted mean and variance of height, `moments.rs`), and counts the share of its area
//! that the surface covers of the piece. After the walk, the pairs whose closest approach could
//! be closer than every contact written are searched, and the closest approach is written as a
//! contact of negligible area (`closest.rs`). Its distance is one between the surfaces, never
//! nearer than they are: where nothing else is written against the obstacle, the exact smallest
//! separation of the triangles under the pairs searched (the contact is then the call's only
//! one, and pushes with the whole stiffness); beside regions, the triangles' under the pair
//! whose pieces are nearest. When the exact surfaces are apart by `D` with `ε < D < δ − ε`, it
//! is within `ε` of `D`. At `error_threshold = 0` the walk descends to
//! triangle pairs and the contacts are exact (the same as
//! [`crate::reference::ReferenceBackend`]).
//!
//! Contact convention (haptic-core [`Contact`](haptic_core::Contact)): `p_a` on the tool, `p_b` on
//! the obstacle, `n` out of the tool (the obstacle piece's outward normal, reversed), and
//! `depth_m` the weighted mean depth of the region. The obstacle's faces are oriented: a tool
//! point below one (down to `δ`) is inside, with a positive depth. `feature_a` and `feature_b`
//! are the source triangle indices for triangle-pair contacts, and
//! [`NO_FEATURE`](haptic_core::NO_FEATURE) for contacts between coarse pieces and for the
//! closest approach.
//!
//! Compact contacts: when there are more than [`LodBackend::max_contacts`] (default
//! [`DEFAULT_MAX_CONTACTS`]), the contacts found are merged region by region into that many by
//! [`crate::compact::Compactor`], which keeps the sums the clustering reads and the deepest
//! contact. [`LodBackend::with_max_contacts`]`(None)` writes every contact found: the all-pairs
//! answer at threshold 0, the reference of the error metric.
//!
//! Hierarchies can be saved and read back ([`LodBackend::with_cache`], [`Hierarchy::write_to`],
//! [`Hierarchy::read_from`], [`LodBackend::with_hierarchies`]), keyed by the mesh's content and
//! the build's version ([`hierarchy_key`]); a file that does not hold is refused
//! ([`HierarchyFileError`]).

mod build;
mod cache;
pub(crate) mod closest;
mod deviation;
mod moments;
mod overhang;
mod quads;
pub(crate) mod query;
mod refine;
mod split;
mod stopping;
mod topology;

use std::time::Instant;

use rayon::prelude::*;

use haptic_core::{CollisionBackend, ContactSet, CoreError, Pose, QueryParams, QueryStats, Real};

pub use build::Hierarchy;
pub(crate) use build::ROUNDOFF_REL;
pub use cache::{CacheOutcome, FORMAT_VERSION, HierarchyFileError, hierarchy_key};
use closest::closest_approaches;
pub(crate) use moments::SurfaceMoments;
pub(crate) use overhang::Overhang;
use query::{Frames, Nearest, Scratch, Walk, collide};
pub use stopping::{StoppingRule, UnknownStoppingRule};

use crate::compact::Compactor;
use crate::mesh::TriMesh;

/// Most contacts a query writes by default ([`LodBackend::with_max_contacts`]).
pub const DEFAULT_MAX_CONTACTS: usize = 256;

/// Most vertices of a node's simplified convex piece.
pub const MAX_PIECE_VERTICES: usize = 6;

/// Errors of the multiresolution back-end.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LodError {
    /// A pose had NaN or Inf components.
    #[error("{what} is not finite")]
    NonFinitePose {
        /// Which pose.
        what: &'static str,
    },
    /// A mesh has more triangles than the hierarchy's 32-bit indices can address.
    #[error("mesh has {triangles} triangles, more than the hierarchy supports")]
    TooManyTriangles {
        /// Number of triangles.
        triangles: usize,
    },
    /// A mesh has triangles wound against their neighbours, whose inside and outside are
    /// swapped: the contacts on them would push the wrong way. [`TriMesh::load`] turns them by
    /// default ([`crate::LoadOptions::winding`]); [`TriMesh::with_consistent_winding`] does so on
    /// demand.
    #[error("the {} mesh has {conflicts} edges shared by triangles wound against each other (a triangle turned inside out makes three): repair it with TriMesh::with_consistent_winding", match obstacle { None => "tool".to_string(), Some(i) => format!("obstacle {i}") })]
    InconsistentWinding {
        /// Which mesh: `None` for the tool, else the obstacle's index.
        obstacle: Option<usize>,
        /// Shared edges along which both triangles run the same way
        /// ([`TriMesh::winding_conflicts`]).
        conflicts: usize,
    },
    /// A mesh has triangles on the same three vertices as another: a repeat, which pushes
    /// twice, or one wound the other way, a sheet with no inside whose two sides pull the tool
    /// through ([`TriMesh::coincident_triangles`]). [`TriMesh::load`] drops repeats; a thin part
    /// must be modelled with a thickness.
    #[error("the {} mesh has {duplicates} repeated triangles and {two_sided} pairs on the same vertices wound opposite ways (a sheet with no inside): drop repeats with TriMesh::without_duplicates, give a thin part a thickness", match obstacle { None => "tool".to_string(), Some(i) => format!("obstacle {i}") })]
    CoincidentTriangles {
        /// Which mesh: `None` for the tool, else the obstacle's index.
        obstacle: Option<usize>,
        /// Triangles wound the same way as an earlier one on the same vertices.
        duplicates: usize,
        /// Pairs on the same vertices wound opposite ways.
        two_sided: usize,
    },
    /// A core check failed: query parameters out of range ([`QueryParams::validate`]), or a
    /// contact that could not be formed (non-finite geometry).
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// Whether the tool's and the obstacles' surfaces say which side is outside:
/// [`LodError::InconsistentWinding`] for the first mesh whose triangles are wound against their
/// neighbours (`mesh/winding.rs`), [`LodError::CoincidentTriangles`] for the first with
/// triangles on the same vertices as another (`mesh/coincident.rs`).
pub(crate) fn check_surfaces(
    tool: &TriMesh,
    obstacles: &[(TriMesh, Pose)],
) -> Result<(), LodError> {
    let meshes = std::iter::once((None, tool))
        .chain(obstacles.iter().enumerate().map(|(i, (m, _))| (Some(i), m)));
    for (obstacle, mesh) in meshes {
        let conflicts = mesh.winding_conflicts();
        if conflicts > 0 {
            return Err(LodError::InconsistentWinding {
                obstacle,
                conflicts,
            });
        }
        let coincident = mesh.coincident_triangles();
        if !coincident.is_none() {
            return Err(LodError::CoincidentTriangles {
                obstacle,
                duplicates: coincident.duplicates,
                two_sided: coincident.two_sided,
            });
        }
    }
    Ok(())
}

/// Build figures of one mesh's hierarchy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshBuildStats {
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Nodes of the hierarchy.
    pub nodes: usize,
    /// Wall-clock build time (s).
    pub build_s: Real,
    /// Heap memory of the hierarchy (bytes).
    pub memory_bytes: usize,
}

impl MeshBuildStats {
    fn of(h: &Hierarchy) -> Self {
        Self {
            triangles: h.triangle_count(),
            nodes: h.node_count(),
            build_s: h.build_s(),
            memory_bytes: h.memory_bytes(),
        }
    }
}

/// Build figures of the whole back-end.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildStats {
    /// The tool's hierarchy.
    pub tool: MeshBuildStats,
    /// Each obstacle's hierarchy, in the order given.
    pub obstacles: Vec<MeshBuildStats>,
    /// Total wall-clock time of [`LodBackend::new`] (s).
    pub total_s: Real,
}

/// The native sensation-preserving multiresolution collision back-end (see the module docs).
#[derive(Debug, Clone)]
pub struct LodBackend {
    tool: Hierarchy,
    obstacles: Vec<(Hierarchy, Pose)>,
    scratch: Scratch,
    compactor: Compactor,
    max_contacts: Option<usize>,
    stopping_rule: StoppingRule,
    stats: BuildStats,
}

const MAX_TRIANGLES: usize = (u32::MAX / 4) as usize;

impl LodBackend {
    /// Builds the hierarchies of the tool (its body frame) and of the static obstacles, each placed
    /// at its pose in the world.
    ///
    /// # Errors
    /// [`LodError::NonFinitePose`] for a non-finite obstacle pose, [`LodError::TooManyTriangles`]
    /// for a mesh beyond 2³⁰ triangles, [`LodError::InconsistentWinding`] for a mesh whose
    /// triangles are wound against their neighbours, [`LodError::CoincidentTriangles`] for one
    /// with triangles on the same vertices as another.
    pub fn new(tool: &TriMesh, obstacles: &[(TriMesh, Pose)]) -> Result<Self, LodError> {
        let start = Instant::now();
        Self::check(tool, obstacles)?;
        // Both sides at once (each build is itself parallel; joining fills idle threads).
        let (tool, obstacles) = rayon::join(
            || Hierarchy::build(tool),
            || {
                obstacles
                    .par_iter()
                    .map(|(m, p)| (Hierarchy::build(m), *p))
                    .collect::<Vec<(Hierarchy, Pose)>>()
            },
        );
        Ok(Self::from_hierarchies(tool, obstacles, start))
    }

    /// The back-end of hierarchies already built ([`Hierarchy::build`]) or read back
    /// ([`Hierarchy::read_from`]): the tool's (its body frame) and each static obstacle's with
    /// its pose in the world. For an application that keeps hierarchies its own way (in an asset
    /// bundle, say) rather than in [`LodBackend::with_cache`]'s directory. The meshes they were
    /// built from are not checked here, as [`LodBackend::new`] checks them: build hierarchies
    /// of meshes wound consistently and with no triangle on the same vertices as another
    /// ([`TriMesh::winding_conflicts`] 0, [`TriMesh::coincident_triangles`] none).
    ///
    /// ```
    /// use haptic_collision::{LodBackend, TriMesh, DegeneratePolicy, lod::Hierarchy};
    /// use haptic_core::{Pose, Vec3};
    ///
    /// let v = [[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]];
    /// let vertices = v.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
    /// let triangles = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    /// let (mesh, _) = TriMesh::new(vertices, triangles, DegeneratePolicy::Reject)?;
    /// // Saved once…
    /// let mut bytes = Vec::new();
    /// Hierarchy::build(&mesh).write_to(&mut bytes, haptic_collision::lod::hierarchy_key(&mesh))?;
    /// // …and read back on every start.
    /// let tool = Hierarchy::read_from(&bytes[..], &mesh)?;
    /// let obstacle = Hierarchy::read_from(&bytes[..], &mesh)?;
    /// let backend = LodBackend::with_hierarchies(
    ///     tool,
    ///     vec![(obstacle, Pose::from_position(Vec3::new(0.05, 0.0, 0.0)))],
    /// )?;
    /// # let _ = backend;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`LodError::NonFinitePose`] for a non-finite obstacle pose, [`LodError::TooManyTriangles`]
    /// for a hierarchy of a mesh beyond 2³⁰ triangles.
    pub fn with_hierarchies(
        tool: Hierarchy,
        obstacles: Vec<(Hierarchy, Pose)>,
    ) -> Result<Self, LodError> {
        let start = Instant::now();
        for h in std::iter::once(&tool).chain(obstacles.iter().map(|(h, _)| h)) {
            if h.triangle_count() > MAX_TRIANGLES {
                return Err(LodError::TooManyTriangles {
                    triangles: h.triangle_count(),
                });
            }
        }
        if obstacles.iter().any(|(_, p)| !p.is_finite()) {
            return Err(LodError::NonFinitePose {
                what: "obstacle pose",
            });
        }
        Ok(Self::from_hierarchies(tool, obstacles, start))
    }

    /// The checks of [`LodBackend::new`] before anything is built.
    fn check(tool: &TriMesh, obstacles: &[(TriMesh, Pose)]) -> Result<(), LodError> {
        for mesh in std::iter::once(tool).chain(obstacles.iter().map(|(m, _)| m)) {
            if mesh.triangles().len() > MAX_TRIANGLES {
                return Err(LodError::TooManyTriangles {
                    triangles: mesh.triangles().len(),
                });
            }
        }
        if obstacles.iter().any(|(_, p)| !p.is_finite()) {
            return Err(LodError::NonFinitePose {
                what: "obstacle pose",
            });
        }
        check_surfaces(tool, obstacles)
    }

    /// The back-end of built (or loaded) hierarchies, with its query scratch reserved.
    fn from_hierarchies(
        tool: Hierarchy,
        obstacles: Vec<(Hierarchy, Pose)>,
        start: Instant,
    ) -> Self {
        // Every pop pushes at most two pairs and each split goes one level down one tree, so the
        // stack never holds more than height_a + height_b + 1 pairs: reserving that up front means
        // the walk never allocates (the list of coarse pairs grows to its largest size once).
        let stack_bound =
            tool.height() + obstacles.iter().map(|(h, _)| h.height()).max().unwrap_or(0) + 2;
        let obstacle_count = obstacles.len();
        let stats = BuildStats {
            tool: MeshBuildStats::of(&tool),
            obstacles: obstacles
                .iter()
                .map(|(h, _)| MeshBuildStats::of(h))
                .collect(),
            total_s: start.elapsed().as_secs_f64(),
        };
        Self {
            tool,
            obstacles,
            scratch: Scratch {
                stack: Vec::with_capacity(stack_bound),
                nearest: Vec::with_capacity(obstacle_count),
                frames: Vec::with_capacity(obstacle_count),
                ..Scratch::default()
            },
            compactor: Compactor::new(),
            max_contacts: Some(DEFAULT_MAX_CONTACTS),
            stopping_rule: StoppingRule::default(),
            stats,
        }
    }

    /// The same back-end writing at most `max` contacts a query (merged as the module docs say),
    /// or every contact found with `None` (at threshold 0, the all-pairs reference). `Some(0)`
    /// and `Some(1)` are taken as 2: the deepest contact and one merged region.
    pub fn with_max_contacts(mut self, max: Option<usize>) -> Self {
        self.max_contacts = max;
        self
    }

    /// Most contacts a query writes (`None`: every contact found).
    pub fn max_contacts(&self) -> Option<usize> {
        self.max_contacts
    }

    /// The same back-end stopping its walk by `rule` ([`StoppingRule`];
    /// [`StoppingRule::CoherenceBudget`] by default, the paper's is [`StoppingRule::Deviation`]).
    pub fn with_stopping_rule(mut self, rule: StoppingRule) -> Self {
        self.stopping_rule = rule;
        self
    }

    /// The walk's stopping rule.
    pub fn stopping_rule(&self) -> StoppingRule {
        self.stopping_rule
    }

    /// Build figures (time, node counts, memory).
    pub fn build_stats(&self) -> &BuildStats {
        &self.stats
    }

    /// Total nodes of all hierarchies.
    pub fn node_count(&self) -> usize {
        self.tool.node_count()
            + self
                .obstacles
                .iter()
                .map(|(h, _)| h.node_count())
                .sum::<usize>()
    }

    /// Heap memory held by the back-end (bytes).
    pub fn memory_bytes(&self) -> usize {
        self.tool.memory_bytes()
            + self
                .obstacles
                .iter()
                .map(|(h, _)| h.memory_bytes())
                .sum::<usize>()
            + self.scratch.stack.capacity() * std::mem::size_of::<(u32, u32)>()
            + self.scratch.apart.capacity() * std::mem::size_of::<(Real, u32, u32, u32)>()
            + self.scratch.written.capacity() * std::mem::size_of::<refine::Written>()
    }

    /// Capacity of the query's scratch buffers, in elements (they are reused between queries;
    /// tests check that they stop growing after warm-up).
    pub fn scratch_capacity(&self) -> usize {
        self.scratch.stack.capacity()
            + self.scratch.apart.capacity()
            + self.scratch.nearest.capacity()
            + self.scratch.frames.capacity()
            + self.scratch.written.capacity()
    }

    /// The tool's hierarchy.
    pub fn tool_hierarchy(&self) -> &Hierarchy {
        &self.tool
    }
}

impl CollisionBackend for LodBackend {
    type Error = LodError;

    fn name(&self) -> &str {
        "lod"
    }

    fn tool_bounding_radius_m(&self) -> Real {
        self.tool.radius_about_origin_m()
    }

    /// `params.error_threshold`, or under a rule that caps `ε` at `δ` (the default,
    /// [`StoppingRule::CoherenceBudget`], and [`StoppingRule::DeviationAndCoherence`]) at most
    /// `δ / radius`, the threshold that cap stands for.
    fn threshold_reached(&self, params: &QueryParams) -> Real {
        self.stopping_rule.threshold_reached(
            params.error_threshold,
            self.tool_bounding_radius_m(),
            params.delta_m,
        )
    }

    fn query(
        &mut self,
        tool_pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, LodError> {
        out.clear();
        params.validate()?;
        if !tool_pose.is_finite() {
            return Err(LodError::NonFinitePose { what: "tool pose" });
        }
        let mut stats = QueryStats::default();
        let radius_m = self.tool.radius_about_origin_m();
        let epsilon_m =
            self.stopping_rule
                .epsilon_m(params.error_threshold, radius_m, params.delta_m);
        let tool_root = self.tool.nodes[0];
        let tool_center_w = tool_pose.transform_point(&tool_root.center);
        self.scratch.frames.clear();
        self.scratch.nearest.clear();
        for (o, (obs, pose)) in self.obstacles.iter().enumerate() {
            let frames = Frames::new(tool_pose, pose);
            self.scratch.frames.push(frames);
            self.scratch.nearest.push(Nearest::NONE);
            // Broad phase: root spheres inflated by δ, in the world frame.
            let ob = &obs.nodes[0];
            let reach = tool_root.radius + ob.radius + params.delta_m;
            if (tool_center_w - pose.transform_point(&ob.center)).norm_squared() > reach * reach {
                continue;
            }
            stats.broad_phase_hit = true;
            let walk = Walk {
                tool: &self.tool,
                obs,
                obstacle: o as u32,
                frames: &frames,
                epsilon_m,
                delta_m: params.delta_m,
                min_coherence: self.stopping_rule.min_coherence(epsilon_m, radius_m),
                cull_at_surfaces: self.stopping_rule.culls_at_surfaces(),
                refine: self.stopping_rule.refines_regions(),
                weight_error_per_weight: Real::INFINITY,
                spread_height_m: self.stopping_rule.spread_height_m(params.delta_m),
            };
            collide(&walk, &mut self.scratch, out, &mut stats)?;
        }
        closest_approaches(
            &self.tool,
            &self.obstacles,
            params.delta_m,
            epsilon_m,
            &mut self.scratch,
            out,
            &mut stats,
        )?;
        if let Some(max) = self.max_contacts {
            let found = self.compactor.compact(out, tool_pose, params.delta_m, max);
            stats.raw_contacts = found as u64;
        }
        Ok(stats)
    }
}

#[cfg(test)]
pub(crate) mod testmesh;
#[cfg(test)]
mod tests;
