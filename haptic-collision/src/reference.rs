//! A brute-force reference back-end: every tool triangle against every obstacle triangle, with
//! the same contact per pair (`slab.rs`) and the same closest approach
//! ([`crate::geometry::triangle_pair`]) as [`crate::lod::LodBackend`] at error threshold 0 with
//! every contact written (`with_max_contacts(None)`). Quadratic in the triangle counts: for tests
//! on small meshes only.

use haptic_core::{CollisionBackend, ContactSet, Pose, QueryParams, QueryStats, Real, Vec3};

use crate::geometry::{PairContact, triangle_normal, triangle_pair};
use crate::lod::LodError;
use crate::lod::closest::touching_if_crossing;
use crate::lod::query::Frames;
use crate::mesh::TriMesh;
use crate::slab::{HeightOffset, pair_region};

/// Triangles of one mesh with their unit normals (mesh frame).
#[derive(Debug, Clone)]
struct Soup {
    tris: Vec<[Vec3; 3]>,
    normals: Vec<Vec3>,
}

impl Soup {
    fn of(mesh: &TriMesh) -> Self {
        let tris: Vec<[Vec3; 3]> = (0..mesh.triangles().len())
            .map(|t| mesh.triangle(t))
            .collect();
        let normals = tris
            .iter()
            .map(|t| triangle_normal(t).unwrap_or_else(Vec3::z))
            .collect();
        Self { tris, normals }
    }
}

/// All-triangle-pairs collision detection (see the module docs). Ignores the error threshold.
#[derive(Debug, Clone)]
pub struct ReferenceBackend {
    tool: Soup,
    radius_m: Real,
    obstacles: Vec<(Soup, Pose)>,
}

impl ReferenceBackend {
    /// The tool (body frame) and static obstacles (placed at their poses).
    ///
    /// # Errors
    /// [`LodError::NonFinitePose`] for a non-finite obstacle pose;
    /// [`LodError::InconsistentWinding`] for a mesh whose triangles are wound against their
    /// neighbours, [`LodError::CoincidentTriangles`] for one with triangles on the same
    /// vertices as another.
    pub fn new(tool: &TriMesh, obstacles: &[(TriMesh, Pose)]) -> Result<Self, LodError> {
        if obstacles.iter().any(|(_, p)| !p.is_finite()) {
            return Err(LodError::NonFinitePose {
                what: "obstacle pose",
            });
        }
        crate::lod::check_surfaces(tool, obstacles)?;
        Ok(Self {
            tool: Soup::of(tool),
            radius_m: tool
                .vertices()
                .iter()
                .map(|v| v.norm())
                .fold(0.0, Real::max),
            obstacles: obstacles.iter().map(|(m, p)| (Soup::of(m), *p)).collect(),
        })
    }
}

impl CollisionBackend for ReferenceBackend {
    type Error = LodError;

    fn name(&self) -> &str {
        "reference"
    }

    fn tool_bounding_radius_m(&self) -> Real {
        self.radius_m
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
        let mut stats = QueryStats {
            broad_phase_hit: true,
            ..QueryStats::default()
        };
        let delta = params.delta_m;
        for (obs, pose) in &self.obstacles {
            let frames = Frames::new(tool_pose, pose);
            // The smallest distance written, and the exact closest approach within δ.
            let mut written = Real::INFINITY;
            let mut closest: Option<PairContact> = None;
            for (ta, (tri_a, n_a)) in self.tool.tris.iter().zip(&self.tool.normals).enumerate() {
                let a = tri_a.map(|v| frames.point(&v));
                let na = frames.rot * n_a;
                for (tb, (b, nb)) in obs.tris.iter().zip(&obs.normals).enumerate() {
                    stats.primitive_pairs_tested += 1;
                    let regions = pair_region(&a, b, nb, delta, HeightOffset::NONE);
                    if let Some(r) = regions.region {
                        let pc = r.pair_contact(nb);
                        frames.emit(&pc, ta as u32, tb as u32, r.area_m2, out)?;
                        written = written.min(pc.distance);
                    }
                    let pc = triangle_pair(&a, &na, b, nb);
                    if pc.depth >= -delta && closest.is_none_or(|c| pc.distance < c.distance) {
                        closest = Some(pc);
                    }
                }
            }
            if let Some(pc) = closest
                && pc.distance < written
            {
                frames.emit_closest_approach(&touching_if_crossing(pc), delta, out)?;
            }
        }
        Ok(stats)
    }
}
