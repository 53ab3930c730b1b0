//! Saved hierarchies: a [`Hierarchy`] written to a file and read back, keyed by the mesh's
//! content and the build's version, so that a second start of a program does no rebuild
//! ([`LodBackend::with_cache`]).
//!
//! # Format (version 3)
//! Little-endian. `HAPTICLOD\0` (10 bytes), the format version (`u32`), the key (`u64`, see
//! [`hierarchy_key`]), the node count and the piece vertex count (`u64` each), the height and
//! the triangle count (`u64`), the count of measured overhangs and of their edges (`u64`), the
//! radius about the origin (`f64`), then each node (its nine
//! vector and three scalar `f64`s, then its five `u32`s) and each piece vertex (three `f64`s),
//! then each planar piece's overhang (`overhang.rs`; new in version 3): the node's index (`u32`,
//! increasing) and, for each edge of its piece, the band's width and uncovered area (`f64`s),
//! and last the checksum (`u64`) of every byte before it: FNV-1a over little-endian 64-bit
//! words, the last padded with zeros (version 1 hashed byte by byte, three times slower to load).
//!
//! A file that is not one, of another version, of another mesh or build, cut short, or whose
//! hash or indices do not hold is refused with a [`HierarchyFileError`]: it is never used.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use haptic_core::{Pose, Real, Vec3};

use super::build::{Hierarchy, Node};
use super::overhang::Overhang;
use super::{LodBackend, LodError};
use crate::mesh::TriMesh;

const MAGIC: &[u8; 10] = b"HAPTICLOD\0";
/// The file format's version.
pub const FORMAT_VERSION: u32 = 3;
/// What the build does, in words: part of every key, so that a change to the build (a new
/// bound, a new piece) makes old files another build's. Change it with the build.
const BUILD: &str = "haptic-collision lod build 7: median split on centroids (a quad's two halves \
                     at its centroid, together, quads.rs) or cut along the \
                     normals' spread (split.rs), planar convex pieces of at most \
                     MAX_PIECE_VERTICES, slab and deviation bounds (piece → surface regions \
                     dropped once bounded, candidates' distances in their own planes, the node's \
                     children always among them; deviations within ROUNDOFF_REL of the radius \
                     none; of equally long axes, the first; the pieces' overhang widths, \
                     overhang.rs)";

/// A saved hierarchy could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum HierarchyFileError {
    /// The file could not be read or written.
    #[error("hierarchy file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// The file does not start as a hierarchy file.
    #[error("not a saved hierarchy")]
    NotAHierarchy,
    /// Another version of the format.
    #[error("saved hierarchy of format version {found}; this build reads version {FORMAT_VERSION}")]
    Version {
        /// The version found.
        found: u32,
    },
    /// The hierarchy of another mesh, or of another build.
    #[error(
        "saved hierarchy of another mesh or build (key {found:016x}, expected {expected:016x})"
    )]
    OtherMesh {
        /// The key in the file.
        found: u64,
        /// The key of the mesh asked for.
        expected: u64,
    },
    /// The file ends early.
    #[error("saved hierarchy cut short")]
    Truncated,
    /// The content does not hold (hash, indices or values).
    #[error("saved hierarchy corrupt: {0}")]
    Corrupt(&'static str),
}

/// FNV-1a's 64-bit prime.
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a, 64 bits.
#[derive(Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
    fn eat(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(FNV_PRIME);
        }
    }
}

/// The file's checksum: FNV-1a over its little-endian 64-bit words, the last one padded with
/// zeros. Word by word because FNV's multiplications form one serial chain: byte by byte, the
/// checksum took a third of the time of loading the jaws' hierarchies (format version 1).
fn checksum(bytes: &[u8]) -> u64 {
    let eat = |h: u64, word: u64| (h ^ word).wrapping_mul(FNV_PRIME);
    let words = bytes.chunks_exact(8);
    let tail = words.remainder();
    let mut h = words.fold(Fnv::new().0, |h, w| {
        let mut word = [0u8; 8];
        word.copy_from_slice(w);
        eat(h, u64::from_le_bytes(word))
    });
    if !tail.is_empty() {
        let mut word = [0u8; 8];
        word[..tail.len()].copy_from_slice(tail);
        h = eat(h, u64::from_le_bytes(word));
    }
    h
}

