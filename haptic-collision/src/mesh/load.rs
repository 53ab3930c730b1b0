//! Loading meshes from STL (binary and ASCII, via `stl_io`), OBJ (via `tobj`) and PLY (ASCII and
//! binary, via `ply-rs`) files, with a unit scale, optional recentring and validation.

use std::io::{BufReader, Cursor};
use std::path::Path;

use haptic_core::{Real, Vec3};

use super::{DegeneratePolicy, MeshError, TriMesh};

/// A mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// STL, binary or ASCII (told apart by content, not by extension).
    Stl,
    /// Wavefront OBJ (positions and faces; polygons are triangulated, other data ignored).
    Obj,
    /// Stanford PLY, ASCII or binary (`vertex` x/y/z and `face` `vertex_indices`).
    Ply,
}

impl MeshFormat {
    /// The format named by a file's extension (`stl`, `obj`, `ply`, any case).
    ///
    /// # Errors
    /// [`MeshError::UnsupportedFormat`] for any other extension, or none.
    pub fn from_path(path: &Path) -> Result<Self, MeshError> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "stl" => Ok(Self::Stl),
            "obj" => Ok(Self::Obj),
            "ply" => Ok(Self::Ply),
            _ => Err(MeshError::UnsupportedFormat { extension: ext }),
        }
    }
}

/// How to load a mesh file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadOptions {
    /// Metres per file unit: `1.0` for files in metres, `1e-3` for millimetres (the shared jaws).
    pub scale_m_per_unit: Real,
    /// Move the mesh so that the centre of its axis-aligned bounding box is the origin. (For a
    /// tool whose body frame must sit at the centre of mass, translate by
    /// [`super::MassProperties::centre_of_mass_m`] instead, with [`TriMesh::translated`].)
    pub recentre: bool,
    /// What to do with degenerate triangles.
    pub degenerate: DegeneratePolicy,
    /// What to do with triangles wound against their neighbours.
    pub winding: WindingPolicy,
}

/// What to do with triangles wound against their neighbours (`mesh/winding.rs`): their inside
/// and outside are swapped, and the contacts on them push the wrong way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WindingPolicy {
    /// Turn them, part by part, to the winding of the larger area of the part
    /// ([`TriMesh::with_consistent_winding`]), and report how many
    /// ([`LoadReport::triangles_rewound`]).
    #[default]
    Repair,
    /// Reject the mesh with [`MeshError::InconsistentWinding`].
    Reject,
}

impl Default for LoadOptions {
    /// Scale 1 (metres), no recentring, degenerate triangles dropped, triangles wound against
    /// their neighbours turned.
    fn default() -> Self {
        Self {
            scale_m_per_unit: 1.0,
            recentre: false,
            degenerate: DegeneratePolicy::Drop,
            winding: WindingPolicy::Repair,
        }
    }
}

impl LoadOptions {
    /// Default options with the given unit scale (metres per file unit).
    pub fn with_scale(scale_m_per_unit: Real) -> Self {
        Self {
            scale_m_per_unit,
            ..Self::default()
        }
    }
}

/// What a load found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadReport {
    /// The format the file was read as.
    pub format: MeshFormat,
    /// Vertices of the mesh (after welding, for STL: exactly equal corners are one vertex).
    pub vertices: usize,
    /// Triangles kept.
    pub triangles: usize,
    /// Degenerate triangles found (and dropped, under [`DegeneratePolicy::Drop`]).
    pub degenerate_dropped: usize,
    /// Polygons with more than three corners that were split into triangles (OBJ, PLY).
    pub polygons_triangulated: usize,
    /// Triangles turned to agree with their neighbours' winding ([`WindingPolicy::Repair`]).
    pub triangles_rewound: usize,
    /// Triangles dropped for repeating an earlier one, on the same vertices and wound the same
    /// way ([`TriMesh::without_duplicates`]): each would have pushed twice.
    pub duplicates_dropped: usize,
    /// The translation (m) that was added to every vertex by recentring (zero without it).
    pub translation_m: Vec3,
}

