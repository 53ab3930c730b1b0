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
//! closed forms on the fan of the clipped polygon, where `g` is linear and within the spread's
//! band at the top, where it is a power of the linear distance to the band's top (`Sums`).
//!
//! Because the prisms of neighbouring obstacle triangles only share walls, and a tool polygon's
//! integrals add up over any partition of it, the sums over triangle pairs do not depend on how
//! either flat surface is tessellated: the all-pairs reference converges as a mesh is refined.
//! A tool polygon lying on a shared wall (within `ROUNDOFF_REL` of the wall's edge length of
//! its plane: a picometre for a millimetre's edge) counts half in each of the two prisms, once
//! in all: on the wall between two prisms (a peg's end flush with a row of its hole's
//! tessellation), roundoff put it inside both, or neither, or one, and the clip's cuts through
//! it fell anywhere.
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

use crate::geometry::{PairContact, any_plane_basis};
use crate::lod::{MAX_PIECE_VERTICES, Overhang, ROUNDOFF_REL, SurfaceMoments};

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
    /// The length of its boundary along the walls of `B`'s prism (m): where it ends because
    /// `A` overhangs `B`, not because `A` ends or leaves the slab. Measured by
    /// [`pair_region_beside`] when asked; 0 otherwise.
    pub walls_m: Real,
    /// A bound on the weight (`∫g`, m³) of the part of it that may lie where `B` overhangs its
    /// surface: over the bands along `B`'s edges that [`pair_region_beside`] was given
    /// (`lod/overhang.rs`), at most its whole weight; 0 where it reaches none.
    pub overhang_m3: Real,
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
    /// From [`pair_region_beside`], where `A`'s shadow lies wholly beyond a wall of `B`'s prism
    /// (the first found): how far beyond it (m; a lower bound on how far `A` lies beside the
    /// prism, [`beside_prism_m`]) and the length over which the two shadows face each other
    /// across it (m; the overlap of their extents along the wall, 0 where there is none).
    pub beside: Option<(Real, Real)>,
}

