//! `ParryBackend`: collision detection by parry3d-f64's triangle-mesh contact manifolds (cargo
//! feature `parry`, on by default).
//!
//! Both meshes become parry `TriMesh`es built with `TriMeshFlags::FIX_INTERNAL_EDGES` (parry's
//! pseudo-normal cones, which remove the bumps of contacts on internal edges). A query runs a
//! broad phase (bounding spheres inflated by `δ`), then parry's composite–composite contact
//! manifolds with prediction `δ`: parry walks both AABB trees, and for each pair of triangles
//! whose inflated AABBs overlap computes a manifold (GJK closest points or EPA penetration, then
//! feature clipping). Each manifold point becomes one [`Contact`]: `p_a` on the tool triangle,
//! `p_b` on the obstacle triangle, `n` parry's normal out of the tool, `depth_m = −dist`.
//!
//! **What its depth means.** Parry's depth is per triangle pair: for two intersecting triangles
//! it is the penetration depth of those two triangles alone (EPA), along a normal that
//! `FIX_INTERNAL_EDGES` may bend into the triangles' pseudo-normal cones (the distance is then
//! measured along the bent normal between the clipped features). It never measures how deep one
//! *solid* is inside the other: a deep penetration, where no triangle pair is close, is not seen
//! (the same holds for [`crate::LodBackend`], whose depth is the separating-axis depth of the
//! triangle pair; see docs/decisions.md). Pairs whose closest direction lies behind a triangle
//! (outside its front cone) give no contact at all.
//!
//! Parry's own temporal coherence (reusing last query's manifold points while the pose changes
//! by less than 1° and 1 mm) is switched off: every query recomputes every manifold, so results
//! do not depend on the previous query. Cost on the shared jaws (47 k and 40 k triangles, 2-core
//! machine, release): about 9 ms for a small patch (40 triangle pairs within δ = 0.5 mm), 55 ms
//! for the ring of contacts of the jaws in occlusion at δ = 0.5 mm, 190 ms at δ = 1 mm; building
//! both meshes takes about 0.1 s.

use crate::area::{AreaSplit, triangle_area};
use std::time::Instant;

use parry3d_f64::math::{Pose as PPose, Vector as PVec};
use parry3d_f64::query::{
    ContactManifold, ContactManifoldsWorkspace, DefaultQueryDispatcher, PersistentQueryDispatcher,
};
use parry3d_f64::shape::{TriMesh as PTriMesh, TriMeshFlags};

use haptic_core::{
    CollisionBackend, Contact, ContactSet, CoreError, Pose, QueryParams, QueryStats, Real, Vec3,
};

use crate::mesh::TriMesh;

/// Errors of the parry back-end.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParryError {
    /// A pose had NaN or Inf components.
    #[error("{what} is not finite")]
    NonFinitePose {
        /// Which pose.
        what: &'static str,
    },
    /// Parry refused to build a mesh.
    #[error("parry could not build a mesh: {0}")]
    Build(String),
    /// Parry does not support this pair of shapes (not expected for two triangle meshes).
    #[error("parry does not support this shape pair")]
    Unsupported,
    /// A core check failed: query parameters out of range ([`QueryParams::validate`]), or a
    /// contact that could not be formed (non-finite geometry).
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// Construction options of [`ParryBackend`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParryOptions {
    /// Build the meshes with `TriMeshFlags::FIX_INTERNAL_EDGES` (default `true`). Without it
    /// parry reports every triangle pair closer than `δ` with its exact closest points (what
    /// the parity test against [`crate::LodBackend`] at threshold 0 compares); with it, pairs
    /// whose closest direction leaves a triangle's pseudo-normal cone are bent or dropped.
    pub fix_internal_edges: bool,
}

impl Default for ParryOptions {
    fn default() -> Self {
        Self {
            fix_internal_edges: true,
        }
    }
}

