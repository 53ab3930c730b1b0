//! Mass properties of the uniform-density solid a mesh bounds (divergence theorem).

use haptic_core::{CoreError, Mat3, Real, RigidBody, Vec3};

use super::{MeshError, TriMesh};

/// Largest relative change of the volume, when the origin of the divergence integral moves by
/// the bounding-box diagonal, that an open mesh may show and still get mass properties (1 %).
pub const OPEN_MESH_VOLUME_TOL: Real = 0.01;

/// Mass properties of a uniform-density solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    /// Enclosed volume (m³).
    pub volume_m3: Real,
    /// Mass (kg) = density × volume.
    pub mass_kg: Real,
    /// Centre of mass, in the mesh's frame (m).
    pub centre_of_mass_m: Vec3,
    /// Inertia tensor about the centre of mass, mesh axes (kg·m²).
    pub inertia_about_com: Mat3,
    /// Edges used by exactly one triangle: 0 for a closed mesh.
    pub boundary_edges: usize,
    /// For an open mesh, the relative change of the volume when the integration origin moves by
    /// the bounding-box diagonal (how much the holes matter; at most
    /// [`OPEN_MESH_VOLUME_TOL`]). 0 for a closed mesh.
    pub open_volume_change_rel: Real,
}

impl MassProperties {
    /// The rigid body with this mass and inertia (body frame = the mesh frame moved to the centre
    /// of mass, axes unchanged).
    ///
    /// # Errors
    /// As [`RigidBody::new`] (non-finite or non-positive-definite inertia).
    pub fn rigid_body(&self) -> Result<RigidBody, CoreError> {
        RigidBody::new(self.mass_kg, self.inertia_about_com)
    }
}

/// Volume, first moment and second moment `∫ x xᵀ` of the solid, with the divergence theorem as
/// a sum of signed tetrahedra `(origin, a, b, c)`, coordinates relative to `origin`.
fn integrals(mesh: &TriMesh, origin: &Vec3) -> (Real, Vec3, Mat3) {
    let (mut vol, mut first, mut second) = (0.0, Vec3::zeros(), Mat3::zeros());
    for t in 0..mesh.triangles().len() {
        let [a, b, c] = mesh.triangle(t).map(|p| p - origin);
        let d = a.dot(&b.cross(&c)) / 6.0;
        vol += d;
        let sum = a + b + c;
        first += sum * (d / 4.0);
        // ∫ x xᵀ over the tetrahedron (0, a, b, c) = V/20 (a aᵀ + b bᵀ + c cᵀ + s sᵀ).
        second +=
            (a * a.transpose() + b * b.transpose() + c * c.transpose() + sum * sum.transpose())
                * (d / 20.0);
    }
    (vol, first, second)
}

impl TriMesh {
    /// Mass properties of the solid this mesh bounds, filled with a uniform density.
    ///
    /// The divergence theorem turns the volume integrals into a sum over the triangles of signed
    /// tetrahedra with a common apex, here the bounding-box centre. For a closed mesh (every edge
    /// shared by two triangles; several closed shells are fine) the result is exact and
    /// independent of the apex.
    ///
    /// **Open meshes (documented approximation):** with holes the sum depends on the apex: the
    /// holes are in effect closed by cones to the apex. The integral is evaluated again with the
    /// apex moved by the bounding-box diagonal; if the volume changes by at most
    /// [`OPEN_MESH_VOLUME_TOL`] (the Newell teaspoon's two slits: 0.16 %), the figures from the
    /// bounding-box centre are returned, with [`MassProperties::boundary_edges`] and
    /// [`MassProperties::open_volume_change_rel`] set so that the caller can see it; otherwise
    /// the mesh is rejected.
    ///
    /// # Errors
    /// [`MeshError::BadParameter`] for a density that is not positive and finite;
    /// [`MeshError::OpenMesh`] for an open mesh whose holes matter;
    /// [`MeshError::NonPositiveVolume`] for inward-facing triangles or a flat mesh.
    pub fn mass_properties(&self, density_kg_per_m3: Real) -> Result<MassProperties, MeshError> {
        if !(density_kg_per_m3 > 0.0 && density_kg_per_m3.is_finite()) {
            return Err(MeshError::BadParameter {
                what: "density_kg_per_m3",
                value: density_kg_per_m3,
                expected: "positive and finite",
            });
        }
        let (lo, hi) = self.bounding_box();
        let origin = (lo + hi) * 0.5;
        let (vol, first, second) = integrals(self, &origin);
        let boundary_edges = self.boundary_edge_count();
        let mut open_volume_change_rel = 0.0;
        if boundary_edges > 0 {
            let (vol2, _, _) = integrals(self, &(origin + (hi - lo)));
            open_volume_change_rel = if vol != 0.0 {
                ((vol2 - vol) / vol).abs()
            } else {
                Real::INFINITY
            };
            if open_volume_change_rel.is_nan() || open_volume_change_rel > OPEN_MESH_VOLUME_TOL {
                return Err(MeshError::OpenMesh {
                    boundary_edges,
                    volume_change_rel: open_volume_change_rel,
                });
            }
        }
        // A volume below 1e-12 of the bounding box's counts as none (a flat mesh).
        let extent = hi - lo;
        let box_volume = extent.x.max(1e-300) * extent.y.max(1e-300) * extent.z.max(1e-300);
        if vol.is_nan() || vol <= 1e-12 * box_volume {
            return Err(MeshError::NonPositiveVolume { volume_m3: vol });
        }
        let com_rel = first / vol;
        // Second moment about the centre of mass, then the inertia tensor.
        let s = (second - com_rel * com_rel.transpose() * vol) * density_kg_per_m3;
        let inertia = Mat3::identity() * s.trace() - s;
        Ok(MassProperties {
            volume_m3: vol,
            mass_kg: vol * density_kg_per_m3,
            centre_of_mass_m: origin + com_rel,
            inertia_about_com: (inertia + inertia.transpose()) * 0.5,
            boundary_edges,
            open_volume_change_rel,
        })
    }
}