/// The key of `mesh`'s hierarchy: a hash of the build (its description, the crate's version and
/// the values of the constants it uses), the format's version, and the mesh's vertex and
/// triangle counts and bits.
pub fn hierarchy_key(mesh: &TriMesh) -> u64 {
    let mut h = Fnv::new();
    h.eat(BUILD.as_bytes());
    h.eat(env!("CARGO_PKG_VERSION").as_bytes());
    h.eat(&FORMAT_VERSION.to_le_bytes());
    for c in [
        super::MAX_PIECE_VERTICES,
        super::deviation::POLY2_CAP,
        super::deviation::MAX_CANDIDATES,
        super::deviation::MAX_REGIONS,
        super::split::MIN_SHARE,
        mesh.vertices().len(),
        mesh.triangles().len(),
    ] {
        h.eat(&(c as u64).to_le_bytes());
    }
    for c in [
        super::split::CREASE_ANGLE_RAD,
        super::split::ORIENTATION_GAIN,
    ] {
        h.eat(&c.to_le_bytes());
    }
    for v in mesh.vertices() {
        for c in v.iter() {
            h.eat(&c.to_le_bytes());
        }
    }
    for t in mesh.triangles() {
        for i in t {
            h.eat(&i.to_le_bytes());
        }
    }
    h.0
}

/// Writes little-endian values into a buffer, which [`Hierarchy::write_to`] then writes out
/// with its [`checksum`].
struct Writer {
    buf: Vec<u8>,
}

impl Writer {
    fn bytes(&mut self, b: &[u8]) {
        self.buf.extend_from_slice(b);
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    fn f64(&mut self, v: Real) {
        self.bytes(&v.to_le_bytes());
    }
    fn vec3(&mut self, v: &Vec3) {
        self.f64(v.x);
        self.f64(v.y);
        self.f64(v.z);
    }
}

/// Reads the header's little-endian values from a file's bytes, in memory.
struct Reader<'a> {
    rest: &'a [u8],
}

impl Reader<'_> {
    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], HierarchyFileError> {
        let (head, rest) = self
            .rest
            .split_first_chunk::<N>()
            .ok_or(HierarchyFileError::Truncated)?;
        self.rest = rest;
        Ok(*head)
    }
    fn u32(&mut self) -> Result<u32, HierarchyFileError> {
        Ok(u32::from_le_bytes(self.bytes()?))
    }
    fn u64(&mut self) -> Result<u64, HierarchyFileError> {
        Ok(u64::from_le_bytes(self.bytes()?))
    }
    fn f64(&mut self) -> Result<Real, HierarchyFileError> {
        Ok(Real::from_le_bytes(self.bytes()?))
    }
}

/// The little-endian `f64` at byte `at` of `b` (within it: the caller's chunks are whole).
#[inline]
fn f64_at(b: &[u8], at: usize) -> Real {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[at..at + 8]);
    Real::from_le_bytes(w)
}

/// The three little-endian `f64`s from byte `at` of `b`.
#[inline]
fn vec3_at(b: &[u8], at: usize) -> Vec3 {
    Vec3::new(f64_at(b, at), f64_at(b, at + 8), f64_at(b, at + 16))
}

/// The little-endian `u32` at byte `at` of `b`.
#[inline]
fn u32_at(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    w.copy_from_slice(&b[at..at + 4]);
    u32::from_le_bytes(w)
}

/// Bytes of the header: magic, version, key, six counts and the radius.
const HEADER_BYTES: usize = 10 + 4 + 8 + 6 * 8 + 8;
/// Bytes of one node: three vectors, three reals and five indices.
const NODE_BYTES: usize = 3 * 24 + 3 * 8 + 5 * 4;
/// Bytes of one piece vertex.
const VERTEX_BYTES: usize = 24;
/// Bytes of a measured piece's entry, before its edges': the node's index.
const MEASURED_BYTES: usize = 4;
/// Bytes of one edge of a measured piece: its overhang's width and area.
const OVERHANG_BYTES: usize = 16;
/// Bytes of the checksum at the end.
const CHECKSUM_BYTES: usize = 8;