impl TriMesh {
    /// Loads a mesh file; the format comes from the extension (`.stl`, `.obj`, `.ply`).
    ///
    /// Vertices are multiplied by `options.scale_m_per_unit`, then validated as in
    /// [`TriMesh::new`]; triangles that repeat an earlier one are dropped, those wound against
    /// their neighbours turned as `options.winding` says; then the mesh is recentred if asked.
    ///
    /// # Errors
    /// [`MeshError::UnsupportedFormat`], [`MeshError::Io`] for a missing or unreadable file, and
    /// every error of [`TriMesh::from_bytes`].
    pub fn load(
        path: impl AsRef<Path>,
        options: &LoadOptions,
    ) -> Result<(Self, LoadReport), MeshError> {
        let path = path.as_ref();
        let format = MeshFormat::from_path(path)?;
        check_scale(options.scale_m_per_unit)?;
        let bytes = std::fs::read(path).map_err(|e| MeshError::Io {
            path: path.display().to_string(),
            kind: e.kind(),
            message: e.to_string(),
        })?;
        Self::from_bytes(&bytes, format, options)
    }

    /// Parses a mesh from a file's content.
    ///
    /// # Errors
    /// [`MeshError::BadParameter`] for a scale that is not positive and finite;
    /// [`MeshError::Truncated`] for a binary STL shorter than its triangle count says;
    /// [`MeshError::Malformed`] for content that does not parse (including a PLY or OBJ face
    /// with fewer than 3 corners); [`MeshError::IndexOutOfRange`] for a face corner that names
    /// no vertex; and the validation errors of [`TriMesh::new`] ([`MeshError::Empty`],
    /// [`MeshError::NonFiniteVertex`], [`MeshError::DegenerateTriangles`]); with
    /// [`WindingPolicy::Repair`], [`MeshError::NonOrientable`] for a part that cannot be wound
    /// consistently, and with [`WindingPolicy::Reject`], [`MeshError::InconsistentWinding`].
    pub fn from_bytes(
        bytes: &[u8],
        format: MeshFormat,
        options: &LoadOptions,
    ) -> Result<(Self, LoadReport), MeshError> {
        check_scale(options.scale_m_per_unit)?;
        let raw = match format {
            MeshFormat::Stl => parse_stl(bytes)?,
            MeshFormat::Obj => parse_obj(bytes)?,
            MeshFormat::Ply => parse_ply(bytes)?,
        };
        let vertex_count = raw.vertices.len();
        let mut triangles = Vec::with_capacity(raw.faces.len());
        for (t, face) in raw.faces.iter().enumerate() {
            let mut tri = [0u32; 3];
            for (slot, &v) in tri.iter_mut().zip(face) {
                if v < 0 || v as u64 >= vertex_count as u64 || v > u32::MAX as i64 {
                    return Err(MeshError::IndexOutOfRange {
                        triangle: t,
                        vertex: v,
                        vertex_count,
                    });
                }
                *slot = v as u32;
            }
            triangles.push(tri);
        }
        let s = options.scale_m_per_unit;
        let vertices: Vec<Vec3> = raw.vertices.iter().map(|v| v * s).collect();
        let (mut mesh, degenerate_dropped) = Self::new(vertices, triangles, options.degenerate)?;
        let mut duplicates_dropped = 0;
        if mesh.coincident_triangles().duplicates > 0 {
            (mesh, duplicates_dropped) = mesh.without_duplicates();
        }
        let mut triangles_rewound = 0;
        match options.winding {
            WindingPolicy::Repair => {
                if mesh.winding_conflicts() > 0 {
                    (mesh, triangles_rewound) = mesh.with_consistent_winding()?;
                }
            }
            WindingPolicy::Reject => {
                let conflicts = mesh.winding_conflicts();
                if conflicts > 0 {
                    return Err(MeshError::InconsistentWinding { conflicts });
                }
            }
        }
        let mut translation_m = Vec3::zeros();
        if options.recentre {
            let (lo, hi) = mesh.bounding_box();
            translation_m = -(lo + hi) * 0.5;
            mesh = mesh.translated(&translation_m)?;
        }
        let report = LoadReport {
            format,
            vertices: mesh.vertices().len(),
            triangles: mesh.triangles().len(),
            degenerate_dropped,
            polygons_triangulated: raw.polygons_triangulated,
            triangles_rewound,
            duplicates_dropped,
            translation_m,
        };
        Ok((mesh, report))
    }
}

fn check_scale(scale: Real) -> Result<(), MeshError> {
    if scale > 0.0 && scale.is_finite() {
        Ok(())
    } else {
        Err(MeshError::BadParameter {
            what: "scale_m_per_unit",
            value: scale,
            expected: "positive and finite",
        })
    }
}

