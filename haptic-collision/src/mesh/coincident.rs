//! Triangles on the same three vertices as another: a duplicate, or the other side of a sheet.
//!
//! The penalty is integrated over each triangle's region (`docs/formulation.md` §7), so a
//! triangle listed twice pushes twice. Two triangles on the same vertices wound opposite ways
//! are a surface facing out on both sides at once, a sheet with no inside: over it, one side
//! says the tool is outside and the other that it is a penetration depth inside, and the two
//! penalties pull it through. Both come from exporters and from meshes merged by hand.
//! [`TriMesh::coincident_triangles`] counts them; the loader drops duplicates
//! ([`crate::LoadReport::duplicates_dropped`]), and the back-ends refuse a mesh that still has
//! either (a thin part must be modelled with a thickness).

use rayon::slice::ParallelSliceMut;

use super::TriMesh;

/// Triangles that lie on the same three vertices as another ([`TriMesh::coincident_triangles`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CoincidentTriangles {
    /// Triangles wound the same way as an earlier one on the same vertices: each pushes twice.
    pub duplicates: usize,
    /// Pairs of triangles on the same vertices wound opposite ways: a sheet with no inside.
    pub two_sided: usize,
}

impl CoincidentTriangles {
    /// Whether there are none.
    pub fn is_none(&self) -> bool {
        self.duplicates == 0 && self.two_sided == 0
    }
}

/// Each triangle's vertices sorted, whether that took an odd permutation (the winding's other
/// way), and its index; sorted by vertices.
fn keyed(mesh: &TriMesh) -> Vec<([u32; 3], bool, u32)> {
    let mut keys: Vec<([u32; 3], bool, u32)> = mesh
        .triangles()
        .iter()
        .enumerate()
        .map(|(t, &[a, b, c])| {
            // The rotation that starts at the smallest vertex keeps the winding; then the
            // other two in order or swapped.
            let [a, b, c] = if a <= b && a <= c {
                [a, b, c]
            } else if b <= c {
                [b, c, a]
            } else {
                [c, a, b]
            };
            if b <= c {
                ([a, b, c], false, t as u32)
            } else {
                ([a, c, b], true, t as u32)
            }
        })
        .collect();
    keys.par_sort_unstable();
    keys
}

impl TriMesh {
    /// The triangles on the same three vertices as another (see the module docs).
    pub fn coincident_triangles(&self) -> CoincidentTriangles {
        let keys = keyed(self);
        let mut found = CoincidentTriangles::default();
        let mut i = 0;
        while i < keys.len() {
            let mut j = i + 1;
            while j < keys.len() && keys[j].0 == keys[i].0 {
                j += 1;
            }
            let odd = keys[i..j].iter().filter(|k| k.1).count();
            let even = (j - i) - odd;
            found.duplicates += odd.saturating_sub(1) + even.saturating_sub(1);
            found.two_sided += odd.min(even);
            i = j;
        }
        found
    }

    /// The mesh without the triangles wound the same way as an earlier one on the same
    /// vertices (the first of each kept, the order kept), and how many were dropped.
    pub fn without_duplicates(&self) -> (Self, usize) {
        let keys = keyed(self);
        let mut drop = vec![false; self.triangles().len()];
        let mut count = 0;
        // Sorted by vertices, then winding, then index: a repeat follows its first.
        for pair in keys.windows(2) {
            if (pair[0].0, pair[0].1) == (pair[1].0, pair[1].1) {
                drop[pair[1].2 as usize] = true;
                count += 1;
            }
        }
        let triangles = self
            .triangles()
            .iter()
            .zip(&drop)
            .filter(|&(_, &d)| !d)
            .map(|(&t, _)| t)
            .collect();
        (
            Self {
                vertices: self.vertices().to_vec(),
                triangles,
            },
            count,
        )
    }
}

#[cfg(test)]
mod tests;