impl Hierarchy {
    /// Writes the hierarchy, under `key` (the [`hierarchy_key`] of its mesh).
    ///
    /// # Errors
    /// The writer's.
    pub fn write_to(&self, mut out: impl Write, key: u64) -> std::io::Result<()> {
        // The planar pieces whose overhang the build measured (the others' is infinite, and a
        // leaf's 0: neither is written).
        let measured: Vec<u32> = (0..self.nodes.len() as u32)
            .filter(|&i| {
                let n = &self.nodes[i as usize];
                !n.is_leaf()
                    && n.piece_len > 0
                    && self.overhang[n.piece_start as usize].width_m.is_finite()
            })
            .collect();
        let measured_vertices: usize = measured
            .iter()
            .map(|&i| self.nodes[i as usize].piece_len as usize)
            .sum();
        let mut w = Writer {
            buf: Vec::with_capacity(
                HEADER_BYTES
                    + self.nodes.len() * NODE_BYTES
                    + self.piece.len() * VERTEX_BYTES
                    + measured.len() * MEASURED_BYTES
                    + measured_vertices * OVERHANG_BYTES
                    + CHECKSUM_BYTES,
            ),
        };
        w.bytes(MAGIC);
        w.u32(FORMAT_VERSION);
        w.u64(key);
        w.u64(self.nodes.len() as u64);
        w.u64(self.piece.len() as u64);
        w.u64(self.height() as u64);
        w.u64(self.triangle_count() as u64);
        w.u64(measured.len() as u64);
        w.u64(measured_vertices as u64);
        w.f64(self.radius_about_origin_m());
        for n in &self.nodes {
            w.vec3(&n.center);
            w.vec3(&n.normal);
            w.vec3(&n.plane_point);
            w.f64(n.radius);
            w.f64(n.half_thickness);
            w.f64(n.deviation);
            for v in [n.right, n.triangle, n.piece_start, n.piece_len, n.triangles] {
                w.u32(v);
            }
        }
        for p in &self.piece {
            w.vec3(p);
        }
        for &i in &measured {
            w.u32(i);
            let n = &self.nodes[i as usize];
            let s = n.piece_start as usize;
            for o in &self.overhang[s..s + n.piece_len as usize] {
                w.f64(o.width_m);
                w.f64(o.area_m2);
            }
        }
        let hash = checksum(&w.buf);
        out.write_all(&w.buf)?;
        out.write_all(&hash.to_le_bytes())?;
        out.flush()
    }

