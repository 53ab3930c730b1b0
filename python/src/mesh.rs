//! `haptic.Mesh` and `haptic.MassProperties`: triangle meshes from files or from arrays.

use std::path::PathBuf;
use std::sync::Arc;

use haptic_collision::{DegeneratePolicy, LoadOptions, MassProperties, TriMesh};
use haptic_core::Vec3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert;
use crate::errors::{from_mesh, input};

/// A triangle mesh (m). Build one from arrays, `Mesh(vertices (n, 3), triangles (m, 3))`
/// (degenerate triangles are dropped and counted in `dropped_degenerate`), or load one with
/// `Mesh.load(path, scale)`.
#[pyclass(module = "haptic", name = "Mesh", frozen)]
#[derive(Clone)]
pub struct PyMesh {
    pub(crate) mesh: Arc<TriMesh>,
    dropped: usize,
    rewound: usize,
    duplicates: usize,
}

impl PyMesh {
    pub(crate) fn wrap(mesh: TriMesh, dropped: usize) -> Self {
        Self {
            mesh: Arc::new(mesh),
            dropped,
            rewound: 0,
            duplicates: 0,
        }
    }
}

#[pymethods]
impl PyMesh {
    #[new]
    fn new(vertices: &Bound<'_, PyAny>, triangles: &Bound<'_, PyAny>) -> PyResult<Self> {
        let v = convert::rows::<3>(vertices, "vertices", false)?;
        let t = convert::rows::<3>(triangles, "triangles", false)?;
        let mut tris = Vec::with_capacity(t.len());
        for (i, row) in t.iter().enumerate() {
            let mut tri = [0u32; 3];
            for (j, x) in row.iter().enumerate() {
                if x.fract() != 0.0 || *x < 0.0 || *x > f64::from(u32::MAX) {
                    return Err(input(
                        "triangles",
                        format!("row {i} holds {x}: indices must be non-negative integers"),
                    ));
                }
                tri[j] = *x as u32;
            }
            tris.push(tri);
        }
        let vertices: Vec<Vec3> = v.iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect();
        let (mesh, dropped) =
            TriMesh::new(vertices, tris, DegeneratePolicy::Drop).map_err(|e| from_mesh(&e))?;
        Ok(Self::wrap(mesh, dropped))
    }

    /// Loads an STL, OBJ or PLY file (by its extension), scaled by `scale` (m per file unit).
    #[staticmethod]
    #[pyo3(signature = (path, scale = 1.0))]
    fn load(py: Python<'_>, path: PathBuf, scale: f64) -> PyResult<Self> {
        convert::positive(scale, "scale")?;
        let (mesh, report) = py
            .detach(|| TriMesh::load(&path, &LoadOptions::with_scale(scale)))
            .map_err(|e| from_mesh(&e))?;
        Ok(Self {
            rewound: report.triangles_rewound,
            duplicates: report.duplicates_dropped,
            ..Self::wrap(mesh, report.degenerate_dropped)
        })
    }

