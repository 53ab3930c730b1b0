//! Triangle meshes: validated storage (loaders and mass properties are added beside it).

use haptic_core::{Real, Vec3};

/// Errors of mesh construction and loading.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// The mesh has no triangle.
    #[error("mesh is empty")]
    Empty,
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {index} has a non-finite coordinate")]
    NonFiniteVertex {
        /// Index of the vertex.
        index: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {vertex}, but there are {vertex_count} vertices")]
    IndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The bad vertex index.
        vertex: u64,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// Degenerate (zero-area or repeated-vertex) triangles were found and the policy rejects them.
    #[error("{count} degenerate triangles (first: {first})")]
    DegenerateTriangles {
        /// How many.
        count: usize,
        /// Index of the first one.
        first: usize,
    },
}

/// A validated triangle mesh: vertices (m) and counter-clockwise triangles (outward normals).
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    vertices: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

/// What to do with degenerate triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DegeneratePolicy {
    /// Drop them (and report how many were dropped).
    #[default]
    Drop,
    /// Reject the mesh with [`MeshError::DegenerateTriangles`].
    Reject,
}

/// Relative area below which a triangle counts as degenerate: `|e1 × e2| <= tol · (|e1|² + |e2|²)`.
pub const DEGENERATE_REL_TOL: Real = 1e-12;

impl TriMesh {
    /// A validated mesh. Returns the mesh and the number of degenerate triangles dropped.
    ///
    /// # Errors
    /// [`MeshError::Empty`], [`MeshError::NonFiniteVertex`], [`MeshError::IndexOutOfRange`], and
    /// [`MeshError::DegenerateTriangles`] under [`DegeneratePolicy::Reject`] (or when every
    /// triangle is degenerate, as [`MeshError::Empty`] after dropping).
    pub fn new(
        vertices: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        policy: DegeneratePolicy,
    ) -> Result<(Self, usize), MeshError> {
        if triangles.is_empty() || vertices.is_empty() {
            return Err(MeshError::Empty);
        }
        if let Some(index) = vertices
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(MeshError::NonFiniteVertex { index });
        }
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                if v as usize >= vertices.len() {
                    return Err(MeshError::IndexOutOfRange {
                        triangle: t,
                        vertex: v as u64,
                        vertex_count: vertices.len(),
                    });
                }
            }
        }
        let degenerate = |tri: &[u32; 3]| {
            let [a, b, c] = tri.map(|i| vertices[i as usize]);
            let (e1, e2) = (b - a, c - a);
            tri[0] == tri[1]
                || tri[1] == tri[2]
                || tri[0] == tri[2]
                || e1.cross(&e2).norm()
                    <= DEGENERATE_REL_TOL * (e1.norm_squared() + e2.norm_squared())
        };
        let count = triangles.iter().filter(|t| degenerate(t)).count();
        let triangles = if count == 0 {
            triangles
        } else {
            match policy {
                DegeneratePolicy::Reject => {
                    let first = triangles.iter().position(degenerate).unwrap_or(0);
                    return Err(MeshError::DegenerateTriangles { count, first });
                }
                DegeneratePolicy::Drop => {
                    triangles.into_iter().filter(|t| !degenerate(t)).collect()
                }
            }
        };
        if triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        Ok((
            Self {
                vertices,
                triangles,
            },
            count,
        ))
    }

    /// Vertices (m).
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The three corners of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }
}