impl PairRegion {
    /// No part of `A` over `B` within reach.
    const NONE: Self = Self {
        region: None,
        nearest_m: Real::INFINITY,
        beside: None,
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
    region::<false>(a, b, nb, delta_m, offset, false, (&[], &[]))
}

/// [`pair_region`], and where `a`'s shadow lies wholly beyond a wall of `b`'s prism, how far
/// and over what length they face each other across it ([`PairRegion::beside`]): the band of
/// the surfaces two facing coarse pieces stand for that may lie over each other there
/// (`lod::refine`). With `walls`, the region's length along the walls of `b`'s prism too
/// ([`RegionContact::walls_m`]), where the surfaces' prisms lean from the pieces'. `overhang`
/// gives, by edge of `a` and of `b` (from each corner), where each overhangs its surface
/// (`lod/overhang.rs`; empty for none): the region's weight over those bands is bounded in
/// [`RegionContact::overhang_m3`].
pub(crate) fn pair_region_beside(
    a: &[Vec3],
    b: &[Vec3],
    nb: &Vec3,
    delta_m: Real,
    offset: HeightOffset,
    walls: bool,
    overhang: (&[Overhang], &[Overhang]),
) -> PairRegion {
    region::<true>(a, b, nb, delta_m, offset, walls, overhang)
}

/// [`pair_region`], and with `BESIDE` [`pair_region_beside`] (measuring the region's length
/// along the walls with `walls`, and its weight over the overhang bands of `a` and `b`).
#[inline(always)]
fn region<const BESIDE: bool>(
    a: &[Vec3],
    b: &[Vec3],
    nb: &Vec3,
    delta_m: Real,
    offset: HeightOffset,
    walls: bool,
    (tool_overhang, overhang): (&[Overhang], &[Overhang]),
) -> PairRegion {
    let (u, w) = any_plane_basis(nb);
    let (u, w) = (&u, &w);
    let origin = b[0];
    let mean = offset.mean_m;
    let to_local = |v: &Vec3| {
        let d = v - origin;
        [u.dot(&d), w.dot(&d), nb.dot(&d) + mean]
    };
    // The tool polygon in the plane's coordinates, where the clips below start from.
    let n = a.len().min(MAX_PIECE_VERTICES);
    let mut poly: Poly = ([[0.0; 3]; MAX_CLIPPED], n);
    for (l, v) in poly.0.iter_mut().zip(&a[..n]) {
        *l = to_local(v);
    }
    let local = &poly.0[..n];
    // The obstacle polygon in the plane's coordinates, once.
    let m = b.len().min(MAX_PIECE_VERTICES);
    let mut corners = [[0.0; 2]; MAX_PIECE_VERTICES];
    for (c, v) in corners.iter_mut().zip(&b[..m]) {
        let d = v - origin;
        *c = [u.dot(&d), w.dot(&d)];
    }
    // Its edges, `p1 − p0` from each corner `p0`, once.
    let mut edges = [[0.0; 2]; MAX_PIECE_VERTICES];
    for (i, e) in edges[..m].iter_mut().enumerate() {
        let (p0, p1) = (corners[i], corners[(i + 1) % m]);
        *e = [p1[0] - p0[0], p1[1] - p0[1]];
    }
    // Inside an edge: to its left (counter-clockwise polygon); on its wall within
    // `ROUNDOFF_REL` of its length, exactly 0 (the cross product is the distance from the
    // wall's plane times the edge's length; module docs).
    let mut on_wall_tolerance = [0.0; MAX_PIECE_VERTICES];
    for (t, e) in on_wall_tolerance[..m].iter_mut().zip(&edges) {
        *t = ROUNDOFF_REL * (e[0] * e[0] + e[1] * e[1]);
    }
    let inside = |i: usize, p: &[Real; 3]| {
        let (p0, e) = (corners[i], edges[i]);
        let f = e[0] * (p[1] - p0[1]) - e[1] * (p[0] - p0[0]);
        if f.abs() <= on_wall_tolerance[i] {
            0.0
        } else {
            f
        }
    };
    // Most pairs that reach here lie beside each other, not one over the other: the whole tool
    // polygon is outside one edge, and the clips below would end empty.
    if let Some(i) = (0..m).find(|&i| local.iter().all(|p| inside(i, p) < 0.0)) {
        if !BESIDE {
            return PairRegion::NONE;
        }
        // How far beyond that wall, and how long the two shadows face each other across it.
        let edge = edges[i];
        let length = (edge[0] * edge[0] + edge[1] * edge[1]).sqrt();
        let beyond = local
            .iter()
            .map(|p| -inside(i, p))
            .fold(Real::INFINITY, Real::min);
        let along = |p: &[Real]| (edge[0] * p[0] + edge[1] * p[1]) / length;
        let span = |(lo, hi): (Real, Real), x: Real| (lo.min(x), hi.max(x));
        let empty = (Real::INFINITY, Real::NEG_INFINITY);
        let (a_lo, a_hi) = local.iter().map(|p| along(p)).fold(empty, span);
        let (b_lo, b_hi) = corners[..m].iter().map(|p| along(p)).fold(empty, span);
        return PairRegion {
            beside: (length > 0.0)
                .then(|| (beyond / length, (a_hi.min(b_hi) - a_lo.max(b_lo)).max(0.0))),
            ..PairRegion::NONE
        };
    }
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
    // The walls that cut it (bit `i` for the wall from corner `i`), and whether it lies on one.
    let mut cut = 0u32;
    let mut on_wall = false;
    for i in 0..m {
        if cur.1 == 0 {
            break;
        }
        if clip(cur, next, |p| inside(i, p)) {
            std::mem::swap(&mut cur, &mut next);
            cut |= 1 << i;
        } else {
            on_wall |= cur.0[..cur.1].iter().all(|p| inside(i, p) == 0.0);
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
    if on_wall {
        // The prism beside this one across that wall has it on its wall too: half each.
        sums.scale(0.5);
    }
    if !(sums.g > 0.0 && sums.g2 > 0.0 && sums.g.is_finite() && sums.g2.is_finite()) {
        return out;
    }
    // Over the bands along the edges of `b` and of `a` where they may overhang their surfaces
    // (`lod/overhang.rs`): for each band the region reaches, its extent along the edge by how
    // far into the band it reaches, at most the band's uncovered area, at the largest weight per
    // area the region has (at its lowest point).
    let mut overhang_m2: Real = 0.0;
    if BESIDE && !(overhang.is_empty() && tool_overhang.is_empty()) {
        let vertices = &poly.0[..poly.1];
        for (i, o) in overhang.iter().enumerate().take(m) {
            if !(o.width_m > 0.0 && o.area_m2 > 0.0) {
                continue;
            }
            let e = edges[i];
            let length = (e[0] * e[0] + e[1] * e[1]).sqrt();
            if !(o.width_m.is_finite() && length > 0.0) {
                overhang_m2 = Real::INFINITY;
                break;
            }
            let from_edge = |p: &[Real; 3]| inside(i, p) / length;
            let along = |p: &[Real; 3]| (e[0] * p[0] + e[1] * p[1]) / length;
            overhang_m2 += band_overlap_m2(vertices, o, from_edge, along);
        }
        // The tool's edges, in its own plane (the region lies in it): the distance from the
        // edge's line, and the extent along it.
        for (j, o) in tool_overhang.iter().enumerate().take(n) {
            if !(o.width_m > 0.0 && o.area_m2 > 0.0) || overhang_m2.is_infinite() {
                continue;
            }
            let (q0, q1) = (to_local(&a[j]), to_local(&a[(j + 1) % n]));
            let e = [q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]];
            let length = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
            if !(o.width_m.is_finite() && length > 0.0) {
                overhang_m2 = Real::INFINITY;
                break;
            }
            let from_edge = |p: &[Real; 3]| {
                let d = [p[0] - q0[0], p[1] - q0[1], p[2] - q0[2]];
                let c = [
                    d[1] * e[2] - d[2] * e[1],
                    d[2] * e[0] - d[0] * e[2],
                    d[0] * e[1] - d[1] * e[0],
                ];
                (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() / length
            };
            let along = |p: &[Real; 3]| (e[0] * p[0] + e[1] * p[1] + e[2] * p[2]) / length;
            overhang_m2 += band_overlap_m2(vertices, o, from_edge, along);
        }
    }
    let overhang_m3 = if overhang_m2 > 0.0 && delta_m + s - lo > 0.0 {
        (overhang_m2 * (delta_m + s - lo)).min(sums.g)
    } else {
        0.0
    };
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
        walls_m: if BESIDE && walls && cut != 0 {
            length_on_walls(poly, cut, |i, p| inside(i, p) == 0.0)
        } else {
            0.0
        },
        overhang_m3,
        area_m2,
        centroid: origin + u * c.x + w * c.y + nb * (c.z - mean),
        depth_m,
    });
    out
}

/// The part of the region with corners `vertices` that may lie in the band `band` along an
/// edge (m²): 0 where its least distance `from_edge` the edge's line is the band's width or
/// more; else its extent `along` the edge by how far into the band it reaches, at most the
/// band's uncovered area.
fn band_overlap_m2(
    vertices: &[[Real; 3]],
    band: &Overhang,
    from_edge: impl Fn(&[Real; 3]) -> Real,
    along: impl Fn(&[Real; 3]) -> Real,
) -> Real {
    let into_m = vertices
        .iter()
        .map(&from_edge)
        .fold(Real::INFINITY, Real::min);
    if into_m >= band.width_m {
        return 0.0;
    }
    let (lo_m, hi_m) = vertices
        .iter()
        .map(along)
        .fold((Real::INFINITY, Real::NEG_INFINITY), |(l, h), x| {
            (l.min(x), h.max(x))
        });
    ((band.width_m - into_m.max(0.0)) * (hi_m - lo_m).max(0.0)).min(band.area_m2)
}

/// The length of the edges of the clipped polygon `poly` (in `B`'s plane coordinates) that lie
/// on the walls of `B`'s prism marked in `cut` (bit `i`: the wall from corner `i`): both their
/// ends on the wall, as `on_wall(i, point)` says (within roundoff of it). The clip put them
/// there.
fn length_on_walls(poly: &Poly, cut: u32, on_wall: impl Fn(usize, &[Real; 3]) -> bool) -> Real {
    let k = poly.1;
    let mut length_m = 0.0;
    for j in 0..k {
        let (p, q) = (&poly.0[j], &poly.0[(j + 1) % k]);
        let along_a_wall = (0..MAX_PIECE_VERTICES)
            .filter(|i| cut & (1 << i) != 0)
            .any(|i| on_wall(i, p) && on_wall(i, q));
        if along_a_wall {
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            length_m += (dx * dx + dy * dy).sqrt();
        }
    }
    length_m
}

/// How far the part of tool polygon `a` whose heights come within `reach_m` of obstacle
/// polygon `b`'s plane (unit normal `nb`, `b` counter-clockwise about it) lies beside `b`'s
/// prism (m): the largest distance of that part from the plane of a wall it lies wholly
/// beyond, or, where it lies beyond none (past a corner), the widest gap between the two
/// shadows on `b`'s plane across a side of its (a separating axis). Either is a lower bound on
/// its distance from the prism. 0 where the shadows overlap (that part over `b` in part, or
/// across it: over the prism but out of the penalty's slab, which the surfaces the pieces
/// stand for may reach); infinite where no part of `a` is within reach. The surfaces two
/// coarse pieces stand for may lie that much nearer than the pieces, and have a region where
/// the pieces have none (`lod::refine`). Measured on the whole of `a`, a piece crossing `b`'s
/// plane steeply (a spoon's sheet through a curved back), over the prism only far below it
/// and beside it within reach, was taken for one over the prism, and dropped: `cargo xtask
/// bench collision --scene newell_teaspoon.stl,spot.stl` (the cow 8.5 cm long) at 2.5 %,
/// 0.112 / 0.472 → 0.081 / 0.233 (median / p90), the suite's peg 0.017 / 0.059 → 0.012 /
/// 0.023, for 1.9 % more instructions a jaws query. Without the sides of `a`, the edge-on pieces of a peg's wall past the
/// corners of the rim's pieces were dropped: the suite's peg had a p90 error of 0.280 at
/// 2.5 % rather than 0.059, for 1 % fewer node pairs a jaws query. (The true distance between
/// the shadows, 0 where they overlap, cost a third more instructions a jaws query:
/// `docs/experiments/lod-accuracy-and-speed-probes.md`, probes 28 and 29.)
pub(crate) fn beside_prism_m(a: &[Vec3], b: &[Vec3], nb: &Vec3, reach_m: Real) -> Real {
    let origin = b[0];
    // The part of `a` within reach in height: where a piece crosses `b`'s plane steeply, its
    // part deep below may lie over `b` while the part that could touch lies beside it.
    let n = a.len().min(MAX_PIECE_VERTICES);
    if n == 0 {
        return Real::INFINITY;
    }
    let mut poly: Poly = ([[0.0; 3]; MAX_CLIPPED], n);
    for (p, v) in poly.0.iter_mut().zip(&a[..n]) {
        *p = [v.x, v.y, v.z];
    }
    let mut tmp: Poly = ([[0.0; 3]; MAX_CLIPPED], 0);
    let (mut cur, mut next) = (&mut poly, &mut tmp);
    let height = |p: &[Real; 3]| nb.dot(&(Vec3::new(p[0], p[1], p[2]) - origin));
    if clip(cur, next, |p| reach_m - height(p)) {
        std::mem::swap(&mut cur, &mut next);
    }
    if cur.1 > 0 && clip(cur, next, |p| reach_m + height(p)) {
        std::mem::swap(&mut cur, &mut next);
    }
    if cur.1 == 0 {
        return Real::INFINITY;
    }
    let mut within = [Vec3::zeros(); MAX_CLIPPED];
    for (v, p) in within.iter_mut().zip(&cur.0[..cur.1]) {
        *v = Vec3::new(p[0], p[1], p[2]);
    }
    let a = &within[..cur.1];
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
    // The shadows overlap: `a` lies over `b` within reach, where the slab of the penalty may
    // leave it no region though the surfaces may have one.
    apart_m.max(0.0)
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
    #[cfg(test)]
    fn antiderivatives(&self, x: Real) -> (Real, Real) {
        let d = self.delta;
        let x = x.min(d);
        let r = d - x;
        (
            2.0 * d * d - 0.5 * r * r,
            (8.0 * d * d * d - r * r * r) / 3.0,
        )
    }

    /// `(E[w(h + e)], E[w(h + e)²])`: the definition [`Sums`] integrates in closed form (the
    /// tests check one against the other).
    #[cfg(test)]
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
/// triangle's vertices, and so is the band above, where the weights are powers of the linear
/// `q`.
#[derive(Debug, Default)]
struct Sums {
    g: Real,
    gx: Vec3,
    g2: Real,
}

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
    /// The sums of the weight `k w` in place of `w`.
    fn scale(&mut self, k: Real) {
        self.g *= k;
        self.gx *= k;
        self.g2 *= k;
    }

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

    /// Within `s` of the top: `E[w] = q²/4s` and `E[w²] = q³/6s` with `q = δ + s − h` linear
    /// over each fan triangle, integrated in closed form from its vertices' `q`: over a triangle
    /// of area `A` with the barycentric coordinates `λᵢ`, `∫ λ₀^a λ₁^b λ₂^c = 2A a! b! c! /
    /// (a + b + c + 2)!`, so `∫q² = A/6 h₂(q)` and `∫q³ = A/10 h₃(q)` (`h_k` the complete
    /// homogeneous symmetric polynomials of the three `qᵢ`), and `∫x q² = Σᵢ xᵢ ∫λᵢ q²` with
    /// `∫λᵢ q² = A/30 (3qᵢ² + qⱼ² + qₖ² + 2qᵢ(qⱼ + qₖ) + qⱼqₖ)`. (Dunavant's seven-point
    /// quadrature, exact for these, cost six times as much; the tests keep it as the check.)
    fn add_band(&mut self, p: &Poly, weight: &Weight) {
        let top = weight.delta + weight.s;
        let (k1, k2) = (0.25 / weight.s, 1.0 / (6.0 * weight.s));
        for (v, area) in fan(p) {
            let q = v.map(|x| top - x.z);
            let (q0, q1, q2) = (q[0], q[1], q[2]);
            let (s1, s2) = (q0 + q1 + q2, q0 * q0 + q1 * q1 + q2 * q2);
            // h₂ = (s1² + s2)/2, h₃ = (s1³ + 3 s1 s2 + 2 Σq³)/6.
            let cubes = q0 * q0 * q0 + q1 * q1 * q1 + q2 * q2 * q2;
            let h2 = 0.5 * (s1 * s1 + s2);
            let h3 = (s1 * s1 * s1 + 3.0 * s1 * s2 + 2.0 * cubes) / 6.0;
            // `∫λᵢ q²` over `A/30`, for the corner `i`.
            let lam = |i: usize| {
                let (qi, qj, qk) = (q[i], q[(i + 1) % 3], q[(i + 2) % 3]);
                3.0 * qi * qi + qj * qj + qk * qk + 2.0 * qi * (qj + qk) + qj * qk
            };
            self.g += area / 6.0 * h2 * k1;
            self.gx += (v[0] * lam(0) + v[1] * lam(1) + v[2] * lam(2)) * (area / 30.0 * k1);
            self.g2 += area / 10.0 * h3 * k2;
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
mod tests;
