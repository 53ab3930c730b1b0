//! The contact of two convex polygons as the penalty integrated over the tool polygon: the part
//! of the tool polygon `A` that lies over the obstacle polygon `B` (inside `B`'s prism) and
//! within `δ` of `B`'s plane (`docs/formulation.md` §7).
//!
//! The obstacle's faces are oriented (outward normals): over `B`, a point of `A` at height `h`
//! above `B`'s plane has depth `d = −h` (positive below the face, inside the obstacle), and the
//! penalty weighs it by the gap `g = d + δ = δ − h` (eq. 28's weight per unit area), for
//! `−δ ≤ h ≤ δ`. The region's contact keeps what the clustering reads of the integral over the
//! region: `∫g`, `∫g x` and `∫g (g − δ)`, that is the weight, its centroid and its weighted mean
//! depth (area `(∫g)²/∫g²`, depth `∫g²/∫g − δ`, at the `g`-weighted centroid). They are exact:
//! closed forms on the fan of the clipped polygon where `g` is linear, a quadrature of degree 5
//! within the spread's band at the top (`Sums`).
//!
//! Because the prisms of neighbouring obstacle triangles only share walls, and a tool polygon's
//! integrals add up over any partition of it, the sums over triangle pairs do not depend on how
//! either flat surface is tessellated: the all-pairs reference converges as a mesh is refined.
//! A separating-axis depth, which measures two crossing triangles' sizes rather than how far the
//! tool has gone in, never enters; the exact closest approach between two polygons, which may lie
//! on their edges outside every region, is found separately (`lod::query::closest_approaches`).
//!
//! A coarse pair stands for the surfaces its pieces simplify, which lie about the pieces by the
//! nodes' measured height offsets ([`HeightOffset`], from `lod/moments.rs`): the heights are
//! shifted by the mean offset, and the weight is averaged over a uniform spread of the same
//! variance ([`Weight`]). Without the spread a flat piece has less variance of depth than its
//! surface, and the clustering's mean depth, read from `∫g²`, comes out shallower. Its contact
//! pushes along the obstacle surface's normal at the region's centroid, from the piece's normal
//! field (`NormalField::normal_at` in `lod/moments.rs`, given to [`RegionContact::pair_contact`] by the walk),
//! not along the piece's mean normal.

use haptic_core::{Real, Vec3, gap_weight_m};

use crate::geometry::{PairContact, plane_basis};
use crate::lod::{MAX_PIECE_VERTICES, SurfaceMoments};

/// Most vertices a clipped polygon can have: the tool polygon's, one more per prism wall and per
/// slab plane.
const MAX_CLIPPED: usize = 2 * MAX_PIECE_VERTICES + 3;

/// A polygon in `B`'s frame: `[u, w, h]`, `h` the height above `B`'s plane.
type Poly = ([[Real; 3]; MAX_CLIPPED], usize);

/// Where the surfaces two pieces simplify lie about the pieces: the height of the tool's
/// surface above the obstacle's, less the pieces' own, is taken uniform in
/// `mean_m ± half_width_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct HeightOffset {
    /// Mean offset (m).
    pub mean_m: Real,
    /// Half-width (m): `√3` times the standard deviation.
    pub half_width_m: Real,
}

impl HeightOffset {
    /// Triangles: the polygons are the surfaces.
    pub const NONE: Self = Self {
        mean_m: 0.0,
        half_width_m: 0.0,
    };

    /// For a tool piece and an obstacle piece with the surface moments `tool` and `obstacle`,
    /// `cos_ab` the dot product of their normals: the tool's surface lies `e_a` along its normal
    /// from its piece and the obstacle's `e_b` along its own, so the height gains
    /// `e_a cos_ab − e_b` (mean and variance from the moments, the two taken independent).
    pub fn of_pieces(tool: &SurfaceMoments, obstacle: &SurfaceMoments, cos_ab: Real) -> Self {
        let var = tool.height_var_m2 * cos_ab * cos_ab + obstacle.height_var_m2;
        Self {
            mean_m: tool.height_mean_m * cos_ab - obstacle.height_mean_m,
            half_width_m: (3.0 * var).sqrt(),
        }
    }

    /// How much nearer than the pieces the surfaces they stand for may come (m): the mean's
    /// size plus the half-width. [`pair_region`] integrates no farther than `δ` plus this.
    pub fn reach_m(&self) -> Real {
        self.mean_m.abs() + self.half_width_m
    }
}

/// The contact that stands for a region: what the clustering reads of the integral.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RegionContact {
    /// The area it stands for (m²): `(∫g)² / ∫g²`, so that `area · (d + δ) = ∫g`.
    pub area_m2: Real,
    /// The `g`-weighted centroid (in the frame the polygons were given in).
    pub centroid: Vec3,
    /// The contact's depth (m): `∫g² / ∫g − δ`, the `g`-weighted mean of `g − δ`.
    pub depth_m: Real,
    /// Whether the pieces themselves lie apart, nearer than that mean only through the
    /// surfaces they stand for, so that the depth is held at their distance (and the weight
    /// `∫g` the surfaces give is kept in the area): what the pieces say of the force is then
    /// least sure.
    pub pieces_apart: bool,
}

