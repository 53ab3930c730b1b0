//! Remeshed copies of a mesh: the same surface, another tessellation, so that a scene from the
//! repository's meshes can be measured against itself tessellated otherwise
//! (`tessellation_error_rel`) and the error goals checked on tessellations nothing was tuned on.

use std::collections::HashMap;

use haptic_collision::TriMesh;
use haptic_core::Vec3;

use super::{build, ensure_indexable};

/// `mesh` with each triangle split into four at its edges' midpoints (shared by the two
/// triangles of an edge, so a closed mesh stays closed): the same surface, four times the
/// triangles, each similar to the one it splits.
///
/// # Errors
/// Too many vertices for `u32` indices, or a degenerate triangle (none where `mesh` has none).
pub fn split_at_midpoints(mesh: &TriMesh) -> anyhow::Result<TriMesh> {
    let mut vertices: Vec<Vec3> = mesh.vertices().to_vec();
    ensure_indexable(vertices.len() + 3 * mesh.triangles().len())?;
    let mut midpoints = HashMap::<(u32, u32), u32>::new();
    let mut midpoint = |a: u32, b: u32, vertices: &mut Vec<Vec3>| {
        *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
            vertices.push((vertices[a as usize] + vertices[b as usize]) * 0.5);
            (vertices.len() - 1) as u32
        })
    };
    let mut triangles = Vec::with_capacity(4 * mesh.triangles().len());
    for &[a, b, c] in mesh.triangles() {
        let ab = midpoint(a, b, &mut vertices);
        let bc = midpoint(b, c, &mut vertices);
        let ca = midpoint(c, a, &mut vertices);
        triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    build("midpoint-split", vertices, triangles)
}

/// `mesh` with each triangle split into three at its centroid: the same surface, three times
/// the triangles, thinner than the ones they split (a fan about each centroid, as meshing tools
/// and STL exporters leave).
///
/// # Errors
/// Too many vertices for `u32` indices, or a degenerate triangle (none where `mesh` has none).
pub fn split_at_centroids(mesh: &TriMesh) -> anyhow::Result<TriMesh> {
    let mut vertices: Vec<Vec3> = mesh.vertices().to_vec();
    ensure_indexable(vertices.len() + mesh.triangles().len())?;
    let mut triangles = Vec::with_capacity(3 * mesh.triangles().len());
    for &[a, b, c] in mesh.triangles() {
        let [pa, pb, pc] = [a, b, c].map(|i| vertices[i as usize]);
        vertices.push((pa + pb + pc) / 3.0);
        let m = (vertices.len() - 1) as u32;
        triangles.extend([[a, b, m], [b, c, m], [c, a, m]]);
    }
    build("centroid-split", vertices, triangles)
}
