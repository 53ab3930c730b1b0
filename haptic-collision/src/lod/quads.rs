//! Which triangles the build's split by position keeps together: the two halves of a quad.
//!
//! Meshes exported from CAD and modelling tools are often quads cut along a diagonal: a
//! cylinder's wall as full-length strips of two long triangles, a grid's cells. A triangle's
//! centroid then says little about where its surface lies: the two triangles of a strip have
//! centroids a third and two thirds along it. A median cut between them (`split.rs`) gives each
//! child a sawtooth over half the strip while its bounding piece spans the whole strip, and the
//! piece's area then counts surface that is not there (probe 26,
//! `docs/experiments/lod-accuracy-and-speed-probes.md`).
//!
//! Two triangles are a quad's halves when they share an edge that is the longest of both (the
//! quad's diagonal), no third triangle uses that edge, and their normals are within the crease
//! angle of each other (a cut along a crease keeps them apart anyway). The split by position
//! then places both at the quad's centroid and never cuts between them. Of the repository's
//! meshes, 54–92 % of the triangles pair up (the jaws' least, the peg's most; probe 27).
//! Neither half of a quad is ever cut from the other by the orientation split either: a cut
//! along a crease separates normals at least the crease angle apart.

use haptic_core::Vec3;

use super::split::CREASE_ANGLE_RAD;

/// No partner.
pub(super) const NONE: u32 = u32::MAX;