impl RegionContact {
    /// Whether the pieces lie beyond `delta_m` of each other, within reach only through the
    /// surfaces they stand for: the depth is held at `−δ` and the weight `∫g` the surfaces give
    /// is next to nothing, whatever those surfaces push where they come within `δ`.
    pub fn pieces_beyond(&self, delta_m: Real) -> bool {
        self.pieces_apart && self.depth_m <= -delta_m
    }

    /// As a pair result against an obstacle polygon of unit normal `nb`: `n = −n_b` (out of
    /// the tool), `p_b = p_a − d n` (on the obstacle polygon's plane, shifted by any offset).
    pub fn pair_contact(&self, nb: &Vec3) -> PairContact {
        PairContact {
            p_a: self.centroid,
            p_b: self.centroid + nb * self.depth_m,
            n: -nb,
            depth: self.depth_m,
            distance: -self.depth_m,
        }
    }
}

/// The region of a tool polygon over an obstacle polygon (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PairRegion {
    /// The part of `A` over `B` within reach of its plane, as one contact.
    pub region: Option<RegionContact>,
    /// The smallest `|h|` over the part of `A` over `B` within `δ` (m): the exact distance from
    /// that part to `B`, 0 where they cross; infinite when there is none.
    pub nearest_m: Real,
}

impl PairRegion {
    /// No part of `A` over `B` within reach.
    const NONE: Self = Self {
        region: None,
        nearest_m: Real::INFINITY,
    };
}

/// The region of tool polygon `a` over obstacle polygon `b` (unit normal `nb`, `b`
/// counter-clockwise about it) within `delta_m` of `b`'s plane, as one contact (see the module
/// docs). `offset` says where the surfaces the polygons simplify lie about them
/// ([`HeightOffset::NONE`] for triangles).
pub(crate) fn pair_region(
    a: &[Vec3],
    b: &[Vec3],
    nb: &Vec3,
    delta_m: Real,
    offset: HeightOffset,
) -> PairRegion {
    let (u, w) = plane_basis(nb);
    let (u, w) = (&u, &w);
    let origin = b[0];
    let mean = offset.mean_m;
    let to_local = |v: &Vec3| {
        let d = v - origin;
        [u.dot(&d), w.dot(&d), nb.dot(&d) + mean]
    };
    let n = a.len().min(MAX_PIECE_VERTICES);
    let mut local = [[0.0; 3]; MAX_PIECE_VERTICES];
    for (l, v) in local.iter_mut().zip(&a[..n]) {
        *l = to_local(v);
    }
    // The obstacle polygon in the plane's coordinates, once.
    let m = b.len().min(MAX_PIECE_VERTICES);
    let mut corners = [[0.0; 2]; MAX_PIECE_VERTICES];
    for (c, v) in corners.iter_mut().zip(&b[..m]) {
        let d = v - origin;
        *c = [u.dot(&d), w.dot(&d)];
    }
    // Inside an edge: to its left (counter-clockwise polygon).
    let inside = |i: usize, p: &[Real; 3]| {
        let (p0, p1) = (corners[i], corners[(i + 1) % m]);
        (p1[0] - p0[0]) * (p[1] - p0[1]) - (p1[1] - p0[1]) * (p[0] - p0[0])
    };
    // Most pairs that reach here lie beside each other, not one over the other: the whole tool
    // polygon is outside one edge, and the clips below would end empty.
    if (0..m).any(|i| local[..n].iter().all(|p| inside(i, p) < 0.0)) {
        return PairRegion::NONE;
    }
    let mut poly: Poly = ([[0.0; 3]; MAX_CLIPPED], n);
    poly.0[..n].copy_from_slice(&local[..n]);
    let s = offset.half_width_m.max(0.0);
    let mut tmp: Poly = ([[0.0; 3]; MAX_CLIPPED], 0);
    // The slab first, then the prism's walls. Ping-pong between the two buffers by reference
    // (swapping the buffers themselves moved 368 bytes three times per wall, an eighth of this
    // function's time on the jaws), and only where a plane cuts.
    let (mut cur, mut next) = (&mut poly, &mut tmp);
    let slab_top = |p: &[Real; 3]| delta_m + s - p[2];
    let slab_bottom = |p: &[Real; 3]| delta_m + p[2];
    if clip(cur, next, slab_top) {
        std::mem::swap(&mut cur, &mut next);
    }
    if clip(cur, next, slab_bottom) {
        std::mem::swap(&mut cur, &mut next);
    }
    for i in 0..m {
        if cur.1 == 0 {
            break;
        }
        if clip(cur, next, |p| inside(i, p)) {
            std::mem::swap(&mut cur, &mut next);
        }
    }
    let poly: &Poly = cur;
    let mut out = PairRegion::NONE;
    if poly.1 < 3 {
        return out;
    }
    let (lo, hi) = poly.0[..poly.1]
        .iter()
        .fold((Real::INFINITY, Real::NEG_INFINITY), |(l, h), p| {
            (l.min(p[2]), h.max(p[2]))
        });
    if lo <= delta_m {
        out.nearest_m = if lo <= 0.0 && hi >= 0.0 {
            0.0
        } else {
            lo.abs().min(hi.abs())
        };
    }
    let weight = Weight::new(delta_m, s);
    let mut sums = Sums::default();
    sums.add(poly, &weight);
    if !(sums.g > 0.0 && sums.g2 > 0.0 && sums.g.is_finite() && sums.g2.is_finite()) {
        return out;
    }
    let c = sums.gx / sums.g;
    let mut depth_m = sums.g2 / sums.g - delta_m;
    let mut area_m2 = sums.g * sums.g / sums.g2;
    // Never nearer than the pieces themselves where they are apart (the offsets deepen the mean,
    // not the closest approach): the smallest separation reported stays within the pieces'
    // deviations of the surfaces' (the guarantee of `lod`), the weight `∫g` is kept.
    let piece_lo = lo - mean;
    let pieces_apart = piece_lo > 0.0 && depth_m > -piece_lo;
    if pieces_apart {
        depth_m = (-piece_lo).max(-delta_m);
        area_m2 = sums.g / gap_weight_m(depth_m, delta_m);
    }
    out.region = Some(RegionContact {
        pieces_apart,
        area_m2,
        centroid: origin + u * c.x + w * c.y + nb * (c.z - mean),
        depth_m,
    });
    out
}

