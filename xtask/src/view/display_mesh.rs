//! Lighter copies of large meshes for drawing while the replay moves (scrubbing, playing,
//! orbiting): vertex clustering on a uniform grid (Rossignac & Borrel, 1993), with the cell
//! chosen by bisection so that the copy holds at most a triangle budget. The page draws the full
//! meshes whenever the view stands still, so what a user studies is the geometry as loaded; the
//! copies only keep the motion smooth on machines that draw slowly (a software renderer).
//!
//! Vertex clustering, not edge collapse: it is a few lines, runs in linear time, and a display
//! copy need not preserve topology. Its error is at most a cell's diagonal, which the page
//! reports.

use haptic_core::Vec3;
use std::collections::HashMap;

/// A display copy: vertices (m), triangles, and the grid cell it was clustered on (m).
#[derive(Debug, Clone, PartialEq)]
pub struct DisplayMesh {
    /// Vertex positions (m), each the mean of the vertices of its cell.
    pub vertices: Vec<Vec3>,
    /// Triangles as indices into `vertices`; none degenerate, none repeated.
    pub triangles: Vec<[u32; 3]>,
    /// The grid cell's edge (m): vertices moved by at most its diagonal, `√3 · cell_m`.
    pub cell_m: f64,
}

/// Clusters `vertices` on a grid of edge `cell_m` and keeps the triangles whose corners fall in
/// three different cells (each once).
fn cluster(vertices: &[Vec3], triangles: &[[u32; 3]], origin: Vec3, cell_m: f64) -> DisplayMesh {
    let mut cell_of: HashMap<[i64; 3], u32> = HashMap::new();
    let mut sums: Vec<(Vec3, f64)> = Vec::new();
    let index: Vec<u32> = vertices
        .iter()
        .map(|v| {
            let c = (v - origin) / cell_m;
            let key = [c.x.floor() as i64, c.y.floor() as i64, c.z.floor() as i64];
            let next = sums.len() as u32;
            let i = *cell_of.entry(key).or_insert(next);
            if i == next {
                sums.push((Vec3::zeros(), 0.0));
            }
            sums[i as usize].0 += v;
            sums[i as usize].1 += 1.0;
            i
        })
        .collect();
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for t in triangles {
        let [a, b, c] = t.map(|i| index[i as usize]);
        if a == b || b == c || a == c {
            continue;
        }
        // The same triangle in either orientation counts once (keep the first).
        let mut key = [a, b, c];
        key.sort_unstable();
        if seen.insert(key) {
            out.push([a, b, c]);
        }
    }
    DisplayMesh {
        vertices: sums.into_iter().map(|(s, n)| s / n).collect(),
        triangles: out,
        cell_m,
    }
}

/// A copy of the mesh with at most `budget` triangles, or `None` when the mesh is within the
/// budget already (or is empty or has no extent). The cell is the smallest found by bisection
/// (20 halvings of the bracket) whose clustering fits the budget.
pub fn simplified(vertices: &[Vec3], triangles: &[[u32; 3]], budget: usize) -> Option<DisplayMesh> {
    if triangles.len() <= budget || vertices.is_empty() {
        return None;
    }
    let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
    for v in vertices {
        lo = lo.inf(v);
        hi = hi.sup(v);
    }
    let extent = (hi - lo).max();
    if !(extent.is_finite() && extent > 0.0) {
        return None;
    }
    // A cell as large as the mesh leaves no triangle: the budget is met at `extent`.
    let (mut small, mut large) = (extent * 1e-6, extent);
    let mut best = cluster(vertices, triangles, lo, large);
    for _ in 0..20 {
        let mid = (small * large).sqrt();
        let m = cluster(vertices, triangles, lo, mid);
        if m.triangles.len() <= budget {
            large = mid;
            best = m;
        } else {
            small = mid;
        }
    }
    Some(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UV sphere of radius 1 with `n` rings and `2n` segments.
    fn sphere(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut v = Vec::new();
        for i in 0..=n {
            let th = std::f64::consts::PI * i as f64 / n as f64;
            for j in 0..2 * n {
                let ph = std::f64::consts::PI * j as f64 / n as f64;
                v.push(Vec3::new(
                    th.sin() * ph.cos(),
                    th.sin() * ph.sin(),
                    th.cos(),
                ));
            }
        }
        let mut t = Vec::new();
        for i in 0..n {
            for j in 0..2 * n {
                let a = i * 2 * n + j;
                let b = i * 2 * n + (j + 1) % (2 * n);
                let (c, d) = (a + 2 * n, b + 2 * n);
                t.push([a, c, b]);
                t.push([b, c, d]);
            }
        }
        (v, t)
    }

    #[test]
    fn a_large_mesh_fits_its_budget_and_keeps_its_shape() {
        let (v, t) = sphere(120); // 57,600 triangles
        let m = simplified(&v, &t, 5_000).expect("over budget");
        assert!(m.triangles.len() <= 5_000, "{}", m.triangles.len());
        assert!(
            m.triangles.len() > 2_000,
            "{} (too coarse)",
            m.triangles.len()
        );
        // Vertices stay within a cell's diagonal of the surface (the sphere of radius 1).
        let tolerance = 3f64.sqrt() * m.cell_m;
        for p in &m.vertices {
            assert!(
                (p.norm() - 1.0).abs() <= tolerance,
                "{} off by more than {tolerance}",
                p.norm()
            );
        }
        assert!(
            m.triangles
                .iter()
                .flatten()
                .all(|&i| (i as usize) < m.vertices.len())
        );
        assert!(
            m.triangles
                .iter()
                .all(|[a, b, c]| a != b && b != c && a != c)
        );
    }

    #[test]
    fn a_mesh_within_its_budget_is_left_alone() {
        let (v, t) = sphere(10);
        assert!(simplified(&v, &t, t.len()).is_none());
        assert!(simplified(&[], &[], 0).is_none());
    }
}