    /// Reads a hierarchy written by [`Hierarchy::write_to`], if it is the one of `mesh` (its
    /// [`hierarchy_key`]). The counts come from the mesh, so nothing is reserved on the file's
    /// word; the tree is checked whole before it is returned (structure, pieces, values), so
    /// that a query never indexes out of bounds or walks a malformed tree.
    ///
    /// # Errors
    /// [`HierarchyFileError`]: not a hierarchy file, another version, another mesh or build,
    /// cut short, or corrupt.
    pub fn read_from(input: impl Read, mesh: &TriMesh) -> Result<Self, HierarchyFileError> {
        let key = hierarchy_key(mesh);
        let expected_triangles = mesh.triangles().len();
        let start = Instant::now();
        // The whole file in memory (never more than a hierarchy of this mesh can take, and a
        // byte more to tell a longer file), then checked and parsed in place.
        let nodes_expected = expected_triangles
            .checked_mul(2)
            .and_then(|n| n.checked_sub(1))
            .ok_or(HierarchyFileError::Corrupt("counts"))?;
        let pieces_max = nodes_expected.saturating_mul(super::MAX_PIECE_VERTICES);
        let bytes_max = nodes_expected
            .saturating_mul(NODE_BYTES + MEASURED_BYTES)
            .saturating_add(pieces_max.saturating_mul(VERTEX_BYTES + OVERHANG_BYTES))
            .saturating_add(HEADER_BYTES + CHECKSUM_BYTES);
        let mut file = Vec::new();
        input
            .take((bytes_max as u64).saturating_add(1))
            .read_to_end(&mut file)
            .map_err(|source| HierarchyFileError::Io {
                path: PathBuf::new(),
                source,
            })?;
        let mut r = Reader { rest: &file };
        let magic: [u8; 10] = r.bytes().map_err(|e| match e {
            HierarchyFileError::Truncated => HierarchyFileError::NotAHierarchy,
            other => other,
        })?;
        if &magic != MAGIC {
            return Err(HierarchyFileError::NotAHierarchy);
        }
        let version = r.u32()?;
        if version != FORMAT_VERSION {
            return Err(HierarchyFileError::Version { found: version });
        }
        let found = r.u64()?;
        if found != key {
            return Err(HierarchyFileError::OtherMesh {
                found,
                expected: key,
            });
        }
        let (node_count, piece_count, height, triangle_count) =
            (r.u64()?, r.u64()?, r.u64()?, r.u64()?);
        let (measured_count, measured_vertices) = (r.u64()?, r.u64()?);
        let radius = r.f64()?;
        // The counts a hierarchy of this mesh has; anything else is corrupt, not an allocation
        // to attempt.
        if triangle_count != expected_triangles as u64
            || node_count != nodes_expected as u64
            || piece_count > pieces_max as u64
            || height > node_count
            || measured_count > node_count
            || measured_vertices > piece_count
        {
            return Err(HierarchyFileError::Corrupt("counts"));
        }
        let (measured_count, measured_vertices) =
            (measured_count as usize, measured_vertices as usize);
        let (node_count, piece_count, height, triangle_count) = (
            nodes_expected,
            piece_count as usize,
            height as usize,
            expected_triangles,
        );
        let body = HEADER_BYTES
            + node_count * NODE_BYTES
            + piece_count * VERTEX_BYTES
            + measured_count * MEASURED_BYTES
            + measured_vertices * OVERHANG_BYTES;
        if file.len() < body + CHECKSUM_BYTES {
            return Err(HierarchyFileError::Truncated);
        }
        if file.len() > body + CHECKSUM_BYTES {
            return Err(HierarchyFileError::Corrupt("bytes after the hash"));
        }
        let (content, stored) = file.split_at(body);
        // Under the fuzzer (`fuzz/`, which builds with `--cfg fuzzing`) the hash is not checked,
        // so that mutated files reach the parser and the tree check behind it.
        if !cfg!(fuzzing) && stored != checksum(content).to_le_bytes() {
            return Err(HierarchyFileError::Corrupt("hash"));
        }
        // The body's length was checked above: every chunk is whole.
        let (node_bytes, rest) = r.rest.split_at(node_count * NODE_BYTES);
        let (piece_bytes, rest) = rest.split_at(piece_count * VERTEX_BYTES);
        let measured_bytes =
            &rest[..measured_count * MEASURED_BYTES + measured_vertices * OVERHANG_BYTES];
        let nodes: Vec<Node> = node_bytes
            .chunks_exact(NODE_BYTES)
            .map(|b| Node {
                center: vec3_at(b, 0),
                normal: vec3_at(b, 24),
                plane_point: vec3_at(b, 48),
                radius: f64_at(b, 72),
                half_thickness: f64_at(b, 80),
                deviation: f64_at(b, 88),
                right: u32_at(b, 96),
                triangle: u32_at(b, 100),
                piece_start: u32_at(b, 104),
                piece_len: u32_at(b, 108),
                triangles: u32_at(b, 112),
            })
            .collect();
        let piece: Vec<Vec3> = piece_bytes[..piece_count * VERTEX_BYTES]
            .chunks_exact(VERTEX_BYTES)
            .map(|b| vec3_at(b, 0))
            .collect();
        if !(radius.is_finite() && radius >= 0.0)
            || piece.iter().any(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(HierarchyFileError::Corrupt("a value is not finite"));
        }
        if check_tree(&nodes, piece_count, triangle_count)? != height {
            return Err(HierarchyFileError::Corrupt("height"));
        }
        let overhang = read_overhang(&nodes, piece_count, measured_count, measured_bytes)?;
        Ok(Hierarchy::from_parts(
            nodes,
            piece,
            overhang,
            radius,
            triangle_count,
            height,
            start.elapsed().as_secs_f64(),
        ))
    }
}