/// How far tool polygon `a` lies beside obstacle polygon `b`'s prism (unit normal `nb`, `b`
/// counter-clockwise about it), where `a`'s heights come within `reach_m` of `b`'s plane
/// (m): the largest distance of `a` from the plane of a wall it lies wholly beyond, or, where
/// it lies beyond none (past a corner), the widest gap between the two shadows on `b`'s
/// plane across a side of `a`'s (a separating axis). Either is a lower bound on its
/// distance from the prism. Infinite where the shadows overlap (`a` over `b` in part, or
/// across it) or where `a` is out of reach in height. The surfaces two coarse pieces stand
/// for may lie that much nearer than the pieces, and have a region where the pieces have
/// none (`lod::refine`). Without the sides of `a`, the edge-on pieces of a peg's wall past the
/// corners of the rim's pieces were dropped: the suite's peg had a p90 error of 0.280 at
/// 2.5 % rather than 0.059, for 1 % fewer node pairs a jaws query. (The true distance between
/// the shadows, 0 where they overlap, cost a third more instructions a jaws query:
/// `docs/experiments/lod-accuracy-and-speed-probes.md`, probes 28 and 29.)
pub(crate) fn beside_prism_m(a: &[Vec3], b: &[Vec3], nb: &Vec3, reach_m: Real) -> Real {
    let origin = b[0];
    let (lo, hi) = a
        .iter()
        .fold((Real::INFINITY, Real::NEG_INFINITY), |(l, h), v| {
            let z = nb.dot(&(v - origin));
            (l.min(z), h.max(z))
        });
    if !(hi >= -reach_m && lo <= reach_m) {
        return Real::INFINITY;
    }
    // Outside an edge `p0 p1` of `b` (counter-clockwise about `nb`): `(p1 − p0) × (p − p0)`
    // along `nb` negative, its size the distance from the wall's plane times the edge's length.
    let mut beside_m = Real::NEG_INFINITY;
    for (i, p0) in b.iter().enumerate() {
        let edge = b[(i + 1) % b.len()] - p0;
        let wall = edge.cross(nb);
        let length = wall.norm();
        if length <= 0.0 {
            continue;
        }
        let outside = a
            .iter()
            .map(|v| wall.dot(&(v - p0)))
            .fold(Real::INFINITY, Real::min);
        beside_m = beside_m.max(outside / length);
    }
    if beside_m > 0.0 {
        return beside_m;
    }
    // Past a corner of the prism no wall of `b` separates the two shadows, but a side of
    // `a`'s may: an edge-on tool piece's shadow is a thin band, and beyond a corner it is
    // its long side that faces `b`.
    let mut apart_m = Real::NEG_INFINITY;
    for (i, q0) in a.iter().enumerate() {
        let edge = a[(i + 1) % a.len()] - q0;
        let side = edge.cross(nb);
        let length = side.norm();
        // (An edge along `nb` has no shadow.)
        if length <= 1e-6 * edge.norm() {
            continue;
        }
        let span = |ps: &[Vec3]| {
            ps.iter()
                .fold((Real::INFINITY, Real::NEG_INFINITY), |(l, h), v| {
                    let x = side.dot(&(v - q0));
                    (l.min(x), h.max(x))
                })
        };
        let ((a_lo, a_hi), (b_lo, b_hi)) = (span(a), span(b));
        apart_m = apart_m.max((b_lo - a_hi).max(a_lo - b_hi) / length);
    }
    if apart_m > 0.0 {
        apart_m
    } else {
        Real::INFINITY
    }
}

