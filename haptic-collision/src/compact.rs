//! Compact contacts: the raw contacts of a query merged into at most `max` contacts that keep
//! what the clustering and the penalty model read of them.
//!
//! A query near a large contact region finds one contact per triangle pair (or per coarse
//! sample) within `δ`: tens of thousands on a finely tessellated pair, growing with the
//! tessellation, when the force needs a few. [`Compactor::compact`] merges them, region by
//! region, so that their number depends on the contact regions and not on the triangles:
//!
//! - Contacts are binned by a cubic grid of cell size `h` on the tool points `p_a` and by the
//!   dominant axis and sign of their normal (six bins, so that the two flanks of a thin wall or
//!   a thread, with opposed normals, do not merge; only a cap below 7 can force them together).
//!   `h` starts at an eighth of the contacts' extent and grows until at most `max − 1` cells are
//!   occupied, each time by the square root of how many cells too many a pass found (and 5 %
//!   more), so the last pass lands just under the cap; it never depends on the scene's scale or
//!   tessellation, only on where the contacts are.
//! - The contacts of a cell become one contact that keeps the sums the clustering reads
//!   (`haptic-cluster`, eqs. 28–32, with weights `w_i = a_i (d_i + δ)`): depth, `p_a` and `r_a`
//!   the `w`-weighted means (so `Σ w d` and `Σ w p` are kept), area `a = Σ w_i / (d + δ)` (so its
//!   weight `a (d + δ)` is `Σ w_i`; it is `Σ a_i` when the depths agree, and less when they
//!   differ, the price of keeping the representative's depth), normal `normalize(Σ w_i n_i)`.
//!   A cluster that takes whole cells therefore gets the same centroid, weight and depth as
//!   from the raw contacts. (Keeping the area and the area-weighted depth instead makes every
//!   representative shallower: on the jaws that cost a third of the force.)
//! - A cell whose normals disagree (`|Σ w n| < Σ w`, a curved surface, a thread's two flanks)
//!   is written as two contacts at its point, with half its weight each and the normals
//!   `m ± s u`: `m = Σ w n / Σ w`, `s = √(1 − |m|²)` (so both are unit). Together they keep
//!   `Σ w n`, so the penalty the contacts stand for, `Σ a (d + δ) n`, is the raw contacts' (its
//!   torque to second order in the cell size), and so is each cluster's normal when it takes
//!   whole cells. One contact per cell would report `Σ w` along `m`'s direction: more force
//!   than the raw contacts by `Σ w − |Σ w n|` per cell, up to 7 % on pressed spheres
//!   (`lod::tests::compact_contacts_give_the_all_pairs_wrench`). The two halves' depths are
//!   `d ± e` (their areas `(Σ w / 2) / (d ± e + δ)`, so `Σ w` and `Σ w d` are kept too), and `u`
//!   and `e` are chosen so that they also keep the part across `m` of `Σ w g n`
//!   (`g = d + δ`), the penalty the clustering reads (`haptic-cluster`'s stiffness shares): `u`
//!   along that part of `Σ w (g − ḡ) n`, the way the cell's depths lean with its normals (a
//!   thread's loaded flank deeper than the other), and `e = |that part| / (Σ w s)`. Where the
//!   depths do not lean, `e = 0` and `u` is the direction across `m` in which the normals spread
//!   most (principal axis of their covariance). `e` is capped so that neither half is deeper
//!   than the cell's deepest contact nor at the weights' floor, and their areas add up to no
//!   more than the cell's (`e² ≤ ḡ (ḡ − Σ w / Σ a)`); the part of `Σ w g n` along `m` is not
//!   kept. The halves sit at `p̄ ± v` (and `r̄ ± Rᵀ v` in the tool's frame, so `Σ w p` and
//!   `Σ w r` are kept): together they push with the torque `w s v × u` about `p̄`, and `v = u ×
//!   τ / (Σ w s)` makes that the part across `u` of the cell's own torque about its point,
//!   `τ = Σ w (p − p̄) × n`, which one point per cell loses. `|v|` is capped at the cell's
//!   spread (`√(Σ w |p − p̄|² / Σ w)`). On a curved wall whose contacts push nearly all ways at
//!   once, that torque is much of the wrench: on the suite's bolts in their nuts, the
//!   compaction alone made the penalty's wrench off the raw contacts' by 0.042 (median) and
//!   0.155 (p90) at threshold 0; with the halves placed apart, 0.002 and 0.007
//!   (`docs/experiments/lod-accuracy-and-speed-probes.md`, probe 32). Splits count against
//!   `max`: a pass fits when its cells and their splits do. Only below `max = 13` (six normal
//!   bins, each split, and the deepest contact) may there be no room for every split; then the
//!   cells that lose most are split first.
//! - The clustering reads a torque of its own, that of `Σ w g n`: the halves push it with
//!   `w v × (ḡ s u + e m)` about `p̄`, while the cell's contacts push `τ_g = Σ w g (p − p̄) × n`,
//!   which is `ḡ τ` only where the depths do not vary over the cell. `v`'s part along `u`
//!   leaves `w s v × u` (so `τ`'s part) alone and adds `w λ e u × m`: `λ` is chosen to keep the
//!   part of `τ_g` along `u × m` that the rest leaves out, with `|v|` still within the
//!   spread. On the suite's bolts, the clustered wrench's error at threshold 0 (the compaction's
//!   own) went from 0.016 / 0.031 (median / p90) to 0.011 / 0.021 on the coarse one and from
//!   0.014 / 0.029 to 0.010 / 0.018 on the fine one, the penalty's above unchanged (probe 41).
//! - The deepest raw contact is kept as it is, so the closest approach (or deepest point) that
//!   the query reports is unchanged by compaction.
//!
//! Areas below [`area_floor_m2`] (degenerate triangles) are raised to it, so every cell has a
//! weight. A cell of one contact is that contact; merged cells carry no feature indices.