/// The pieces' overhang (`overhang.rs`) from the `count` entries of `bytes`, each a measured
/// inner node's index (increasing) and its piece's edges' widths and areas (finite, 0 or more),
/// the whole of `bytes`: a leaf's is 0, an inner node's not written infinite (not measured).
fn read_overhang(
    nodes: &[Node],
    piece_count: usize,
    count: usize,
    mut bytes: &[u8],
) -> Result<Vec<Overhang>, HierarchyFileError> {
    let corrupt = HierarchyFileError::Corrupt;
    let unmeasured = Overhang {
        width_m: Real::INFINITY,
        area_m2: Real::INFINITY,
    };
    let mut overhang = vec![unmeasured; piece_count];
    for n in nodes.iter().filter(|n| n.is_leaf()) {
        let s = n.piece_start as usize;
        overhang[s..s + n.piece_len as usize].fill(Overhang::default());
    }
    let mut next = 0usize;
    for _ in 0..count {
        if bytes.len() < MEASURED_BYTES {
            return Err(corrupt("overhang entries"));
        }
        let i = u32_at(bytes, 0) as usize;
        bytes = &bytes[MEASURED_BYTES..];
        let Some(n) = nodes.get(i).filter(|n| i >= next && !n.is_leaf()) else {
            return Err(corrupt("overhang entries"));
        };
        next = i + 1;
        let (s, len) = (n.piece_start as usize, n.piece_len as usize);
        if bytes.len() < len * OVERHANG_BYTES {
            return Err(corrupt("overhang entries"));
        }
        for (k, o) in overhang[s..s + len].iter_mut().enumerate() {
            let (width_m, area_m2) = (
                f64_at(bytes, k * OVERHANG_BYTES),
                f64_at(bytes, k * OVERHANG_BYTES + 8),
            );
            let ok = |x: Real| x.is_finite() && x >= 0.0;
            if !(ok(width_m) && ok(area_m2)) {
                return Err(corrupt("an overhang width"));
            }
            *o = Overhang { width_m, area_m2 };
        }
        bytes = &bytes[len * OVERHANG_BYTES..];
    }
    if !bytes.is_empty() {
        return Err(corrupt("overhang entries"));
    }
    Ok(overhang)
}

/// Checks a tree read from a file as the walk will use it, and returns its height:
/// - pre-order, every node once: an inner node's left child is the next node and its right child
///   the first node after the left subtree; leaves number `triangle_count`;
/// - each node's `triangles` is its subtree's leaf count;
/// - a leaf has its triangle (an index below `triangle_count`) as a piece of 3 vertices and
///   deviation 0; an inner node a piece of 3 to `MAX_PIECE_VERTICES` vertices and a finite
///   deviation, or none and an infinite deviation; every piece lies in `0..piece_count`;
/// - every other value finite, radii, thicknesses and deviations not negative, normals unit.
fn check_tree(
    nodes: &[Node],
    piece_count: usize,
    triangle_count: usize,
) -> Result<usize, HierarchyFileError> {
    let corrupt = HierarchyFileError::Corrupt;
    let mut stack: Vec<(usize, usize)> = vec![(0, 1)];
    let (mut visited, mut leaves, mut height) = (0usize, 0usize, 0usize);
    while let Some((i, level)) = stack.pop() {
        if i != visited || i >= nodes.len() {
            return Err(corrupt("tree structure"));
        }
        visited += 1;
        height = height.max(level);
        let n = &nodes[i];
        let finite = [n.center, n.normal, n.plane_point]
            .iter()
            .all(|v| v.iter().all(|c| c.is_finite()))
            && n.radius.is_finite()
            && n.half_thickness.is_finite();
        if !finite
            || n.radius < 0.0
            || n.half_thickness < 0.0
            || n.deviation.is_nan()
            || n.deviation < 0.0
            || (n.normal.norm() - 1.0).abs() > 1e-6
        {
            return Err(corrupt("node values"));
        }
        if u64::from(n.piece_start) + u64::from(n.piece_len) > piece_count as u64 {
            return Err(corrupt("piece indices"));
        }
        if n.is_leaf() {
            if n.triangle as usize >= triangle_count || n.piece_len != 3 || n.deviation != 0.0 {
                return Err(corrupt("leaf"));
            }
            leaves += 1;
        } else {
            let piece_ok = if n.piece_len == 0 {
                n.deviation == Real::INFINITY
            } else {
                n.deviation.is_finite()
                    && (3..=super::MAX_PIECE_VERTICES as u32).contains(&n.piece_len)
            };
            let right = n.right as usize;
            if !piece_ok || right <= i + 1 || right >= nodes.len() {
                return Err(corrupt("inner node"));
            }
            // Left (the next node) first: the right child must come right after the left
            // subtree.
            stack.push((right, level + 1));
            stack.push((i + 1, level + 1));
        }
    }
    if visited != nodes.len() || leaves != triangle_count {
        return Err(corrupt("tree structure"));
    }
    // Leaf counts, children first (they come after their parent).
    let mut below = vec![0u32; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = &nodes[i];
        below[i] = if n.is_leaf() {
            1
        } else {
            below[i + 1].saturating_add(below[n.right as usize])
        };
        if below[i] != n.triangles {
            return Err(corrupt("triangle counts"));
        }
    }
    Ok(height)
}