/// A parsed file before validation: vertices in file units, faces as signed indices (so that
/// negative or huge indices reach the range check).
struct RawMesh {
    vertices: Vec<Vec3>,
    faces: Vec<[i64; 3]>,
    polygons_triangulated: usize,
}

impl RawMesh {
    /// Adds a polygon as a triangle fan.
    fn push_polygon(&mut self, corners: &[i64], format: MeshFormat) -> Result<(), MeshError> {
        if corners.len() < 3 {
            return Err(MeshError::Malformed {
                format,
                message: format!(
                    "face {} has {} corners (at least 3 needed)",
                    self.faces.len(),
                    corners.len()
                ),
            });
        }
        if corners.len() > 3 {
            self.polygons_triangulated += 1;
        }
        for k in 1..corners.len() - 1 {
            self.faces.push([corners[0], corners[k], corners[k + 1]]);
        }
        Ok(())
    }
}

const STL_HEADER: usize = 84;
const STL_RECORD: u64 = 50;

/// STL: binary when the size matches the header's triangle count exactly, or when the content
/// does not start with `solid`; ASCII otherwise.
fn parse_stl(bytes: &[u8]) -> Result<RawMesh, MeshError> {
    let announced = bytes
        .get(80..84)
        .and_then(|b| b.try_into().ok())
        .map(|b: [u8; 4]| u32::from_le_bytes(b) as u64);
    let binary_size = announced.map(|n| STL_HEADER as u64 + STL_RECORD * n);
    let exact_binary = binary_size == Some(bytes.len() as u64);
    let text = bytes.trim_ascii_start();
    let ascii = !exact_binary && text.starts_with(b"solid");
    let owned: Vec<u8>;
    let input: &[u8] = if ascii {
        // stl_io wants "solid " followed by a name on the first line; give it one.
        let first_line_end = text.iter().position(|&c| c == b'\n').unwrap_or(text.len());
        let mut v = b"solid mesh".to_vec();
        v.extend_from_slice(&text[first_line_end..]);
        owned = v;
        &owned
    } else {
        let n = announced.unwrap_or(0);
        let expected = STL_HEADER as u64 + STL_RECORD * n;
        if (bytes.len() as u64) < expected || bytes.len() < STL_HEADER {
            return Err(MeshError::Truncated {
                triangles: n,
                expected_bytes: expected.max(STL_HEADER as u64),
                actual_bytes: bytes.len() as u64,
            });
        }
        // A binary header may itself start with "solid": blank it so that stl_io reads binary.
        let mut v = bytes[..expected as usize].to_vec();
        v[..80].fill(0);
        owned = v;
        &owned
    };
    let mesh = stl_io::read_stl(&mut Cursor::new(input)).map_err(|e| MeshError::Malformed {
        format: MeshFormat::Stl,
        message: e.to_string(),
    })?;
    Ok(RawMesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|v| Vec3::new(v[0] as Real, v[1] as Real, v[2] as Real))
            .collect(),
        faces: mesh
            .faces
            .iter()
            .map(|f| f.vertices.map(|i| i as i64))
            .collect(),
        polygons_triangulated: 0,
    })
}

/// OBJ via tobj: every object and group, positions only, polygons triangulated as fans by tobj.
fn parse_obj(bytes: &[u8]) -> Result<RawMesh, MeshError> {
    let opts = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = BufReader::new(Cursor::new(bytes));
    let (models, _materials) =
        tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed)).map_err(
            |e| match e {
                tobj::LoadError::FaceVertexOutOfBounds => {
                    obj_bad_index(bytes).unwrap_or(MeshError::Malformed {
                        format: MeshFormat::Obj,
                        message: e.to_string(),
                    })
                }
                _ => MeshError::Malformed {
                    format: MeshFormat::Obj,
                    message: e.to_string(),
                },
            },
        )?;
    let mut raw = RawMesh {
        vertices: Vec::new(),
        faces: Vec::new(),
        polygons_triangulated: 0,
    };
    for model in &models {
        let m = &model.mesh;
        let base = raw.vertices.len() as i64;
        raw.vertices.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0] as Real, p[1] as Real, p[2] as Real)),
        );
        // Without triangulation tobj gives each face's corner count (empty when all are
        // triangles).
        let mut start = 0usize;
        let mut corners: Vec<i64> = Vec::new();
        let arities: Box<dyn Iterator<Item = usize>> = if m.face_arities.is_empty() {
            Box::new(std::iter::repeat_n(3, m.indices.len() / 3))
        } else {
            Box::new(m.face_arities.iter().map(|&a| a as usize))
        };
        for arity in arities {
            let Some(face) = m.indices.get(start..start + arity) else {
                return Err(MeshError::Malformed {
                    format: MeshFormat::Obj,
                    message: "face list shorter than its corner counts".into(),
                });
            };
            corners.clear();
            corners.extend(face.iter().map(|&i| base + i as i64));
            raw.push_polygon(&corners, MeshFormat::Obj)?;
            start += arity;
        }
    }
    Ok(raw)
}