use haptic_core::{Contact, ContactSet, Mat3, NO_FEATURE, Pose, Real, Vec3, gap_weight_m};

/// The smallest area a contact weighs for in a merge, as a fraction of `δ²`: 10⁻¹² (10⁻¹⁸ m²,
/// a square nanometre, at `δ` = 1 mm). Relative to the penalty's reach, not a fixed area, so
/// that a scene given in other units is the same computation
/// (`lod::tests::a_scene_in_other_units_gives_the_same_query`).
pub const AREA_FLOOR_PER_DELTA2: Real = 1e-12;

/// The smallest area a contact weighs for in a merge at the penalty's reach `delta_m` (m²):
/// [`AREA_FLOOR_PER_DELTA2`] `δ²`.
#[inline]
pub fn area_floor_m2(delta_m: Real) -> Real {
    AREA_FLOOR_PER_DELTA2 * delta_m * delta_m
}

/// Cells per side of the contacts' bounding box in the first pass.
const FIRST_CELLS_PER_SIDE: Real = 8.0;

/// The sums of one cell.
#[derive(Debug, Clone, Copy)]
struct Cell {
    key: u64,
    count: u32,
    /// The cell's single contact, while it has one.
    first: u32,
    w: Real,
    p_a: Vec3,
    r_a: Vec3,
    n: Vec3,
    /// `Σ w_i d_i`.
    w_depth: Real,
    /// `Σ w_i g_i n_i` (`g = d + δ`): the penalty the clustering reads of the cell.
    wgn: Vec3,
    /// `Σ a_i` (m²).
    area_m2: Real,
    /// `Σ w_i n_i n_iᵀ`: xx, yy, zz, xy, xz, yz.
    nn: [Real; 6],
    /// Normal of the cell's deepest contact (the fallback when the normals cancel).
    deepest_n: Vec3,
    deepest_d: Real,
    /// Written as one contact even though its normals disagree (no room to split it).
    whole: bool,
    /// The cell's first tool point, about which `torque` and `spread` are summed.
    origin: Vec3,
    /// `Σ w_i (p_i − origin) × n_i`.
    torque: Vec3,
    /// `Σ w_i g_i (p_i − origin) × n_i`: the torque of the penalty the clustering reads.
    torque_g: Vec3,
    /// `Σ w_i |p_i − origin|²` (m²).
    spread: Real,
}

