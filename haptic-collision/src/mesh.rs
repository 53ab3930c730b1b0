//! Triangle meshes: validated storage ([`TriMesh::new`]), loading from STL (binary and ASCII),
//! OBJ and PLY files ([`TriMesh::load`]), and the mass properties of the solid a closed mesh
//! bounds ([`TriMesh::mass_properties`]).

mod coincident;
mod load;
mod mass;
mod winding;

pub use coincident::CoincidentTriangles;
pub use load::{LoadOptions, LoadReport, MeshFormat, WindingPolicy};
pub use mass::{MassProperties, OPEN_MESH_VOLUME_TOL};

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
        /// The bad vertex index, 0-based (negative when a relative OBJ index or a signed PLY index
        /// points before the first vertex).
        vertex: i64,
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
    /// The file could not be opened or read (missing, no permission, I/O error).
    #[error("cannot read {path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// The kind of I/O error.
        kind: std::io::ErrorKind,
        /// The I/O error's message.
        message: String,
    },
    /// A binary STL file is shorter than its triangle count says.
    #[error(
        "truncated binary STL: {triangles} triangles need {expected_bytes} bytes, the file has {actual_bytes}"
    )]
    Truncated {
        /// Triangle count announced in the header.
        triangles: u64,
        /// Bytes the file would need.
        expected_bytes: u64,
        /// Bytes it has.
        actual_bytes: u64,
    },
    /// The file's content does not parse as its format.
    #[error("malformed {format:?} file: {message}")]
    Malformed {
        /// The format the file was read as.
        format: MeshFormat,
        /// What the parser said.
        message: String,
    },
    /// The file extension is none of `stl`, `obj`, `ply`.
    #[error("unsupported mesh file extension {extension:?} (expected stl, obj or ply)")]
    UnsupportedFormat {
        /// The extension found (empty if none).
        extension: String,
    },
    /// A connected part of the mesh cannot be wound consistently (a Möbius band): see
    /// [`TriMesh::with_consistent_winding`].
    #[error(
        "mesh cannot be wound consistently: going round its part with triangle {triangle} turns that triangle against itself"
    )]
    NonOrientable {
        /// A triangle of the part.
        triangle: usize,
    },
    /// Triangles that share an edge are wound against each other, so some have their inside
    /// and outside swapped (see [`TriMesh::winding_conflicts`]); [`LoadOptions`] repairs them
    /// by default, [`TriMesh::with_consistent_winding`] on demand.
    #[error(
        "{conflicts} edges are shared by triangles wound against each other (a triangle turned inside out makes three); repair with TriMesh::with_consistent_winding or LoadOptions::winding"
    )]
    InconsistentWinding {
        /// Shared edges along which both triangles run the same way.
        conflicts: usize,
    },
    /// A parameter (unit scale, density) is out of range.
    #[error("{what} = {value} is out of range: {expected}")]
    BadParameter {
        /// Which parameter.
        what: &'static str,
        /// The value given.
        value: Real,
        /// What was expected.
        expected: &'static str,
    },
    /// Mass properties were asked of an open mesh whose boundary changes the enclosed volume by
    /// more than [`OPEN_MESH_VOLUME_TOL`] (see [`TriMesh::mass_properties`]).
    #[error(
        "mesh is open ({boundary_edges} boundary edges): its volume changes by {volume_change_rel:.2e} (relative) with the integration origin"
    )]
    OpenMesh {
        /// Edges used by exactly one triangle.
        boundary_edges: usize,
        /// Relative change of the volume when the origin of the divergence integral moves by the
        /// bounding-box diagonal.
        volume_change_rel: Real,
    },
    /// The enclosed volume is not positive: inward-facing (clockwise) triangles, or no volume.
    #[error("enclosed volume {volume_m3} m^3 is not positive (inward normals or a flat mesh)")]
    NonPositiveVolume {
        /// The signed volume found (m³).
        volume_m3: Real,
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
                        vertex: v as i64,
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

    /// Axis-aligned bounding box `(min, max)` of the vertices used by triangles (m).
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::repeat(Real::INFINITY);
        let mut hi = Vec3::repeat(Real::NEG_INFINITY);
        for tri in &self.triangles {
            for &i in tri {
                let v = &self.vertices[i as usize];
                lo = lo.inf(v);
                hi = hi.sup(v);
            }
        }
        (lo, hi)
    }

    /// The same mesh with every vertex moved by `offset_m`.
    ///
    /// # Errors
    /// [`MeshError::NonFiniteVertex`] if the offset is not finite (or a coordinate overflows).
    pub fn translated(&self, offset_m: &Vec3) -> Result<Self, MeshError> {
        let vertices: Vec<Vec3> = self.vertices.iter().map(|v| v + offset_m).collect();
        if let Some(index) = vertices
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(MeshError::NonFiniteVertex { index });
        }
        Ok(Self {
            vertices,
            triangles: self.triangles.clone(),
        })
    }

    /// Number of edges used by exactly one triangle (0 for a closed mesh). Edges are vertex-index
    /// pairs, so a mesh whose coincident corners are not welded counts as open.
    pub fn boundary_edge_count(&self) -> usize {
        let mut edges: Vec<(u32, u32)> = self
            .triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        edges.sort_unstable();
        let mut count = 0;
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j] == edges[i] {
                j += 1;
            }
            if j - i == 1 {
                count += 1;
            }
            i = j;
        }
        count
    }

    /// The three corners of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }
}

#[cfg(test)]
mod tests;