/// One obstacle: its parry mesh, pose, bounding sphere (mesh frame) and persistent buffers.
struct Obstacle {
    mesh: PTriMesh,
    pose: Pose,
    pose_p: PPose,
    center: Vec3,
    radius: Real,
    manifolds: Vec<ContactManifold<(), ()>>,
    workspace: Option<ContactManifoldsWorkspace>,
}

/// Collision detection with parry3d-f64 (see the module docs).
pub struct ParryBackend {
    tool: PTriMesh,
    tool_center: Vec3,
    tool_sphere_radius: Real,
    tool_radius_about_origin: Real,
    /// Area of each tool triangle (m²), for the contacts' `area_m2`.
    tool_areas_m2: Vec<Real>,
    split: AreaSplit,
    obstacles: Vec<Obstacle>,
    build_s: Real,
}

impl std::fmt::Debug for ParryBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ParryBackend")
            .field("tool_triangles", &self.tool.num_triangles())
            .field("obstacles", &self.obstacles.len())
            .field("build_s", &self.build_s)
            .finish()
    }
}

fn to_p(v: &Vec3) -> PVec {
    PVec::new(v.x, v.y, v.z)
}

fn from_p(v: &PVec) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

fn pose_to_p(p: &Pose) -> PPose {
    let q = p.orientation.quaternion();
    PPose::from_parts(
        to_p(&p.position),
        parry3d_f64::math::Rotation::from_xyzw(q.i, q.j, q.k, q.w).normalize(),
    )
}

fn build(mesh: &TriMesh, options: &ParryOptions) -> Result<PTriMesh, ParryError> {
    let flags = if options.fix_internal_edges {
        TriMeshFlags::FIX_INTERNAL_EDGES
    } else {
        TriMeshFlags::empty()
    };
    PTriMesh::with_flags(
        mesh.vertices().iter().map(to_p).collect(),
        mesh.triangles().to_vec(),
        flags,
    )
    .map_err(|e| ParryError::Build(format!("{e:?}")))
}

/// Centre and radius of a sphere around the mesh (bounding-box centre).
fn sphere(mesh: &TriMesh) -> (Vec3, Real) {
    let (lo, hi) = mesh.bounding_box();
    let c = (lo + hi) * 0.5;
    let r = mesh
        .vertices()
        .iter()
        .map(|v| (v - c).norm())
        .fold(0.0, Real::max);
    (c, r)
}

impl ParryBackend {
    /// Builds parry meshes (with `FIX_INTERNAL_EDGES`) of the tool, in its body frame, and of the
    /// static obstacles, each placed at its pose in the world.
    ///
    /// # Errors
    /// [`ParryError::NonFinitePose`] for a non-finite obstacle pose, [`ParryError::Build`] if
    /// parry rejects a mesh.
    pub fn new(tool: &TriMesh, obstacles: &[(TriMesh, Pose)]) -> Result<Self, ParryError> {
        Self::with_options(tool, obstacles, &ParryOptions::default())
    }

    /// As [`ParryBackend::new`], with options.
    ///
    /// # Errors
    /// As [`ParryBackend::new`].
    pub fn with_options(
        tool: &TriMesh,
        obstacles: &[(TriMesh, Pose)],
        options: &ParryOptions,
    ) -> Result<Self, ParryError> {
        let start = Instant::now();
        if obstacles.iter().any(|(_, p)| !p.is_finite()) {
            return Err(ParryError::NonFinitePose {
                what: "obstacle pose",
            });
        }
        let (tool_center, tool_sphere_radius) = sphere(tool);
        let tool_radius_about_origin = tool
            .vertices()
            .iter()
            .map(|v| v.norm())
            .fold(0.0, Real::max);
        let tool_p = build(tool, options)?;
        let obstacles = obstacles
            .iter()
            .map(|(m, pose)| {
                let (center, radius) = sphere(m);
                Ok(Obstacle {
                    mesh: build(m, options)?,
                    pose: *pose,
                    pose_p: pose_to_p(pose),
                    center,
                    radius,
                    manifolds: Vec::new(),
                    workspace: None,
                })
            })
            .collect::<Result<Vec<_>, ParryError>>()?;
        let tool_areas_m2: Vec<Real> = (0..tool.triangles().len())
            .map(|t| triangle_area(&tool.triangle(t)))
            .collect();
        Ok(Self {
            split: AreaSplit::new(tool_areas_m2.len()),
            tool_areas_m2,
            tool: tool_p,
            tool_center,
            tool_sphere_radius,
            tool_radius_about_origin,
            obstacles,
            build_s: start.elapsed().as_secs_f64(),
        })
    }