/// Relative force a cell's one contact may add, `1 − |Σ w n| / Σ w`, below which it is not split.
const SPLIT_TOLERANCE: Real = 1e-9;

impl Cell {
    /// Whether the cell is written as two contacts: it merges contacts whose normals disagree,
    /// and there was room.
    #[inline]
    fn split(&self) -> bool {
        self.count > 1 && !self.whole && self.n.norm() < (1.0 - SPLIT_TOLERANCE) * self.w
    }
}

const EMPTY: u64 = u64::MAX;

impl Default for Cell {
    fn default() -> Self {
        Self {
            key: EMPTY,
            count: 0,
            first: 0,
            w: 0.0,
            p_a: Vec3::zeros(),
            r_a: Vec3::zeros(),
            n: Vec3::zeros(),
            w_depth: 0.0,
            wgn: Vec3::zeros(),
            area_m2: 0.0,
            nn: [0.0; 6],
            deepest_n: Vec3::z(),
            deepest_d: Real::NEG_INFINITY,
            whole: false,
            origin: Vec3::zeros(),
            torque: Vec3::zeros(),
            torque_g: Vec3::zeros(),
            spread: 0.0,
        }
    }
}

/// Merges raw contacts into compact ones (see the module docs). Reused between queries: after
/// warm-up it allocates nothing.
#[derive(Debug, Clone, Default)]
pub struct Compactor {
    /// Open-addressing table of cells (a power of two, at least four times `max`).
    table: Vec<Cell>,
    /// Slots used in this pass, in the order first seen (so the output order is deterministic).
    used: Vec<u32>,
    /// The merged contacts, before they replace the raw ones.
    merged: Vec<Contact>,
    /// Cells whose normals disagree, with how much force their one contact would add
    /// (`Σ w − |Σ w n|`), when not all of them can be split.
    splits: Vec<(Real, u32)>,
}

impl Compactor {
    /// An empty compactor.
    pub fn new() -> Self {
        Self::default()
    }

    /// Replaces the contacts of `set` by at most `max` compact ones when there are more (see the
    /// module docs); `tool` is the tool's pose the contacts were found at (their `r_a` are
    /// `p_a` in its body frame), `delta_m` the query's distance tolerance. `max` below 2 is taken
    /// as 2 (the deepest contact and one cell). Returns the number of contacts before
    /// compaction.
    pub fn compact(
        &mut self,
        set: &mut ContactSet,
        tool: &Pose,
        delta_m: Real,
        max: usize,
    ) -> usize {
        let max = max.max(2);
        let raw = set.as_slice();
        let n = raw.len();
        if n <= max {
            return n;
        }
        let Some(deepest) = deepest_index(raw) else {
            return n;
        };
        let capacity = (4 * max).next_power_of_two();
        if self.table.len() != capacity {
            self.table.clear();
            self.table.resize(capacity, Cell::default());
        }
        let (lo, extent) = bounds(raw);
        let mut h = if extent > 0.0 {
            extent / FIRST_CELLS_PER_SIDE
        } else {
            1.0
        };
        // A pass that does not fit grows `h`: by the square root of how many cells too many it
        // found (a surface's cells go as 1/h²) and 5 % more, so that the last pass lands just
        // under the cap, or doubles it when even the count overflowed. Once `h` exceeds the
        // extent, every contact is in one spatial cell and at most six normal bins; should even
        // that be too many (`max` below 7), the normals are no longer told apart and one cell
        // remains, so this ends.
        let fit = max - 1;
        let count_limit = (self.table.len() / 2).max(fit);
        let mut by_normal = true;
        //
        // A cell whose normals disagree is written as two contacts (see the module docs), so a
        // pass fits when its cells and those splits do; once one cell spans the contacts' extent
        // the splits are optional: the cells that fit are split, those that lose most first.
        loop {
            match self.bin(raw, deepest, &lo, h, by_normal, delta_m, count_limit) {
                Some(cells) => {
                    let split = self
                        .used
                        .iter()
                        .filter(|&&s| self.table[s as usize].split())
                        .count();
                    if cells + split <= fit || (h > extent && cells <= fit) {
                        break;
                    }
                    h *= 1.05 * ((cells + split) as Real / fit as Real).sqrt();
                }
                None => h *= 2.0,
            }
            if h > extent {
                by_normal = false;
            }
        }
        self.choose_splits(fit);
        let body_from_world = tool
            .orientation
            .to_rotation_matrix()
            .into_inner()
            .transpose();
        self.merged.clear();
        self.merged.push(raw[deepest]);
        for &slot in &self.used {
            let c = &self.table[slot as usize];
            if c.count == 1 {
                self.merged.push(raw[c.first as usize]);
            } else if c.split() {
                let [x, y] = split_contacts(c, delta_m, &body_from_world);
                self.merged.push(x);
                self.merged.push(y);
            } else {
                self.merged.push(merged_contact(c, delta_m));
            }
        }
        set.clear();
        set.extend(self.merged.iter().copied());
        n
    }