/// Finds the first OBJ face corner that names no vertex (tobj reports only that one exists).
fn obj_bad_index(bytes: &[u8]) -> Option<MeshError> {
    let text = std::str::from_utf8(bytes).ok()?;
    let (mut vertices, mut faces) = (0i64, 0usize);
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => vertices += 1,
            Some("f") => {
                for w in words {
                    let i: i64 = w.split('/').next()?.parse().ok()?;
                    // 1-based, negative counts back from the last vertex read.
                    let zero_based = if i < 0 { vertices + i } else { i - 1 };
                    if i == 0 || zero_based < 0 || zero_based >= vertices {
                        return Some(MeshError::IndexOutOfRange {
                            triangle: faces,
                            vertex: zero_based,
                            vertex_count: vertices as usize,
                        });
                    }
                }
                faces += 1;
            }
            _ => {}
        }
    }
    None
}

/// PLY via ply-rs: element `vertex` with scalar `x`, `y`, `z`; element `face` with a list
/// `vertex_indices` (or `vertex_index`).
fn parse_ply(bytes: &[u8]) -> Result<RawMesh, MeshError> {
    use ply_rs::ply::Property;
    let malformed = |message: String| MeshError::Malformed {
        format: MeshFormat::Ply,
        message,
    };
    let parser = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new();
    let ply = parser
        .read_ply(&mut BufReader::new(Cursor::new(bytes)))
        .map_err(|e| malformed(e.to_string()))?;
    let scalar = |p: &Property| -> Option<Real> {
        Some(match *p {
            Property::Char(v) => v as Real,
            Property::UChar(v) => v as Real,
            Property::Short(v) => v as Real,
            Property::UShort(v) => v as Real,
            Property::Int(v) => v as Real,
            Property::UInt(v) => v as Real,
            Property::Float(v) => v as Real,
            Property::Double(v) => v,
            _ => return None,
        })
    };
    let vertex_elems = ply
        .payload
        .get("vertex")
        .ok_or_else(|| malformed("no `vertex` element".into()))?;
    let mut raw = RawMesh {
        vertices: Vec::with_capacity(vertex_elems.len()),
        faces: Vec::new(),
        polygons_triangulated: 0,
    };
    for (i, e) in vertex_elems.iter().enumerate() {
        let mut xyz = [0.0; 3];
        for (c, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
            *c = e
                .get(name)
                .and_then(scalar)
                .ok_or_else(|| malformed(format!("vertex {i} has no scalar `{name}`")))?;
        }
        raw.vertices.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
    }
    let Some(face_elems) = ply.payload.get("face") else {
        return Ok(raw);
    };
    let mut corners: Vec<i64> = Vec::new();
    for (f, e) in face_elems.iter().enumerate() {
        let list = e
            .get("vertex_indices")
            .or_else(|| e.get("vertex_index"))
            .ok_or_else(|| malformed(format!("face {f} has no `vertex_indices` list")))?;
        corners.clear();
        match list {
            Property::ListChar(v) => corners.extend(v.iter().map(|&i| i as i64)),
            Property::ListUChar(v) => corners.extend(v.iter().map(|&i| i as i64)),
            Property::ListShort(v) => corners.extend(v.iter().map(|&i| i as i64)),
            Property::ListUShort(v) => corners.extend(v.iter().map(|&i| i as i64)),
            Property::ListInt(v) => corners.extend(v.iter().map(|&i| i as i64)),
            Property::ListUInt(v) => corners.extend(v.iter().map(|&i| i as i64)),
            _ => {
                return Err(malformed(format!(
                    "face {f}: indices are not an integer list"
                )));
            }
        }
        raw.push_polygon(&corners, MeshFormat::Ply)?;
    }
    Ok(raw)
}
