//! The hierarchy's topology: the binary tree of triangle ranges, split top-down (`split.rs`),
//! with nodes in depth-first pre-order. Large subtrees build their two children in parallel.

use haptic_core::Vec3;

use super::build::{LEAF, Node};
use super::split::{SplitScratch, Triangles};

/// A node of `triangles` triangles whose first one is `triangle`, with no geometry yet.
fn blank_node(triangle: u32, triangles: u32) -> Node {
    Node {
        center: Vec3::zeros(),
        radius: 0.0,
        normal: Vec3::z(),
        plane_point: Vec3::zeros(),
        half_thickness: 0.0,
        deviation: 0.0,
        right: LEAF,
        triangle,
        piece_start: 0,
        piece_len: 0,
        triangles,
    }
}

/// Subtrees with at least this many triangles split their two children's topologies in parallel.
pub(super) const PARALLEL_TOPOLOGY_MIN: usize = 4096;

/// A hierarchy's topology: its nodes (no geometry yet) in depth-first pre-order, each node's
/// range in `perm`, the triangles' order, and the height.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Tree {
    /// The nodes, `2 n − 1` for `n` triangles: counts, children and leaf triangles set, the
    /// geometry not yet.
    pub nodes: Vec<Node>,
    /// By node: its triangles' range `[lo, hi)` in `perm`.
    pub ranges: Vec<(u32, u32)>,
    /// The triangles' source indices, in the order the nodes' ranges read them.
    pub perm: Vec<u32>,
    /// Depth of the deepest leaf (the root at 1).
    pub height: usize,
}

impl Tree {
    /// The topology of `triangles` (at least one), subtrees of at least `parallel_min`
    /// triangles building their two children in parallel ([`PARALLEL_TOPOLOGY_MIN`] in a build).
    pub(super) fn build(triangles: &Triangles<'_>, parallel_min: usize) -> Self {
        let n = triangles.corners.len();
        let mut perm: Vec<u32> = (0..n as u32).collect();
        let mut nodes = vec![blank_node(0, 0); 2 * n - 1];
        let mut ranges = vec![(0, 0); 2 * n - 1];
        let at = Place {
            lo: 0,
            base: 0,
            level: 1,
        };
        let height = topology(
            triangles,
            &mut perm,
            &mut nodes,
            &mut ranges,
            at,
            parallel_min,
        );
        Self {
            nodes,
            ranges,
            perm,
            height,
        }
    }
}

/// Where a subtree sits in the hierarchy being built.
#[derive(Debug, Clone, Copy)]
struct Place {
    /// Its first triangle's position in the whole permutation.
    lo: u32,
    /// Its root's node index.
    base: u32,
    /// Its root's depth (the hierarchy's root is at 1).
    level: usize,
}

/// Builds the topology of the subtree at `at` over `perm` (its triangles, reordered in place)
/// into `nodes` and `ranges` (its `2 perm.len() − 1` nodes in depth-first pre-order) and returns
/// its height (deepest level). A node's index follows from its place (the left child of `i` is
/// `i + 1`, the right one `i + 2 · left triangles`), so subtrees of at least `parallel_min`
/// triangles build their two children at once, with the same result.
fn topology(
    triangles: &Triangles<'_>,
    perm: &mut [u32],
    nodes: &mut [Node],
    ranges: &mut [(u32, u32)],
    at: Place,
    parallel_min: usize,
) -> usize {
    let n = perm.len();
    let mut scratch = SplitScratch::default();
    if n >= parallel_min.max(2) {
        nodes[0] = blank_node(perm[0], n as u32);
        ranges[0] = (at.lo, at.lo + n as u32);
        let cut = triangles.split(perm, &mut scratch);
        nodes[0].right = at.base + 2 * cut as u32;
        let (perm_l, perm_r) = perm.split_at_mut(cut);
        let (nodes_l, nodes_r) = nodes[1..].split_at_mut(2 * cut - 1);
        let (ranges_l, ranges_r) = ranges[1..].split_at_mut(2 * cut - 1);
        let left = Place {
            lo: at.lo,
            base: at.base + 1,
            level: at.level + 1,
        };
        let right = Place {
            lo: at.lo + cut as u32,
            base: at.base + 2 * cut as u32,
            level: at.level + 1,
        };
        let (height_l, height_r) = rayon::join(
            || topology(triangles, perm_l, nodes_l, ranges_l, left, parallel_min),
            || topology(triangles, perm_r, nodes_r, ranges_r, right, parallel_min),
        );
        return height_l.max(height_r);
    }
    let (lo, base) = (at.lo, at.base);
    // (first triangle, end, node index, level), all local to this subtree.
    let mut todo: Vec<(usize, usize, usize, usize)> = vec![(0, n, 0, at.level)];
    let mut height = at.level;
    while let Some((first, end, index, level)) = todo.pop() {
        height = height.max(level);
        nodes[index] = blank_node(perm[first], (end - first) as u32);
        ranges[index] = (lo + first as u32, lo + end as u32);
        if end - first > 1 {
            let cut = triangles.split(&mut perm[first..end], &mut scratch);
            let right = index + 2 * cut;
            nodes[index].right = base + right as u32;
            todo.push((first + cut, end, right, level + 1));
            todo.push((first, first + cut, index + 1, level + 1));
        }
    }
    height
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::split::TriangleData;
    use crate::lod::testmesh;

    #[test]
    fn parallel_and_serial_topologies_are_the_same_tree() {
        let mesh = testmesh::bumpy_sphere(4, 1.0, 0.1, 7);
        let data = TriangleData::of(&mesh);
        let serial = Tree::build(&data.view(), usize::MAX);
        for parallel_min in [2, 3, 64, 1000] {
            let parallel = Tree::build(&data.view(), parallel_min);
            assert_eq!(parallel, serial, "parallel_min {parallel_min}");
        }
        // A well-formed pre-order tree: children after their parent, ranges split at the left
        // child's end, every triangle in one leaf.
        let Tree {
            nodes,
            ranges,
            perm,
            height,
        } = serial;
        let mut leaves = vec![0; perm.len()];
        for (i, node) in nodes.iter().enumerate() {
            let (lo, hi) = ranges[i];
            assert_eq!(node.triangles, hi - lo);
            if node.is_leaf() {
                assert_eq!(hi - lo, 1);
                leaves[perm[lo as usize] as usize] += 1;
            } else {
                let (l, r) = (i + 1, node.right as usize);
                assert_eq!(ranges[l], (lo, ranges[r].0));
                assert_eq!(ranges[r].1, hi);
                assert_eq!(r, i + 2 * (ranges[l].1 - ranges[l].0) as usize);
            }
        }
        assert!(leaves.iter().all(|&k| k == 1));
        // The root is at level 1, a tree of n leaves is at least ⌈log₂ n⌉ levels deeper.
        assert!(height > (perm.len() as f64).log2().ceil() as usize);
    }
}