    /// Leaves at most `fit` minus the cells of the pass split: when there are more, those whose
    /// one contact would add most force are split, and the others marked whole.
    fn choose_splits(&mut self, fit: usize) {
        self.splits.clear();
        for &slot in &self.used {
            let c = &self.table[slot as usize];
            if c.split() {
                self.splits.push((c.w - c.n.norm(), slot));
            }
        }
        let budget = fit.saturating_sub(self.used.len());
        if self.splits.len() <= budget {
            return;
        }
        self.splits
            .sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for &(_, slot) in &self.splits[budget..] {
            self.table[slot as usize].whole = true;
        }
    }

    /// Bins every contact but `skip` with cell size `h` (and by normal when `by_normal`); the
    /// number of cells occupied, or `None` (and the pass abandoned) when more than `limit`.
    #[allow(clippy::too_many_arguments)]
    fn bin(
        &mut self,
        raw: &[Contact],
        skip: usize,
        lo: &Vec3,
        h: Real,
        by_normal: bool,
        delta_m: Real,
        limit: usize,
    ) -> Option<usize> {
        for &slot in &self.used {
            self.table[slot as usize] = Cell::default();
        }
        self.used.clear();
        let mask = self.table.len() - 1;
        let floor_m2 = area_floor_m2(delta_m);
        let inv_h = 1.0 / h;
        for (i, c) in raw.iter().enumerate() {
            if i == skip {
                continue;
            }
            let mut key = cell_key(&c.p_a, &c.n, lo, inv_h);
            if !by_normal {
                key &= !(7 << 61);
            }
            let mut slot = (hash(key) as usize) & mask;
            loop {
                let cell = &self.table[slot];
                if cell.key == key || cell.key == EMPTY {
                    break;
                }
                slot = (slot + 1) & mask;
            }
            let cell = &mut self.table[slot];
            if cell.key == EMPTY {
                if self.used.len() == limit {
                    return None;
                }
                cell.key = key;
                cell.first = i as u32;
                cell.origin = c.p_a;
                self.used.push(slot as u32);
            }
            let area = c.area_m2.max(floor_m2);
            let g = c.gap_weight_m(delta_m);
            let w = area * g;
            cell.wgn += c.n * (w * g);
            cell.area_m2 += area;
            cell.count += 1;
            cell.w += w;
            cell.p_a += c.p_a * w;
            cell.r_a += c.r_a * w;
            cell.n += c.n * w;
            cell.w_depth += w * c.depth_m;
            let dp = c.p_a - cell.origin;
            let dp_n = dp.cross(&c.n);
            cell.torque += dp_n * w;
            cell.torque_g += dp_n * (w * g);
            cell.spread += w * dp.norm_squared();
            let wn = c.n * w;
            cell.nn[0] += wn.x * c.n.x;
            cell.nn[1] += wn.y * c.n.y;
            cell.nn[2] += wn.z * c.n.z;
            cell.nn[3] += wn.x * c.n.y;
            cell.nn[4] += wn.x * c.n.z;
            cell.nn[5] += wn.y * c.n.z;
            if c.depth_m > cell.deepest_d {
                cell.deepest_d = c.depth_m;
                cell.deepest_n = c.n;
            }
        }
        Some(self.used.len())
    }
}