    /// Wall-clock time of [`ParryBackend::new`] (s).
    pub fn build_s(&self) -> Real {
        self.build_s
    }
}

impl CollisionBackend for ParryBackend {
    type Error = ParryError;

    fn name(&self) -> &str {
        "parry"
    }

    fn tool_bounding_radius_m(&self) -> Real {
        self.tool_radius_about_origin
    }

    /// Contacts of the tool at `tool_pose` (the error threshold is ignored: parry has no levels
    /// of detail). `feature_a`/`feature_b` are the tool and obstacle triangle indices; each
    /// contact stands for its share of its tool triangle's area (`area_m2`).
    fn query(
        &mut self,
        tool_pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, ParryError> {
        out.clear();
        params.validate()?;
        if !tool_pose.is_finite() {
            return Err(ParryError::NonFinitePose { what: "tool pose" });
        }
        let delta = params.delta_m;
        let mut stats = QueryStats::default();
        let tool_p = pose_to_p(tool_pose);
        let rot = tool_pose.orientation.to_rotation_matrix();
        let tool_c = tool_pose.transform_point(&self.tool_center);
        for obs in &mut self.obstacles {
            let reach = self.tool_sphere_radius + obs.radius + delta;
            if (tool_c - obs.pose.transform_point(&obs.center)).norm_squared() > reach * reach {
                continue;
            }
            stats.broad_phase_hit = true;
            // Exact answers every query: disable parry's reuse of last query's points.
            for m in &mut obs.manifolds {
                m.mark_shapes_deformed();
            }
            let pos12 = tool_p.inv_mul(&obs.pose_p);
            DefaultQueryDispatcher
                .contact_manifolds(
                    &pos12,
                    &self.tool,
                    &obs.mesh,
                    delta,
                    &mut obs.manifolds,
                    &mut obs.workspace,
                )
                .map_err(|_| ParryError::Unsupported)?;
            stats.primitive_pairs_tested += obs.manifolds.len() as u64;
            for m in &obs.manifolds {
                let n = rot * from_p(&m.local_n1);
                let len = n.norm();
                if len.is_nan() || len <= 0.5 {
                    continue;
                }
                let n = n / len;
                for pt in &m.points {
                    if pt.dist > delta {
                        continue;
                    }
                    let r_a = from_p(&pt.local_p1);
                    let p_a = tool_pose.transform_point(&r_a);
                    let p_b = obs.pose.transform_point(&from_p(&pt.local_p2));
                    let area = self
                        .tool_areas_m2
                        .get(m.subshape1 as usize)
                        .copied()
                        .unwrap_or(0.0);
                    let c = Contact::new(p_a, r_a, p_b, n, -pt.dist)?
                        .with_features(m.subshape1, m.subshape2)
                        .with_area(area);
                    out.push(c);
                }
            }
        }
        // Each tool triangle's area shared among its contacts, as `LodBackend` does.
        self.split.split(out.as_mut_slice(), delta);
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use haptic_core::{CollisionBackend, ContactSet, Pose, QueryParams, Real, Vec3};
    use nalgebra::{UnitQuaternion, Vector3};
    use proptest::prelude::*;

    use super::{ParryBackend, ParryError, ParryOptions};
    use crate::geometry::{triangle_normal, triangle_pair};
    use crate::lod::testmesh::{bumpy_sphere, cuboid};
    use crate::mesh::TriMesh;
    use crate::reference::ReferenceBackend;

    const DELTA: Real = 2e-3;

    fn pairs(s: &ContactSet, below: Real) -> BTreeSet<(u32, u32)> {
        s.iter()
            .filter(|c| -c.depth_m < below)
            .map(|c| (c.feature_a, c.feature_b))
            .collect()
    }

    /// The (tool, obstacle) triangle pairs closer than `below`, the tool at `pose`.
    fn pairs_within(a: &TriMesh, b: &TriMesh, pose: &Pose, below: Real) -> BTreeSet<(u32, u32)> {
        let tri = |m: &TriMesh, t: usize, place: &dyn Fn(&Vec3) -> Vec3| {
            let v = m.triangle(t).map(|v| place(&v));
            let n = triangle_normal(&v).unwrap_or_else(Vec3::z);
            (v, n)
        };
        let mut out = BTreeSet::new();
        for ta in 0..a.triangles().len() {
            let (va, na) = tri(a, ta, &|v| pose.transform_point(v));
            for tb in 0..b.triangles().len() {
                let (vb, nb) = tri(b, tb, &|v| *v);
                if triangle_pair(&va, &na, &vb, &nb).distance < below {
                    out.insert((ta as u32, tb as u32));
                }
            }
        }
        out
    }

    fn min_distance(s: &ContactSet) -> Real {
        s.iter().map(|c| -c.depth_m).fold(Real::INFINITY, Real::min)
    }

    #[test]
    fn sphere_over_box_contact_convention() {
        let tool = bumpy_sphere(2, 0.02, 0.0, 1);
        let floor = cuboid(Vec3::new(0.1, 0.1, 0.01));
        let mut parry = ParryBackend::new(&tool, &[(floor, Pose::identity())]).unwrap();
        // Sphere bottom 0.5 mm above the box top (z = 0.01); the icosphere's lowest point is a
        // vertex at −0.02·(something ≤ 1); place it by its lowest vertex.
        let lowest = tool
            .vertices()
            .iter()
            .map(|v| v.z)
            .fold(Real::INFINITY, Real::min);
        let pose = Pose::from_position(Vec3::new(0.0, 0.0, 0.01 + 5e-4 - lowest));
        let mut out = ContactSet::new();
        let st = parry
            .query(&pose, &QueryParams::new(DELTA, 0.0).unwrap(), &mut out)
            .unwrap();
        assert!(st.broad_phase_hit && !out.is_empty());
        let deepest = out
            .iter()
            .max_by(|a, b| a.depth_m.total_cmp(&b.depth_m))
            .unwrap();
        assert!((deepest.depth_m + 5e-4).abs() < 1e-9, "{}", deepest.depth_m);
        assert!(
            (deepest.n - Vec3::new(0.0, 0.0, -1.0)).norm() < 1e-6,
            "{:?}",
            deepest.n
        );
        assert!((deepest.p_a - deepest.p_b - deepest.n * deepest.depth_m).norm() < 1e-9);
        assert!((pose.transform_point(&deepest.r_a) - deepest.p_a).norm() < 1e-12);
        for c in &out {
            assert!(c.depth_m >= -DELTA);
        }
        // Far away: nothing, and the broad phase says so.
        let far = Pose::from_position(Vec3::new(1.0, 0.0, 0.0));
        let st = parry
            .query(&far, &QueryParams::new(DELTA, 0.0).unwrap(), &mut out)
            .unwrap();
        assert!(!st.broad_phase_hit && out.is_empty());
    }

    #[test]
    fn bad_poses_and_params_are_errors() {
        let m = cuboid(Vec3::repeat(0.01));
        let bad = Pose::from_position(Vec3::new(Real::NAN, 0.0, 0.0));
        assert!(matches!(
            ParryBackend::new(&m, &[(m.clone(), bad)]),
            Err(ParryError::NonFinitePose { .. })
        ));
        let mut p = ParryBackend::new(&m, &[(m.clone(), Pose::identity())]).unwrap();
        let mut out = ContactSet::new();
        let params = QueryParams::new(DELTA, 0.0).unwrap();
        assert!(matches!(
            p.query(&bad, &params, &mut out),
            Err(ParryError::NonFinitePose { .. })
        ));
        let mut neg = params;
        neg.delta_m = -1.0;
        assert!(matches!(
            p.query(&Pose::identity(), &neg, &mut out),
            Err(ParryError::Core(haptic_core::CoreError::OutOfRange { .. }))
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Two bumpy spheres apart by less than δ: parry without `FIX_INTERNAL_EDGES` gives
        /// the reference's minimum distance and its set of triangle pairs closer than δ; with
        /// it, a minimum distance never nearer than that and still within δ, and a subset of
        /// the pairs.
        #[test]
        fn parry_agrees_with_the_reference_when_apart(
            seed in 0u64..500,
            dir in prop::array::uniform3(-1.0f64..1.0),
            axis in prop::array::uniform3(-1.0f64..1.0),
            angle in -3.0f64..3.0,
        ) {
            let u = Vector3::from(dir);
            prop_assume!(u.norm() > 0.1);
            let u = u.normalize();
            let a = bumpy_sphere(2, 0.02, 0.1, seed);
            let b = bumpy_sphere(2, 0.03, 0.1, seed + 1);
            let rot = UnitQuaternion::from_scaled_axis(Vector3::from(axis) * angle);
            let mut reference = ReferenceBackend::new(&a, &[(b.clone(), Pose::identity())]).unwrap();
            let mut out = ContactSet::new();
            // Start 3 mm beyond touching spheres of the nominal radii, then close the gap to
            // about δ/2 (distance is 1-Lipschitz in the translation).
            let mut offset = 0.05 * 1.1 + 3e-3;
            let wide = QueryParams::new(0.02, 0.0).unwrap();
            for _ in 0..4 {
                let pose = Pose { position: u * offset, orientation: rot };
                reference.query(&pose, &wide, &mut out).unwrap();
                let g = min_distance(&out);
                prop_assume!(g.is_finite() && g > 0.0);
                offset -= g - DELTA / 2.0;
            }
            let pose = Pose { position: u * offset, orientation: rot };
            let params = QueryParams::new(DELTA, 0.0).unwrap();
            reference.query(&pose, &params, &mut out).unwrap();
            let g = min_distance(&out);
            prop_assume!(g > 0.0 && g < DELTA);
            // The triangle pairs within δ, by brute force (the reference writes one contact per
            // pair with a part over the other, not one per pair within δ).
            let exact = pairs_within(&a, &b, &pose, DELTA - 1e-9);
            let exact_loose = pairs_within(&a, &b, &pose, DELTA + 1e-9);

            let obstacles = [(b.clone(), Pose::identity())];
            let plain = ParryOptions { fix_internal_edges: false };
            let mut p = ParryBackend::with_options(&a, &obstacles, &plain).unwrap();
            let mut pout = ContactSet::new();
            p.query(&pose, &params, &mut pout).unwrap();
            prop_assert!((min_distance(&pout) - g).abs() < 1e-9, "{} vs {}", min_distance(&pout), g);
            let got = pairs(&pout, DELTA + 1e-9);
            prop_assert!(exact.is_subset(&got) && got.is_subset(&exact_loose));

            let mut fixed = ParryBackend::new(&a, &obstacles).unwrap();
            fixed.query(&pose, &params, &mut pout).unwrap();
            // Where the closest features meet at an internal edge, `FIX_INTERNAL_EDGES` bends
            // the normal or drops the pair (module docs): the minimum it reports is never
            // nearer than the true one, and still within δ. Over 1,500 cases it was the true
            // one to 3e-14 but in two, 3.5e-4 and 1.7e-3 farther (both kept in
            // `proptest-regressions/parry.txt`); a tolerance on how much farther is a matter of
            // the mesh, not of parry.
            let fixed_g = min_distance(&pout);
            prop_assert!(fixed_g >= g * (1.0 - 1e-9), "fixed: {} nearer than {}", fixed_g, g);
            prop_assert!(fixed_g < DELTA, "fixed: {} not within δ", fixed_g);
            prop_assert!(pairs(&pout, DELTA + 1e-9).is_subset(&exact_loose));
        }
    }
}
