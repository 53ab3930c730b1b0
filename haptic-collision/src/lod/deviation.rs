//! The piece → surface side of a node's deviation: how far any point of its simplified piece can
//! be from the mesh surface, bounded through the pieces of nearby smaller nodes (whose own
//! deviations are final by then). The build's costliest step (`docs/experiments/lod-build-time.md`).

use haptic_core::{Real, Vec3};

use super::MAX_PIECE_VERTICES;
use super::build::Node;
use crate::geometry::{closest_point_on_polygon_2d, plane_basis};

/// A small convex polygon in a node's plane (2-D, fixed capacity, CCW).
#[derive(Debug, Clone, Copy)]
struct Poly2<const CAP: usize = POLY2_CAP> {
    pts: [[Real; 2]; CAP],
    len: usize,
}

/// Capacity of [`Poly2`]: a hexagon clipped by two hexagons' half-planes stays far below it.
pub(crate) const POLY2_CAP: usize = 24;

impl<const CAP: usize> Default for Poly2<CAP> {
    fn default() -> Self {
        Self {
            pts: [[0.0; 2]; CAP],
            len: 0,
        }
    }
}

impl<const CAP: usize> Poly2<CAP> {
    fn push(&mut self, p: [Real; 2]) {
        if self.len < CAP {
            self.pts[self.len] = p;
            self.len += 1;
        }
    }

    fn as_slice(&self) -> &[[Real; 2]] {
        &self.pts[..self.len]
    }

    fn signed_area(&self) -> Real {
        let mut a = 0.0;
        for i in 0..self.len {
            let (p, q) = (
                self.pts[i],
                self.pts[if i + 1 == self.len { 0 } else { i + 1 }],
            );
            a += p[0] * q[1] - p[1] * q[0];
        }
        0.5 * a
    }

    fn reverse(&mut self) {
        self.pts[..self.len].reverse();
    }