/// The deepest contact (the first of equals), `None` for an empty slice.
fn deepest_index(raw: &[Contact]) -> Option<usize> {
    let mut best: Option<(usize, Real)> = None;
    for (i, c) in raw.iter().enumerate() {
        if best.is_none_or(|(_, d)| c.depth_m > d) {
            best = Some((i, c.depth_m));
        }
    }
    best.map(|(i, _)| i)
}

/// The lower corner of the tool points' bounding box and its largest side.
fn bounds(raw: &[Contact]) -> (Vec3, Real) {
    let mut lo = Vec3::repeat(Real::INFINITY);
    let mut hi = Vec3::repeat(Real::NEG_INFINITY);
    for c in raw {
        lo = lo.inf(&c.p_a);
        hi = hi.sup(&c.p_a);
    }
    (lo, (hi - lo).max())
}

/// Cell index along each axis (21 bits each) and the normal's bin (3 bits), packed.
#[inline]
fn cell_key(p: &Vec3, n: &Vec3, lo: &Vec3, inv_h: Real) -> u64 {
    let idx = |k: usize| (((p[k] - lo[k]) * inv_h) as u64).min((1 << 21) - 1);
    let a = n.abs();
    let axis: usize = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let bin = 2 * axis as u64 + u64::from(n[axis] < 0.0);
    idx(0) | (idx(1) << 21) | (idx(2) << 42) | (bin << 61)
}

/// A multiplicative hash (Fibonacci hashing's constant), high bits folded down.
#[inline]
pub(crate) fn hash(key: u64) -> u64 {
    let h = key.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    h ^ (h >> 29)
}