    /// Vertex positions (m), `(n, 3)` float64 (a copy).
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        convert::array3(py, self.mesh.vertices().iter().copied())
    }

    /// Triangles as vertex indices, `(m, 3)` uint32 (a copy).
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u32>> {
        let t = self.mesh.triangles();
        let flat: Vec<u32> = t.iter().flatten().copied().collect();
        Array2::from_shape_vec((t.len(), 3), flat)
            .expect("3 indices a triangle")
            .into_pyarray(py)
    }

    /// Number of vertices.
    #[getter]
    fn vertex_count(&self) -> usize {
        self.mesh.vertices().len()
    }

    /// Number of triangles.
    #[getter]
    fn triangle_count(&self) -> usize {
        self.mesh.triangles().len()
    }

    /// Degenerate triangles dropped when the mesh was made.
    #[getter]
    fn dropped_degenerate(&self) -> usize {
        self.dropped
    }

    /// Triangles dropped at load for repeating an earlier one (same vertices, same winding).
    #[getter]
    fn dropped_duplicates(&self) -> usize {
        self.duplicates
    }

    /// Triangles turned to agree with their neighbours' winding when the mesh was loaded or
    /// repaired (`with_consistent_winding`).
    #[getter]
    fn rewound_triangles(&self) -> usize {
        self.rewound
    }

    /// Edges shared by two triangles wound against each other (0 for a consistent mesh; a
    /// triangle turned inside out makes three).
    #[getter]
    fn winding_conflicts(&self) -> usize {
        self.mesh.winding_conflicts()
    }

    /// A copy with every connected part wound consistently, each the way the larger area of
    /// its triangles is; `rewound_triangles` says how many were turned.
    fn with_consistent_winding(&self) -> PyResult<Self> {
        let (mesh, rewound) = self
            .mesh
            .with_consistent_winding()
            .map_err(|e| from_mesh(&e))?;
        Ok(Self {
            rewound,
            duplicates: self.duplicates,
            ..Self::wrap(mesh, self.dropped)
        })
    }

    /// The axis-aligned bounding box, `(lo (3,), hi (3,))` (m).
    fn bounding_box<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let (lo, hi) = self.mesh.bounding_box();
        (
            convert::array1(py, vec![lo.x, lo.y, lo.z]),
            convert::array1(py, vec![hi.x, hi.y, hi.z]),
        )
    }

    /// A copy moved by `offset` (m).
    fn translated(&self, offset: &Bound<'_, PyAny>) -> PyResult<Self> {
        let o = convert::vec3(offset, "offset")?;
        let m = self.mesh.translated(&o).map_err(|e| from_mesh(&e))?;
        Ok(Self::wrap(m, 0))
    }

    /// Volume, mass, centre of mass and inertia of the solid the mesh bounds, at a uniform
    /// density (kg/m³).
    fn mass_properties(&self, density_kg_per_m3: f64) -> PyResult<PyMassProperties> {
        convert::positive(density_kg_per_m3, "density_kg_per_m3")?;
        let mp = self
            .mesh
            .mass_properties(density_kg_per_m3)
            .map_err(|e| from_mesh(&e))?;
        Ok(PyMassProperties { mp })
    }

    fn __repr__(&self) -> String {
        format!(
            "Mesh({} vertices, {} triangles)",
            self.mesh.vertices().len(),
            self.mesh.triangles().len()
        )
    }
}

/// The mass properties of a mesh's solid.
#[pyclass(module = "haptic", name = "MassProperties", frozen)]
pub struct PyMassProperties {
    pub(crate) mp: MassProperties,
}

#[pymethods]
impl PyMassProperties {
    /// Enclosed volume (m³).
    #[getter]
    fn volume_m3(&self) -> f64 {
        self.mp.volume_m3
    }

    /// Mass (kg).
    #[getter]
    fn mass_kg(&self) -> f64 {
        self.mp.mass_kg
    }

    /// Centre of mass in the mesh's frame (m), `(3,)`.
    #[getter]
    fn centre_of_mass_m<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let c = self.mp.centre_of_mass_m;
        convert::array1(py, vec![c.x, c.y, c.z])
    }

    /// Inertia tensor about the centre of mass, mesh axes (kg m²), `(3, 3)`.
    #[getter]
    fn inertia_about_com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let m = self.mp.inertia_about_com;
        let rows: Vec<[f64; 3]> = (0..3).map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]).collect();
        convert::array_rows(py, &rows)
    }

    /// Edges used by one triangle only: 0 for a closed mesh.
    #[getter]
    fn boundary_edges(&self) -> usize {
        self.mp.boundary_edges
    }

    fn __repr__(&self) -> String {
        format!(
            "MassProperties(volume_m3={:.6e}, mass_kg={:.6e})",
            self.mp.volume_m3, self.mp.mass_kg
        )
    }
}