/// How each hierarchy of a [`LodBackend::with_cache`] came to be.
#[derive(Debug, Clone, PartialEq)]
pub enum CacheOutcome {
    /// Read from its file.
    Loaded(PathBuf),
    /// Built, and written to its file (there was none).
    Built(PathBuf),
    /// Built because its file could not be used (why), and written anew.
    Rebuilt(PathBuf, String),
    /// Built; writing its file failed (why): the next start builds again.
    NotSaved(PathBuf, String),
}

/// The hierarchy of `mesh` from `dir` (built and saved there if it is missing or unusable).
fn load_or_build(mesh: &TriMesh, dir: &Path) -> (Hierarchy, CacheOutcome) {
    let key = hierarchy_key(mesh);
    let path = dir.join(format!("lod-{key:016x}.bin"));
    let why = match std::fs::File::open(&path) {
        Ok(f) => match Hierarchy::read_from(std::io::BufReader::new(f), mesh) {
            Ok(h) => return (h, CacheOutcome::Loaded(path)),
            Err(HierarchyFileError::Io { source, .. }) => Some(
                HierarchyFileError::Io {
                    path: path.clone(),
                    source,
                }
                .to_string(),
            ),
            Err(e) => Some(e.to_string()),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => Some(e.to_string()),
    };
    let h = Hierarchy::build(mesh);
    // Written beside under a name of its own (process, and a counter across threads) and
    // renamed: a reader never sees half a file, and two writers never share one.
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!("lod-{key:016x}.bin.{}-{n}.tmp", std::process::id()));
    let written = std::fs::create_dir_all(dir)
        .and_then(|()| {
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp)
        })
        .and_then(|f| h.write_to(std::io::BufWriter::new(f), key))
        .and_then(|()| std::fs::rename(&tmp, &path));
    let outcome = match (written, why) {
        (Err(e), _) => {
            let _ = std::fs::remove_file(&tmp);
            CacheOutcome::NotSaved(path, e.to_string())
        }
        (Ok(()), Some(why)) => CacheOutcome::Rebuilt(path, why),
        (Ok(()), None) => CacheOutcome::Built(path),
    };
    (h, outcome)
}

impl LodBackend {
    /// [`LodBackend::new`], with each hierarchy read from `dir` when it was saved there for the
    /// same mesh and build, and built and saved there otherwise. A file that cannot be used is
    /// never used: the hierarchy is built again and the file replaced. Returns what happened to
    /// the tool's hierarchy, then each obstacle's.
    ///
    /// # Errors
    /// As [`LodBackend::new`].
    pub fn with_cache(
        tool: &TriMesh,
        obstacles: &[(TriMesh, Pose)],
        dir: &Path,
    ) -> Result<(Self, Vec<CacheOutcome>), LodError> {
        use rayon::prelude::*;
        let start = Instant::now();
        Self::check(tool, obstacles)?;
        // Both sides at once, as `new` builds them.
        let ((t, outcome), rest) = rayon::join(
            || load_or_build(tool, dir),
            || {
                obstacles
                    .par_iter()
                    .map(|(m, pose)| (load_or_build(m, dir), *pose))
                    .collect::<Vec<_>>()
            },
        );
        let mut outcomes = vec![outcome];
        let mut hierarchies = Vec::with_capacity(obstacles.len());
        for ((h, o), pose) in rest {
            hierarchies.push((h, pose));
            outcomes.push(o);
        }
        Ok((Self::from_hierarchies(t, hierarchies, start), outcomes))
    }
}

#[cfg(test)]
mod tests;