    /// Whether `other` lies entirely outside one of this polygon's edges (then they do not
    /// overlap).
    fn beside<const N: usize>(&self, other: &Poly2<N>) -> bool {
        let n = self.len;
        (0..n).any(|i| {
            let (a, b) = (self.pts[i], self.pts[if i + 1 == n { 0 } else { i + 1 }]);
            other
                .as_slice()
                .iter()
                .all(|p| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) < 0.0)
        })
    }

    /// Makes `self` a copy of `other` (its points only).
    fn assign(&mut self, other: &Self) {
        self.pts[..other.len].copy_from_slice(other.as_slice());
        self.len = other.len;
    }

    /// Writes into `out` the part of `self` on the left of the directed line `a → b` (closed
    /// half-plane).
    fn clip_into(&self, a: &[Real; 2], b: &[Real; 2], out: &mut Self) {
        let side = |p: &[Real; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        out.len = 0;
        let n = self.len;
        if n == 0 {
            return;
        }
        let mut p = self.pts[0];
        let mut sp = side(&p);
        for i in 0..n {
            let q = self.pts[if i + 1 == n { 0 } else { i + 1 }];
            let sq = side(&q);
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp > 0.0 && sq < 0.0) || (sp < 0.0 && sq > 0.0) {
                let t = sp / (sp - sq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
            (p, sp) = (q, sq);
        }
    }
}

/// Scratch of [`final_deviation`]: the candidates, the walk's stack, the candidates' gaps.
pub(super) type DeviationScratch = (Vec<usize>, Vec<usize>, Vec<(Real, usize, usize)>);

/// The final (two-sided) deviation of inner node `index`: its surface → piece part, already in
/// `nodes`, and the piece → surface part bounded through nearby smaller nodes.
pub(super) fn final_deviation(
    index: usize,
    nodes: &[Node],
    pieces: &[([Vec3; MAX_PIECE_VERTICES], usize)],
    count: &(dyn Fn(usize) -> u32 + Sync),
    cands: &mut Vec<usize>,
    walk: &mut Vec<usize>,
    gaps: &mut Vec<(Real, usize, usize)>,
) -> Real {
    let node = nodes[index];
    if !node.deviation.is_finite() {
        return node.deviation;
    }
    cands.clear();
    walk.clear();
    walk.push(0);
    while let Some(m) = walk.pop() {
        let nm = &nodes[m];
        let reach = nm.radius + node.radius;
        if (nm.center - node.center).norm_squared() > reach * reach {
            continue;
        }
        if count(m) < count(index) {
            cands.push(m);
        } else if !nm.is_leaf() {
            walk.push(m + 1);
            walk.push(nm.right as usize);
        }
    }
    if cands.len() > MAX_CANDIDATES {
        // The node's own children, whose pieces stand for all of its triangles, then the
        // nearest others (any subset keeps the bound rigorous, only looser), nearest first,
        // ties in walk order. By gap alone, a thin plate's flat node lost its children to the
        // pieces of the face beneath it and of its neighbours, equally near, and its bound was
        // a cell of the grid: deviations of 8 mm on a flat face.
        let children = [index + 1, node.right as usize];
        let gap = |m: usize| {
            if children.contains(&m) {
                Real::NEG_INFINITY
            } else {
                (nodes[m].center - node.center).norm() - nodes[m].radius
            }
        };
        gaps.clear();
        gaps.extend(cands.iter().enumerate().map(|(k, &m)| (gap(m), k, m)));
        let by_gap = |a: &(Real, usize, usize), b: &(Real, usize, usize)| {
            a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
        };
        gaps.select_nth_unstable_by(MAX_CANDIDATES - 1, by_gap);
        gaps[..MAX_CANDIDATES].sort_unstable_by(by_gap);
        cands.clear();
        cands.extend(gaps[..MAX_CANDIDATES].iter().map(|g| g.2));
    }
    let s_in = piece_to_surface(&node, &pieces[index], cands, nodes, pieces);
    let cap = (1.0 + std::f64::consts::SQRT_2) * node.radius;
    s_in.min(cap)
}

/// Most neighbouring nodes used to bound a piece's distance to the surface.
pub(crate) const MAX_CANDIDATES: usize = 10;

/// Most convex regions tracked while cutting a piece along its neighbours' pieces.
pub(crate) const MAX_REGIONS: usize = 32;

/// A candidate node as [`piece_to_surface`] reads it: its sphere, and its piece in its own plane
/// (the basis `u, w` of its normal `n`, coordinates about the piece's first vertex `origin`).
#[derive(Debug, Clone, Copy)]
struct CandidateFrame {
    center: Vec3,
    radius: Real,
    /// The node's two-sided deviation; infinite (with no piece) when it has none.
    deviation: Real,
    origin: Vec3,
    n: Vec3,
    u: Vec3,
    w: Vec3,
    piece: [[Real; 2]; MAX_PIECE_VERTICES],
    /// Vertices of `piece`; below 3, only the sphere bound is used.
    len: usize,
}

impl CandidateFrame {
    const NONE: Self = Self {
        center: Vec3::new(0.0, 0.0, 0.0),
        radius: Real::INFINITY,
        deviation: Real::INFINITY,
        origin: Vec3::new(0.0, 0.0, 0.0),
        n: Vec3::new(0.0, 0.0, 0.0),
        u: Vec3::new(0.0, 0.0, 0.0),
        w: Vec3::new(0.0, 0.0, 0.0),
        piece: [[0.0; 2]; MAX_PIECE_VERTICES],
        len: 0,
    };

    fn of(node: &Node, (verts, len): &([Vec3; MAX_PIECE_VERTICES], usize)) -> Self {
        let mut frame = Self {
            center: node.center,
            radius: node.radius,
            deviation: node.deviation,
            ..Self::NONE
        };
        if node.deviation.is_finite() && *len >= 3 {
            let (u, w) = plane_basis(&node.normal);
            let origin = verts[0];
            for (p, v) in frame.piece.iter_mut().zip(&verts[..*len]) {
                let d = v - origin;
                *p = [u.dot(&d), w.dot(&d)];
            }
            frame.origin = origin;
            frame.n = node.normal;
            frame.u = u;
            frame.w = w;
            frame.len = *len;
        }
        frame
    }

    /// The smaller of `|q − centre| + r` and `dist(q, piece) + s` when it is below `limit`, else
    /// some value at least `limit`: both bound `dist(q, S)`. The piece is planar and CCW about
    /// `n`, so its distance is the 2-D distance in its plane and the height above it, combined.
    #[inline]
    fn term(&self, q: &Vec3, limit: Real) -> Real {
        let t = (q - self.center).norm() + self.radius;
        if self.len >= 3 {
            let d = q - self.origin;
            let h = self.n.dot(&d);
            if h.abs() + self.deviation < t.min(limit) {
                let p = [self.u.dot(&d), self.w.dot(&d)];
                let c = closest_point_on_polygon_2d(p, &self.piece[..self.len]);
                let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
                return t.min((h * h + dx * dx + dy * dy).sqrt() + self.deviation);
            }
        }
        t
    }
}

/// Upper bound on `sup_{q ∈ piece} dist(q, S)`, `S` the whole mesh surface, or `node.deviation`
/// (the surface → piece part) when that is larger: the larger of the two is the two-sided
/// deviation, so a region whose bound is already below `node.deviation` needs no tighter one.
///
/// For any node `m`, `dist(q, S) <= dist(q, piece_m) + s_m` (its two-sided deviation) and
/// `dist(q, S) <= |q − centre_m| + r_m`. Both are convex in `q`, so over a convex region their
/// maximum is at a vertex. The piece (in 2-D, in its plane) is cut along the projections of the
/// candidates' pieces, best-aligned first: each region above candidate `m` is bounded with `m`'s
/// term, and what no candidate covers with the smallest of all terms' vertex maxima. A region
/// whose vertices the next candidate's term already bounds by the running maximum is dropped
/// before it is cut (nothing in it can raise the maximum).
fn piece_to_surface(
    node: &Node,
    own: &([Vec3; MAX_PIECE_VERTICES], usize),
    cands: &[usize],
    nodes: &[Node],
    pieces: &[([Vec3; MAX_PIECE_VERTICES], usize)],
) -> Real {
    let n = node.normal;
    let (u, w) = plane_basis(&n);
    let o = node.plane_point;
    let to2 = |v: &Vec3| -> [Real; 2] {
        let d = v - o;
        [u.dot(&d), w.dot(&d)]
    };
    let to3 = |p: &[Real; 2]| o + u * p[0] + w * p[1];
    // Each candidate's piece in its own plane, once: the distance to it is then a 2-D closest
    // point and the height above the plane.
    let mut frames = [CandidateFrame::NONE; MAX_CANDIDATES];
    for (frame, &m) in frames.iter_mut().zip(cands) {
        *frame = CandidateFrame::of(&nodes[m], &pieces[m]);
    }
    let frames = &frames[..cands.len().min(MAX_CANDIDATES)];
    // `term(k, q, limit)`: the smaller of candidate k's two bounds at q when it is below
    // `limit`, else some value at least `limit`. The polygon distance (the costly part) is
    // skipped when its lower bound, the distance to k's plane, already reaches the sphere bound
    // or `limit`: the result is then the same as with it.
    let term = |k: usize, q: &Vec3, limit: Real| frames[k].term(q, limit);
    let mut q_poly = Poly2::<POLY2_CAP>::default();
    for v in &own.0[..own.1] {
        q_poly.push(to2(v));
    }
    // Candidates with a usable projected piece, best first (closest to this plane).
    let mut usable: Vec<(Real, usize, Poly2<MAX_PIECE_VERTICES>)> = Vec::with_capacity(cands.len());
    for (k, frame) in frames.iter().enumerate() {
        // A candidate without a piece bounds through its sphere only (`term`).
        if frame.len < 3 {
            continue;
        }
        let (verts, len) = &pieces[cands[k]];
        let mut p = Poly2::<MAX_PIECE_VERTICES>::default();
        let mut off: Real = 0.0;
        for v in &verts[..*len] {
            p.push(to2(v));
            off = off.max(n.dot(&(v - o)).abs());
        }
        let area = p.signed_area();
        if area.abs() <= 1e-12 * node.radius * node.radius {
            continue;
        }
        if area < 0.0 {
            p.reverse();
        }
        usable.push((off + frame.deviation, k, p));
    }
    usable.sort_by(|a, b| a.0.total_cmp(&b.0));
    // min over candidates of (max over the region's vertices of the candidate's term), below
    // `start`; any value at most `enough` once one is found (the caller takes the max with it).
    let best_term = |verts: &[[Real; 2]], start: Real, enough: Real| -> Real {
        let mut best = start;
        for k in 0..frames.len() {
            if best <= enough {
                break;
            }
            let mut worst: Real = 0.0;
            for v in verts {
                worst = worst.max(term(k, &to3(v), best));
                if worst >= best {
                    break;
                }
            }
            best = best.min(worst);
        }
        best
    };
    let mut s_in: Real = node.deviation;
    let mut rest: Vec<Poly2> = vec![q_poly];
    let mut next: Vec<Poly2> = Vec::new();
    // Clipping buffers, ping-ponged by reference.
    let (mut buf_a, mut buf_b, mut outside) =
        (Poly2::default(), Poly2::default(), Poly2::default());
    for (_, k, p) in &usable {
        if rest.is_empty() {
            break;
        }
        next.clear();
        for piece in &rest {
            // A region that m's term bounds by `s_in` as a whole is done.
            let mut whole: Real = 0.0;
            for v in piece.as_slice() {
                whole = whole.max(term(*k, &to3(v), s_in));
                if whole > s_in {
                    break;
                }
            }
            if whole <= s_in {
                continue;
            }
            // The part above candidate m, and the rest of the piece as disjoint convex parts:
            // the same half-planes cut both, and what is left after the last is the part above.
            if p.beside(piece) {
                next.push(*piece);
                continue;
            }
            let mark = next.len();
            let (mut inside, mut spare) = (&mut buf_a, &mut buf_b);
            inside.assign(piece);
            for i in 0..p.len {
                let (p0, p1) = (p.pts[i], p.pts[if i + 1 == p.len { 0 } else { i + 1 }]);
                inside.clip_into(&p1, &p0, &mut outside);
                if outside.len >= 3 && outside.signed_area() > 0.0 {
                    next.push(outside);
                }
                inside.clip_into(&p0, &p1, spare);
                std::mem::swap(&mut inside, &mut spare);
                if inside.len < 3 {
                    break;
                }
            }
            if inside.len < 3 {
                // Nothing above m: the piece goes on whole.
                next.truncate(mark);
                next.push(*piece);
                continue;
            }
            let mut b: Real = 0.0;
            for v in inside.as_slice() {
                b = b.max(term(*k, &to3(v), Real::INFINITY));
            }
            if b > s_in {
                // Slivers left by rounding can land on a poor candidate: try every term.
                b = b.min(best_term(inside.as_slice(), b, s_in));
                s_in = s_in.max(b);
            }
        }
        std::mem::swap(&mut rest, &mut next);
        if rest.len() > MAX_REGIONS {
            break;
        }
    }
    // Whatever is left: the best single term per region.
    for r in &rest {
        s_in = s_in.max(best_term(r.as_slice(), Real::INFINITY, s_in));
    }
    s_in
}