/// The penalty's weight `w(h) = δ − h` (0 above `δ`) at a piece's height `h`, averaged over where
/// the surface it simplifies may lie: `h + e`, `e` uniform in `[−s, s]` (`s` the offset's
/// half-width): `E[w]` and `E[w²]`, from the antiderivatives of `w` and `w²`. With `s = 0` they
/// are `w` and `w²` on `[−δ, δ]`. Only the top is smoothed: the cut at `−δ` (the region's lower
/// bound) applies to the piece's shifted height, where the weight is largest; smoothing it too
/// moved the weight of pieces lying below `−δ` into the region and over-pushed (jaws at 2.5 %:
/// error 0.05 → 0.40).
#[derive(Debug, Clone, Copy)]
struct Weight {
    delta: Real,
    s: Real,
}

impl Weight {
    fn new(delta: Real, s: Real) -> Self {
        Self { delta, s }
    }

    /// `∫_{−δ}^{x} w` and `∫_{−δ}^{x} w²`, with `w` continued linearly below `−δ`.
    #[inline]
    fn antiderivatives(&self, x: Real) -> (Real, Real) {
        let d = self.delta;
        let x = x.min(d);
        let r = d - x;
        (
            2.0 * d * d - 0.5 * r * r,
            (8.0 * d * d * d - r * r * r) / 3.0,
        )
    }

    /// `(E[w(h + e)], E[w(h + e)²])`.
    #[inline]
    fn at(&self, h: Real) -> (Real, Real) {
        if self.s <= 0.0 {
            let w = if h.abs() <= self.delta {
                self.delta - h
            } else {
                0.0
            };
            return (w, w * w);
        }
        let (hi1, hi2) = self.antiderivatives(h + self.s);
        let (lo1, lo2) = self.antiderivatives(h - self.s);
        let k = 0.5 / self.s;
        ((hi1 - lo1) * k, (hi2 - lo2) * k)
    }
}

/// `∫g`, `∫g x` and `∫g²` over polygons, exact. The spread weight is a polynomial of the height
/// on either side of the knee `h = δ − s` ([`Weight`]): below it `E[w] = δ − h` and
/// `E[w²] = (δ − h)² + s²/3`, above it (within `s` of the top) `E[w] = q²/4s` and
/// `E[w²] = q³/6s`, `q = δ + s − h`. The polygon is cut at the knee; the part below, where the
/// weight is linear (all of it without a spread), is summed in closed form from each fan
/// triangle's vertices, and the band above by a quadrature exact for polynomials of degree 5
/// (Dunavant's seven points).
#[derive(Debug, Default)]
struct Sums {
    g: Real,
    gx: Vec3,
    g2: Real,
}

/// Dunavant's degree-5 rule: barycentric points (as `(a, b)`, the point `a` at one vertex and
/// `b` at the two others, in every rotation) and weights.
const DUNAVANT5: [(Real, Real, Real); 3] = [
    (1.0 / 3.0, 1.0 / 3.0, 0.225),
    (
        0.059_715_871_789_770,
        0.470_142_064_105_115,
        0.132_394_152_788_506,
    ),
    (
        0.797_426_985_353_087,
        0.101_286_507_323_456,
        0.125_939_180_544_827,
    ),
];

/// The corners of a polygon's fan triangles, `(v0, v_k, v_k+1)`, with the triangle's area
/// (degenerate ones left out; none for fewer than three vertices).
fn fan(p: &Poly) -> impl Iterator<Item = ([Vec3; 3], Real)> + '_ {
    let v = |k: usize| Vec3::new(p.0[k][0], p.0[k][1], p.0[k][2]);
    let v0 = v(0);
    (1..p.1.max(2) - 1).filter_map(move |k| {
        let (v1, v2) = (v(k), v(k + 1));
        let area = 0.5 * (v1 - v0).cross(&(v2 - v0)).norm();
        (area > 0.0).then_some(([v0, v1, v2], area))
    })
}

impl Sums {
    fn add(&mut self, p: &Poly, weight: &Weight) {
        if p.1 < 3 {
            return;
        }
        if weight.s <= 0.0 {
            self.add_linear(p, weight.delta, 0.0);
            return;
        }
        let knee = weight.delta - weight.s;
        let mut part: Poly = ([[0.0; 3]; MAX_CLIPPED], 0);
        if !clip(p, &mut part, |x| knee - x[2]) {
            // All of it below the knee.
            self.add_linear(p, weight.delta, weight.s);
            return;
        }
        self.add_linear(&part, weight.delta, weight.s);
        if clip(p, &mut part, |x| x[2] - knee) {
            self.add_band(&part, weight);
        } else {
            self.add_band(p, weight);
        }
    }