/// By triangle: its quad partner (or [`NONE`]). `triangles` are vertex indices, `corners` and
/// `area_normals` by the same triangle index.
pub(super) fn partners(
    triangles: &[[u32; 3]],
    corners: &[[Vec3; 3]],
    area_normals: &[Vec3],
) -> Vec<u32> {
    // Each triangle's longest edge, as a sorted vertex pair, with the triangle's index.
    let mut longest: Vec<((u32, u32), u32)> = triangles
        .iter()
        .zip(corners)
        .enumerate()
        .map(|(t, (v, c))| {
            let len = |i: usize| (c[(i + 1) % 3] - c[i]).norm_squared();
            let i = (0..3)
                .max_by(|&a, &b| len(a).total_cmp(&len(b)))
                .unwrap_or(0);
            let (a, b) = (v[i], v[(i + 1) % 3]);
            ((a.min(b), a.max(b)), t as u32)
        })
        .collect();
    longest.sort_unstable();
    // Every triangle using each edge, to refuse edges a third triangle also uses.
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|v| [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    let uses =
        |e: (u32, u32)| edges.partition_point(|&x| x <= e) - edges.partition_point(|&x| x < e);
    let min_cos = CREASE_ANGLE_RAD.cos();
    let coplanar = |s: usize, t: usize| {
        let (a, b) = (&area_normals[s], &area_normals[t]);
        let norms = a.norm() * b.norm();
        norms > 0.0 && a.dot(b) >= min_cos * norms
    };
    let mut partner = vec![NONE; triangles.len()];
    let mut i = 0;
    while i < longest.len() {
        let mut j = i + 1;
        while j < longest.len() && longest[j].0 == longest[i].0 {
            j += 1;
        }
        if j - i == 2 && uses(longest[i].0) == 2 {
            let (s, t) = (longest[i].1, longest[i + 1].1);
            if coplanar(s as usize, t as usize) {
                partner[s as usize] = t;
                partner[t as usize] = s;
            }
        }
        i = j;
    }
    partner
}

/// By triangle: where the split by position places it: the area-weighted centroid of its quad,
/// or its own centroid when it has no partner.
pub(super) fn positions(centroids: &[Vec3], area_normals: &[Vec3], partner: &[u32]) -> Vec<Vec3> {
    (0..centroids.len())
        .map(|t| match partner[t] {
            NONE => centroids[t],
            p => {
                let p = p as usize;
                let (a, b) = (area_normals[t].norm(), area_normals[p].norm());
                if a + b > 0.0 {
                    (centroids[t] * a + centroids[p] * b) / (a + b)
                } else {
                    centroids[t]
                }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::split::TriangleData;
    use crate::lod::testmesh;

    /// A cylinder's wall of full-length strips: every strip's two triangles are partners,
    /// placed at the strip's middle, half-way up the wall.
    #[test]
    fn a_cylinders_strips_are_quads() {
        let segments = 24;
        let mesh = testmesh::cylinder(0.004, 0.02, segments);
        let data = TriangleData::of(&mesh);
        let tris = mesh.triangles();
        for (t, &p) in data.partner.iter().enumerate() {
            if p == NONE {
                continue;
            }
            assert_eq!(data.partner[p as usize] as usize, t, "partners are mutual");
            let shared = tris[t]
                .iter()
                .filter(|v| tris[p as usize].contains(v))
                .count();
            assert_eq!(shared, 2, "partners share an edge");
        }
        // The wall's triangles come first in `testmesh::cylinder`, a strip's two together.
        for s in 0..segments {
            let (a, b) = (2 * s, 2 * s + 1);
            assert_eq!(data.partner[a] as usize, b, "strip {s}");
            assert!((data.positions[a].z - 0.01).abs() < 1e-12);
            assert_eq!(data.positions[a], data.positions[b]);
        }
    }

    /// The build never cuts a quad apart above the node of its two halves: on a cylinder's wall
    /// of strips, each child of a cut holds whole strips, and its piece spans the surface it
    /// holds (covers of at least 0.9; a strip cut apart gave a sawtooth over half its piece).
    #[test]
    fn the_build_keeps_a_quads_halves_together() {
        use crate::lod::build::Hierarchy;
        use crate::lod::topology::Tree;

        let segments = 48;
        let mesh = testmesh::cylinder(0.004, 0.03, segments);
        let data = TriangleData::of(&mesh);
        let tree = Tree::build(&data.view(), usize::MAX);
        let mut cuts = 0;
        for (i, node) in tree.nodes.iter().enumerate() {
            let (lo, hi) = tree.ranges[i];
            if node.is_leaf() || hi - lo <= 2 {
                continue;
            }
            let mid = tree.ranges[i + 1].1;
            let side = |t: u32| {
                tree.perm[lo as usize..hi as usize]
                    .iter()
                    .position(|&x| x == t)
            };
            for k in lo..hi {
                let t = tree.perm[k as usize];
                let p = data.partner[t as usize];
                if p == NONE {
                    continue;
                }
                let at = side(p).expect("partners in one node") as u32 + lo;
                assert_eq!(k < mid, at < mid, "node {i} cuts quad ({t}, {p}) apart");
            }
            cuts += 1;
        }
        assert!(cuts > segments / 2);
        // On an open tube of strips, every node's piece is covered by the strips it holds.
        let wall = 2 * segments;
        let tube = testmesh::mesh(mesh.vertices().to_vec(), mesh.triangles()[..wall].to_vec());
        let h = Hierarchy::build(&tube);
        for (i, node) in h.nodes.iter().enumerate() {
            let cover = h.moments_of(i as u32).cover;
            assert!(
                cover >= 0.9,
                "node {i} of {} triangles covers {cover}",
                node.triangles
            );
        }
    }

    /// Two triangles folded along their shared edge by more than the crease angle are not a
    /// quad, and neither are triangles whose shared edge is not the longest of both.
    #[test]
    fn folded_or_unequal_pairs_are_not_quads() {
        // Folded 90° along the diagonal x = y.
        let folded = testmesh::mesh(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        assert!(TriangleData::of(&folded).partner.iter().all(|&p| p == NONE));
        // Flat, but the shared edge (0,0)-(1,0) is the short side of the long second triangle.
        let unequal = testmesh::mesh(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.5, 0.4, 0.0),
                Vec3::new(0.5, -3.0, 0.0),
            ],
            vec![[0, 1, 2], [1, 0, 3]],
        );
        assert!(
            TriangleData::of(&unequal)
                .partner
                .iter()
                .all(|&p| p == NONE)
        );
        // The same flat pair across a square's diagonal is a quad.
        let square = testmesh::mesh(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        assert_eq!(TriangleData::of(&square).partner, vec![1, 0]);
    }
}