/// A merged cell whose normals disagree as two contacts (see the module docs): half its weight
/// each, the normals `m ± s u` (`m = Σ w n / Σ w`, `s = √(1 − |m|²)`) and the depths `d ± e`,
/// which keep `Σ w n` and the part of `Σ w g n` across `m`.
fn split_contacts(c: &Cell, delta_m: Real, body_from_world: &Mat3) -> [Contact; 2] {
    let one = merged_contact(c, delta_m);
    let m = c.n / c.w;
    let s = (1.0 - m.norm_squared()).max(0.0).sqrt();
    // How the cell's depths follow its normals, across m: `Σ w g n − ḡ Σ w n`.
    let g_bar = gap_weight_m(one.depth_m, delta_m);
    let mhat = m.try_normalize(0.0).unwrap_or(Vec3::z());
    let lean = c.wgn - c.n * g_bar;
    let lean = lean - mhat * mhat.dot(&lean);
    let (u, e) = match lean.try_normalize(1e-12 * c.w * g_bar) {
        Some(u) if s > 0.0 => {
            // Neither half deeper than the cell's deepest contact, nor at the weights' floor,
            // and their areas, (w/2)/(ḡ ± e), not more than the cell's: e² ≤ ḡ (ḡ − w / Σ a).
            let floor = gap_weight_m(-delta_m, delta_m);
            let area_room = (g_bar * (g_bar - c.w / c.area_m2)).max(0.0).sqrt();
            let room = (c.deepest_d - one.depth_m)
                .min(g_bar - 2.0 * floor)
                .min(area_room)
                .max(0.0);
            (u, (lean.norm() / (c.w * s)).min(room))
        }
        _ => (spread_direction(c, &m), 0.0),
    };
    // The halves at `p̄ ± v` (and `r̄ ± Rᵀ v`): `(w/2)(v × n₊ − v × n₋) = w s v × u` keeps the
    // part across `u` of the cell's torque about `p̄`, `Σ w (p − p̄) × n`, with `|v|` at most
    // the cell's spread; `v`'s part along `u` keeps what it can of the clustering's torque.
    let v = if s > 0.0 {
        let from_origin = one.p_a - c.origin;
        let torque = c.torque - from_origin.cross(&c.n);
        let spread_m = (c.spread / c.w - from_origin.norm_squared())
            .max(0.0)
            .sqrt();
        let v = u.cross(&torque) / (c.w * s);
        let length_m = v.norm();
        let v = if length_m > spread_m {
            v * (spread_m / length_m)
        } else {
            v
        };
        // The halves push the clustering's penalty with the torque `w v × a` about `p̄`;
        // `λ u` adds `w λ e u × m` to it, nothing to `w s v × u`.
        let torque_g = c.torque_g - from_origin.cross(&c.wgn);
        let a = u * (g_bar * s) + m * e;
        let um = u.cross(&m);
        let k = c.w * e * um.norm_squared();
        let room_m = (spread_m * spread_m - v.norm_squared()).max(0.0).sqrt();
        let lambda = (torque_g - v.cross(&a) * c.w).dot(&um) / k;
        if k > 0.0 && lambda.is_finite() {
            v + u * lambda.clamp(-room_m, room_m)
        } else {
            v
        }
    } else {
        Vec3::zeros()
    };
    let v_body = body_from_world * v;
    let half = |n: Vec3, d: Real, sign: Real| {
        let n = n.normalize();
        let p_a = one.p_a + v * sign;
        Contact {
            n,
            p_a,
            r_a: one.r_a + v_body * sign,
            p_b: p_a - n * d,
            depth_m: d,
            area_m2: 0.5 * c.w / gap_weight_m(d, delta_m),
            ..one
        }
    };
    [
        half(m + u * s, one.depth_m + e, 1.0),
        half(m - u * s, one.depth_m - e, -1.0),
    ]
}

/// The unit direction across `m` in which the cell's normals spread most: the principal axis
/// of their covariance `Σ w n nᵀ / Σ w − m mᵀ`, made perpendicular to `m` (any perpendicular
/// when that vanishes).
fn spread_direction(c: &Cell, m: &Vec3) -> Vec3 {
    let q = c.nn.map(|x| x / c.w);
    let cov = nalgebra::Matrix3::new(
        q[0], q[3], q[4], //
        q[3], q[1], q[5], //
        q[4], q[5], q[2],
    ) - m * m.transpose();
    let eig = cov.symmetric_eigen();
    let (k, _) = eig.eigenvalues.argmax();
    let axis: Vec3 = eig.eigenvectors.column(k).into_owned();
    let mhat = m.try_normalize(0.0).unwrap_or(Vec3::z());
    let across = axis - mhat * mhat.dot(&axis);
    across.try_normalize(1e-9).unwrap_or_else(|| {
        let other = if mhat.x.abs() < 0.9 {
            Vec3::x()
        } else {
            Vec3::y()
        };
        mhat.cross(&other).normalize()
    })
}

/// The contact a merged cell stands for (see the module docs).
fn merged_contact(c: &Cell, delta_m: Real) -> Contact {
    let p_a = c.p_a / c.w;
    // A mean is at most the deepest of the cell; clamped there so that rounding never makes a
    // merged contact deeper than the deepest raw one.
    let d = (c.w_depth / c.w).min(c.deepest_d).max(-delta_m);
    // The floor on `d + δ` is the clustering's (a cell of contacts all at `−δ`).
    let area_m2 = c.w / gap_weight_m(d, delta_m);
    let n = c.n.try_normalize(1e-9 * c.w).unwrap_or(c.deepest_n);
    Contact {
        p_a,
        r_a: c.r_a / c.w,
        p_b: p_a - n * d,
        n,
        depth_m: d,
        feature_a: NO_FEATURE,
        feature_b: NO_FEATURE,
        area_m2,
        stiffness_share: 1.0,
    }
}

#[cfg(test)]
mod tests;