    /// Below the knee: `g = δ − h` linear, so `∫g = A ḡ`, `∫g x = A/12 (Σ gᵢxᵢ + Σgᵢ Σxᵢ)`
    /// and `∫g² = A/12 (Σ gᵢ² + (Σ gᵢ)²)` on each fan triangle, and the spread adds `s²/3`
    /// to `E[w²]` everywhere.
    fn add_linear(&mut self, p: &Poly, delta: Real, s: Real) {
        let spread2 = s * s / 3.0;
        for (v, area) in fan(p) {
            let g = v.map(|x| delta - x.z);
            let sg = g[0] + g[1] + g[2];
            let k = area / 12.0;
            self.g += area * sg / 3.0;
            self.gx += (v[0] * g[0] + v[1] * g[1] + v[2] * g[2] + (v[0] + v[1] + v[2]) * sg) * k;
            self.g2 += (g[0] * g[0] + g[1] * g[1] + g[2] * g[2] + sg * sg) * k + area * spread2;
        }
    }

    /// Within `s` of the top: a polynomial of degree 3 in the height, by the quadrature.
    fn add_band(&mut self, p: &Poly, weight: &Weight) {
        for ([v0, v1, v2], area) in fan(p) {
            let mut at = |x: Vec3, wt: Real| {
                let (g, g2) = weight.at(x.z);
                self.g += area * wt * g;
                self.gx += x * (area * wt * g);
                self.g2 += area * wt * g2;
            };
            let (a0, b0, w0) = DUNAVANT5[0];
            at(v0 * a0 + v1 * b0 + v2 * b0, w0);
            for &(a, b, wt) in &DUNAVANT5[1..] {
                at(v0 * a + v1 * b + v2 * b, wt);
                at(v0 * b + v1 * a + v2 * b, wt);
                at(v0 * b + v1 * b + v2 * a, wt);
            }
        }
    }
}

/// Sutherland–Hodgman: the part of `src` where `f ≥ 0`, into `dst`; returns whether it wrote
/// `dst`, which it does not where all of `src` is in that part (the part is `src` itself).
#[inline]
fn clip(src: &Poly, dst: &mut Poly, f: impl Fn(&[Real; 3]) -> Real) -> bool {
    let n = src.1;
    let mut values = [0.0; MAX_CLIPPED];
    let mut all_in = true;
    for (v, p) in values.iter_mut().zip(&src.0[..n]) {
        *v = f(p);
        all_in &= *v >= 0.0;
    }
    if all_in {
        return false;
    }
    dst.1 = 0;
    let mut push = |p: [Real; 3]| {
        if dst.1 < MAX_CLIPPED {
            dst.0[dst.1] = p;
            dst.1 += 1;
        }
    };
    let mut prev = src.0[n - 1];
    let mut f_prev = values[n - 1];
    for (&cur, &f_cur) in src.0[..n].iter().zip(&values[..n]) {
        if (f_cur >= 0.0) != (f_prev >= 0.0) {
            let t = f_prev / (f_prev - f_cur);
            push(lerp(&prev, &cur, t));
        }
        if f_cur >= 0.0 {
            push(cur);
        }
        prev = cur;
        f_prev = f_cur;
    }
    true
}

#[inline]
fn lerp(a: &[Real; 3], b: &[Real; 3], t: Real) -> [Real; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const DELTA: Real = 1e-3;

    /// `(∫g, ∫g x, ∫g²)` of a region as its contact stands for it.
    fn sums_of(r: &RegionContact) -> (Real, Vec3, Real) {
        let g = r.area_m2 * (r.depth_m + DELTA);
        (g, r.centroid * g, g * (r.depth_m + DELTA))
    }

    /// A square `[x0, x0 + side]²` at `z = 0` split into `k × k` cells of two triangles each,
    /// counter-clockwise about `+z` (or `−z` when `down`), mapped by `f`.
    fn grid(
        k: usize,
        x0: Real,
        side: Real,
        down: bool,
        f: &dyn Fn(Vec3) -> Vec3,
    ) -> Vec<[Vec3; 3]> {
        let at = |i: usize, j: usize| {
            let s = side / k as Real;
            f(Vec3::new(x0 + i as Real * s, x0 + j as Real * s, 0.0))
        };
        let mut out = Vec::new();
        for i in 0..k {
            for j in 0..k {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                if down {
                    out.push([a, c, b]);
                    out.push([a, d, c]);
                } else {
                    out.push([a, b, c]);
                    out.push([a, c, d]);
                }
            }
        }
        out
    }

    /// The sums over every pair of `tool` × `obstacle` triangles.
    fn total(
        tool: &[[Vec3; 3]],
        obstacle: &[[Vec3; 3]],
        offset: HeightOffset,
    ) -> (Real, Vec3, Real) {
        let mut s = (0.0, Vec3::zeros(), 0.0);
        for a in tool {
            for b in obstacle {
                let nb = (b[1] - b[0]).cross(&(b[2] - b[0])).normalize();
                if let Some(r) = pair_region(a, b, &nb, DELTA, offset).region {
                    let (g, gx, g2) = sums_of(&r);
                    s.0 += g;
                    s.1 += gx;
                    s.2 += g2;
                }
            }
        }
        s
    }

    /// A tool square parallel to a floor square, its surface spread 0.6 mm about it: 0.5 mm up,
    /// the pieces lie apart but within δ, their depth held at their distance; 1.2 mm up, beyond
    /// δ, within reach only through the spread, the depth held at `−δ` and the weight next to
    /// nothing.
    #[test]
    fn pieces_beyond_delta_are_told_from_pieces_apart_within_it() {
        let offset = HeightOffset {
            mean_m: 0.0,
            half_width_m: 0.6e-3,
        };
        let floor = grid(1, 0.0, 0.01, false, &|v| v);
        let region = |h: Real| {
            let tool = grid(1, 0.0, 0.01, true, &|v| v + Vec3::new(0.0, 0.0, h));
            let nb = Vec3::z();
            pair_region(&tool[0], &floor[0], &nb, DELTA, offset)
                .region
                .expect("within reach")
        };
        let within = region(0.5e-3);
        assert!(within.pieces_apart && !within.pieces_beyond(DELTA));
        assert_eq!(within.depth_m, -0.5e-3);
        let beyond = region(1.2e-3);
        assert!(beyond.pieces_apart && beyond.pieces_beyond(DELTA));
        assert_eq!(beyond.depth_m, -DELTA);
        // Crossing pieces are neither.
        let crossing = region(-0.2e-3);
        assert!(!crossing.pieces_apart && !crossing.pieces_beyond(DELTA));
    }

    /// A vertical tool square standing beside a floor square (edge-on), `x` beyond its edge
    /// at `x = 0`: how far beside it lies, where its heights reach the band.
    #[test]
    fn a_piece_beside_a_prism_says_how_far() {
        let floor = [
            Vec3::new(-0.01, -0.01, 0.0),
            Vec3::new(0.0, -0.01, 0.0),
            Vec3::new(0.0, 0.01, 0.0),
            Vec3::new(-0.01, 0.01, 0.0),
        ];
        let wall = |x: Real, z: Real| {
            [
                Vec3::new(x, -0.005, z - 0.002),
                Vec3::new(x, 0.005, z - 0.002),
                Vec3::new(x, 0.005, z + 0.002),
                Vec3::new(x, -0.005, z + 0.002),
            ]
        };
        let nb = Vec3::z();
        let beside = |x, z| beside_prism_m(&wall(x, z), &floor, &nb, DELTA);
        assert!(
            pair_region(&wall(0.3e-3, 0.0), &floor, &nb, DELTA, HeightOffset::NONE)
                .region
                .is_none()
        );
        assert!((beside(0.3e-3, 0.0) - 0.3e-3).abs() < 1e-12);
        // Beyond a corner: the larger of its distances from the two walls' planes.
        let corner: Vec<Vec3> = wall(0.3e-3, 0.0)
            .iter()
            .map(|v| v + Vec3::new(0.0, 0.0152, 0.0))
            .collect();
        assert!((beside_prism_m(&corner, &floor, &nb, DELTA) - 0.3e-3).abs() < 1e-12);
        // Past the corner (0, 0.01) along the diagonal, the wall turned 45° to it: beyond
        // neither wall's plane (each sees part of it inside), apart by 0.3 mm across its side.
        let (d, l) = (0.3e-3, 0.005);
        let diagonal: Vec<Vec3> = wall(0.0, 0.0)
            .iter()
            .map(|v| {
                let along = v.y / 0.005 * l * std::f64::consts::FRAC_1_SQRT_2;
                let out = d * std::f64::consts::FRAC_1_SQRT_2;
                Vec3::new(out + along, 0.01 + out - along, v.z)
            })
            .collect();
        assert!(
            (beside_prism_m(&diagonal, &floor, &nb, DELTA) - d).abs() < 1e-12,
            "{}",
            beside_prism_m(&diagonal, &floor, &nb, DELTA)
        );
        // Moved onto the corner, its shadow crosses the floor's: not beside.
        let onto: Vec<Vec3> = diagonal
            .iter()
            .map(|v| v - Vec3::new(1.0, 1.0, 0.0) * (d * std::f64::consts::FRAC_1_SQRT_2 * 2.0))
            .collect();
        assert_eq!(beside_prism_m(&onto, &floor, &nb, DELTA), Real::INFINITY);
        // Its heights out of the band: not within reach whatever its place.
        assert_eq!(beside(0.3e-3, 0.0035), Real::INFINITY);
        // Within the prism, the band 2δ tall along the wall is its region, and it is not
        // beside; nor is a wall tilted across the prism's wall.
        assert!(
            pair_region(&wall(-0.3e-3, 0.0), &floor, &nb, DELTA, HeightOffset::NONE)
                .region
                .is_some()
        );
        assert_eq!(beside(-0.3e-3, 0.0), Real::INFINITY);
        let tilted: Vec<Vec3> = wall(0.0, 0.0)
            .iter()
            .map(|v| v - Vec3::new(0.1 * v.z, 0.0, 0.0))
            .collect();
        assert_eq!(beside_prism_m(&tilted, &floor, &nb, DELTA), Real::INFINITY);
    }

    /// A tilted tool square over a floor, partly beyond δ and partly below the floor: the same
    /// sums from two triangles or a 6 × 6 grid on either side, so the force does not depend on
    /// how a flat surface is tessellated.
    #[test]
    fn the_sums_do_not_depend_on_the_tessellation() {
        let tilt = nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(0.05, 0.3, 0.0));
        let place =
            |v: Vec3| tilt * (v - Vec3::new(0.005, 0.005, 0.0)) + Vec3::new(0.006, 0.004, 0.0003);
        let floor = |k| grid(k, 0.0, 0.012, false, &|v| v);
        let tool = |k| grid(k, 0.0, 0.01, true, &place);
        let coarse = total(&tool(1), &floor(1), HeightOffset::NONE);
        assert!(coarse.0 > 0.0);
        for (kt, kf) in [(6, 1), (1, 6), (6, 6), (3, 5)] {
            let fine = total(&tool(kt), &floor(kf), HeightOffset::NONE);
            assert!(
                (fine.0 - coarse.0).abs() < 1e-12 * coarse.0,
                "{kt}×{kf}: {fine:?} {coarse:?}"
            );
            assert!((fine.1 - coarse.1).norm() < 1e-12 * coarse.0);
            assert!((fine.2 - coarse.2).abs() < 1e-12 * coarse.2);
        }
    }

    /// `E[w]` and `E[w²]` by a fine midpoint sum over the spread.
    fn weight_by_sum(delta: Real, s: Real, h: Real) -> (Real, Real) {
        let n = 20_000;
        let (mut g, mut g2) = (0.0, 0.0);
        for i in 0..n {
            let e = -s + 2.0 * s * (i as Real + 0.5) / n as Real;
            let x = h + e;
            // `w` continued linearly below −δ (see `Weight::antiderivatives`).
            let w = if x <= delta { delta - x } else { 0.0 };
            g += w / n as Real;
            g2 += w * w / n as Real;
        }
        (g, g2)
    }

    proptest! {
        /// The closed form of the spread weight against a direct average.
        #[test]
        fn spread_weight_matches_its_average(s in 1e-5..3e-3f64, h in -2e-3..5e-3f64) {
            let (g, g2) = Weight::new(DELTA, s).at(h);
            let (gs, g2s) = weight_by_sum(DELTA, s, h);
            prop_assert!((g - gs).abs() < 1e-7 * DELTA, "{g} {gs}");
            prop_assert!((g2 - g2s).abs() < 1e-7 * DELTA * DELTA, "{g2} {g2s}");
        }

        /// The closed forms and the band's quadrature against the spread weight summed over a
        /// fine grid of a triangle that crosses the knee, the top of the band or neither.
        #[test]
        fn polygon_sums_match_the_spread_weight_summed(
            x in prop::array::uniform6(-2e-3..2e-3f64),
            h in prop::array::uniform3(0.0..1.0f64),
            s in prop_oneof![Just(0.0), 1e-5..3e-3f64],
        ) {
            // Heights in `[−2δ, δ + s]`: below the band's top, where the weight ends.
            let h = h.map(|t| -2.0 * DELTA + t * (3.0 * DELTA + s));
            let v = [
                Vec3::new(x[0], x[1], h[0]),
                Vec3::new(x[2], x[3], h[1]),
                Vec3::new(x[4], x[5], h[2]),
            ];
            let area = 0.5 * (v[1] - v[0]).cross(&(v[2] - v[0])).norm();
            prop_assume!(area > 1e-8);
            let mut poly: Poly = ([[0.0; 3]; MAX_CLIPPED], 3);
            for (p, q) in poly.0.iter_mut().zip(&v) {
                *p = [q.x, q.y, q.z];
            }
            let weight = Weight::new(DELTA, s);
            let mut sums = Sums::default();
            sums.add(&poly, &weight);
            let n = 300;
            let (mut g, mut gx, mut g2) = (0.0, Vec3::zeros(), 0.0);
            let cell = area / (n * n) as Real;
            for i in 0..n {
                for j in 0..n - i {
                    for (a, b, up) in [
                        (i as Real + 1.0 / 3.0, j as Real + 1.0 / 3.0, true),
                        (i as Real + 2.0 / 3.0, j as Real + 2.0 / 3.0, false),
                    ] {
                        if !up && i + j + 1 >= n {
                            continue;
                        }
                        let p = v[0]
                            + (v[1] - v[0]) * (a / n as Real)
                            + (v[2] - v[0]) * (b / n as Real);
                        // `s = 0`: the weight continued linearly, as the clipped polygon has it.
                        let (w, w2) = if s > 0.0 {
                            weight.at(p.z)
                        } else {
                            (DELTA - p.z, (DELTA - p.z).powi(2))
                        };
                        g += w * cell;
                        gx += p * (w * cell);
                        g2 += w2 * cell;
                    }
                }
            }
            let scale = area * DELTA;
            prop_assert!((sums.g - g).abs() < 1e-4 * scale, "{} {g}", sums.g);
            prop_assert!((sums.gx - gx).norm() < 1e-4 * scale * 4e-3, "{} {gx}", sums.gx);
            prop_assert!((sums.g2 - g2).abs() < 1e-4 * scale * DELTA, "{} {g2}", sums.g2);
        }

        /// Against the integral summed over a fine grid of points of the tool triangle: the
        /// weight, its centroid and its mean depth; and the region never stands for more than
        /// the triangle, nor lies beyond δ.
        #[test]
        fn a_triangle_pair_integrates_the_penalty(
            a in prop::array::uniform9(-2e-3..2e-3f64),
            b in prop::array::uniform9(-2e-3..2e-3f64),
        ) {
            let tri = |x: [Real; 9]| [
                Vec3::new(x[0], x[1], x[2] * 0.5),
                Vec3::new(x[3], x[4], x[5] * 0.5),
                Vec3::new(x[6], x[7], x[8] * 0.5),
            ];
            let (ta, mut tb) = (tri(a), tri(b));
            let cr = (tb[1] - tb[0]).cross(&(tb[2] - tb[0]));
            prop_assume!(cr.norm() > 1e-7 && (ta[1] - ta[0]).cross(&(ta[2] - ta[0])).norm() > 1e-7);
            if cr.z < 0.0 {
                tb.swap(1, 2);
            }
            let nb = (tb[1] - tb[0]).cross(&(tb[2] - tb[0])).normalize();
            let r = pair_region(&ta, &tb, &nb, DELTA, HeightOffset::NONE);
            // The sum: points of a fine barycentric grid on `ta`, each standing for its share.
            let (n, area_a) = (200, 0.5 * (ta[1] - ta[0]).cross(&(ta[2] - ta[0])).norm());
            let (mut g, mut gx, mut g2) = (0.0, Vec3::zeros(), 0.0);
            let count = n * n;
            for i in 0..n {
                for j in 0..n - i {
                    // Two sub-triangles' centroids per cell; each stands for area / n².
                    for (u, v) in [
                        ((i as Real + 1.0 / 3.0) / n as Real, (j as Real + 1.0 / 3.0) / n as Real),
                        ((i as Real + 2.0 / 3.0) / n as Real, (j as Real + 2.0 / 3.0) / n as Real),
                    ] {
                        if u + v > 1.0 {
                            continue;
                        }
                        let x = ta[0] + (ta[1] - ta[0]) * u + (ta[2] - ta[0]) * v;
                        let h = nb.dot(&(x - tb[0]));
                        let inside = (0..3).all(|k| {
                            let (p, q) = (tb[k], tb[(k + 1) % 3]);
                            nb.dot(&(q - p).cross(&(x - p))) >= 0.0
                        });
                        if inside && h.abs() <= DELTA {
                            let w = (DELTA - h) * area_a / count as Real;
                            g += w;
                            gx += x * w;
                            g2 += w * (DELTA - h);
                        }
                    }
                }
            }
            let scale = area_a * DELTA;
            match r.region {
                Some(reg) => {
                    let (rg, rgx, rg2) = sums_of(&reg);
                    prop_assert!((rg - g).abs() < 0.02 * scale, "{rg} {g}");
                    prop_assert!((rgx - gx).norm() < 0.02 * scale * 4e-3);
                    prop_assert!((rg2 - g2).abs() < 0.02 * scale * DELTA);
                    prop_assert!(reg.area_m2 <= area_a * (1.0 + 1e-9));
                    prop_assert!(reg.depth_m >= -DELTA && reg.depth_m <= DELTA);
                    // The nearest point is no farther than the mean.
                    prop_assert!(r.nearest_m <= reg.depth_m.abs() + 1e-15);
                }
                None => prop_assert!(g < 0.02 * scale, "missed {g}"),
            }
        }
    }
}
