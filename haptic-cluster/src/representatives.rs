//! From clusters to representatives: one spring per cluster (eqs. 30–32), or a torque pair.
//!
//! A cluster's contacts push with `u_i = w_i g_i s_i n_i` (in units of `K' k_c / W`, the
//! stiffness shares of the crate docs) at their points `p_i`. One representative at the weighted
//! centroid `c` along `P = Σ u_i` keeps their force, and their torque but for
//! `M = Σ (p_i − c) × u_i`: the couple of the cluster's contacts about `c`. Where a cluster's
//! forces nearly cancel (a nut's thread pressed on both flanks, a peg wedged in its hole) that
//! couple is most of what turns the tool, and which part of it a cluster loses depends on where
//! Lloyd's method drew its boundaries.
//!
//! A **torque pair** ([`crate::ClusterParams::torque_pairs`]) keeps it. The cluster is written as
//! two springs at `c ± h`, pushing with `P/2 ± G`:
//!
//! - their force is `P`; their torque about `c` is `2 h × G`, which is `M` for
//!   `G = (M × h) / (2 |h|²)` whenever `h ⊥ M`;
//! - `h` is the cluster's spread along the direction `v ⊥ C M` of largest spread, `C` the
//!   contacts' weighted covariance about `c`: `h = C v / √(vᵀ C v)`. Then `h · M = vᵀ C M = 0`,
//!   `|h|` is within the contacts' RMS spread along `h` (Cauchy–Schwarz), and `h` is a weighted
//!   sum of the contacts' offsets `p_i − c`, so the same sum of their body-frame offsets
//!   `r_i − r̄` gives the springs' `r_a` without knowing the tool's pose;
//! - each spring is a point pressed on a fixed plane (normal along its force, the cluster's
//!   depth), so the pair has a potential, as one representative has, and a penalty model or a
//!   linearized contact model takes it as it takes any contact;
//! - their shares `K' |P/2 ± G| / (W g_k)` add up to at most the cluster's own bound
//!   `K' Σ_{i∈k} w_i g_i s_i / (W g_k)`: where the whole couple would need more, `G` is scaled
//!   down until they fit (the pair then keeps part of `M`), so the total stiffness stays within
//!   `K k_c` as with one spring per cluster.
//!
//! A cluster whose contacts all lie at one point has no couple and no spread, and is written as
//! one spring.

use haptic_core::{Contact, ContactSet, Mat3, Real, Vec3};

use crate::{Clusterer, weight};

/// Weighted sums over one cluster's contacts.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Accumulator {
    pub cost: Real,
    pub w: Real,
    pub p_a: Vec3,
    pub r_a: Vec3,
    /// `Σ w_i g_i s_i n_i`: the direction and size of the cluster's penalty.
    pub penalty: Vec3,
    /// `Σ w_i g_i s_i`: the penalty's size were every normal the same.
    pub unsigned: Real,
    pub d: Real,
    pub area_m2: Real,
    pub deepest: usize,
    /// Torque pairs only, about the local origin `o` (the cluster's final centroid from Lloyd's
    /// iterations): `Σ (p_i − o) × u_i` and `Σ w_i (p_i − o)(p_i − o)ᵀ` (xx, yy, zz, xy, xz,
    /// yz).
    pub moment: Vec3,
    pub second: [Real; 6],
    /// The cluster's torque pair, its centroid and mean `r_a` (for the second pass), and its
    /// offset in the body frame (summed in the second pass).
    pub pair: Option<TorquePair>,
    pub centre: Vec3,
    pub body_centre: Vec3,
    pub offset_body: Vec3,
}

impl Default for Accumulator {
    fn default() -> Self {
        Self {
            cost: 0.0,
            w: 0.0,
            p_a: Vec3::zeros(),
            r_a: Vec3::zeros(),
            penalty: Vec3::zeros(),
            unsigned: 0.0,
            d: 0.0,
            area_m2: 0.0,
            deepest: usize::MAX,
            moment: Vec3::zeros(),
            second: [0.0; 6],
            pair: None,
            centre: Vec3::zeros(),
            body_centre: Vec3::zeros(),
            offset_body: Vec3::zeros(),
        }
    }
}

/// The two springs of a torque pair (the module docs), about the cluster's centroid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TorquePair {
    /// `h`: the springs sit at `c ± h` (world, m).
    pub offset: Vec3,
    /// `v / √(vᵀ C v)` (1/m): `h = C v / √(vᵀ C v)` is the weighted mean of `(p_i − c)` times
    /// `(p_i − c) · spread`, and the same mean of `(r_i − r̄)` is `h` in the body frame.
    pub spread: Vec3,
    /// `G`: the springs push with `P/2 ± G` (penalty units, as `P`).
    pub tilt: Vec3,
}

/// The torque pair of a cluster with penalty `p` (`P`), couple `m` (`M` about the centroid),
/// weighted covariance `c` (`C`, m²) and unsigned penalty `unsigned` (`Σ w g s`); `None` when
/// the contacts have no spread where the offset must lie.
pub(crate) fn torque_pair(p: &Vec3, m: &Vec3, c: &Mat3, unsigned: Real) -> Option<TorquePair> {
    let trace = c.trace();
    // Not positive, or NaN: no spread.
    if trace.is_nan() || trace <= 0.0 {
        return None;
    }
    // The direction of largest spread ⊥ C M (then h = C v ⊥ M).
    let v = match unit(c * m, 1e-12 * trace * m.norm()) {
        Some(u) => widest_across(c, &u),
        None => widest(c, trace)?,
    };
    let cv = c * v;
    let spread_sq = v.dot(&cv);
    if spread_sq.is_nan() || spread_sq <= 1e-12 * trace {
        return None;
    }
    let scale = spread_sq.sqrt().recip();
    let offset = cv * scale;
    // h × G = M/2 with G ⊥ h: G = (M × h) / (2 |h|²); the part of M along h (none, up to
    // rounding) is left out.
    let full = m.cross(&offset) * (0.5 * offset.norm_squared().recip());
    let half = p * 0.5;
    let size = |t: Real| (half + full * t).norm() + (half - full * t).norm();
    // The springs' shares within the cluster's bound: the largest t ∈ [0, 1] that fits (the
    // size is convex in t and fits at 0, where it is |P| ≤ Σ w g s). Springs whose forces are
    // parallel (a flat face) fit to rounding, hence the tolerance.
    let fits = |t: Real| size(t) <= unsigned * (1.0 + 1e-12);
    let t = if fits(1.0) {
        1.0
    } else {
        // size(t) = U solved in closed form: with a = P/2, b = G and U² ≥ 4|a|²,
        // t² = U² (U²/4 − |a|²) / (U² |b|² − 4 (a·b)²).
        let (aa, bb, ab) = (half.norm_squared(), full.norm_squared(), half.dot(&full));
        let u2 = unsigned * unsigned;
        let den = u2 * bb - 4.0 * ab * ab;
        let mut t = if den > 0.0 {
            ((u2 * (0.25 * u2 - aa)).max(0.0) / den).sqrt().min(1.0)
        } else {
            0.0
        };
        // Rounding: step back until it fits (0 always does).
        for _ in 0..8 {
            if fits(t) {
                break;
            }
            t *= 1.0 - 1e-9;
        }
        if fits(t) { t } else { 0.0 }
    };
    Some(TorquePair {
        offset,
        spread: v * scale,
        tilt: full * t,
    })
}

/// `v / |v|`, unless `|v| ≤ min` (one square root and one division).
#[inline]
fn unit(v: Vec3, min: Real) -> Option<Vec3> {
    let len = v.norm();
    (len > min).then(|| v * len.recip())
}

/// The unit direction `v ⊥ u` of largest `vᵀ C v` (`u` unit): the larger eigenvector of `C` on
/// the plane across `u`, in closed form.
fn widest_across(c: &Mat3, u: &Vec3) -> Vec3 {
    // An orthonormal basis of the plane: across u from its smallest axis.
    let axis = u.iamin();
    let e1 = unit(u.cross(&Vec3::ith(axis, 1.0)), 0.0).unwrap_or(Vec3::x());
    let e2 = u.cross(&e1);
    let (c1, c2) = (c * e1, c * e2);
    let (b11, b22, b12) = (e1.dot(&c1), e2.dot(&c2), e1.dot(&c2));
    let half_gap = 0.5 * (b11 - b22);
    let lambda = 0.5 * (b11 + b22) + (half_gap * half_gap + b12 * b12).sqrt();
    // (λ − b22, b12) and (b12, λ − b11) are both eigenvectors; the longer is the better
    // conditioned.
    let (a, b) = if lambda - b22 >= lambda - b11 {
        (lambda - b22, b12)
    } else {
        (b12, lambda - b11)
    };
    unit(e1 * a + e2 * b, 0.0).unwrap_or(e1)
}

/// The unit direction of largest `vᵀ C v`: power iteration from `C`'s largest column; `None`
/// when `C` vanishes.
fn widest(c: &Mat3, trace: Real) -> Option<Vec3> {
    let v = (0..3)
        .map(|i| c.column(i).into_owned())
        .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))?;
    let mut v = v.try_normalize(1e-9 * trace)?;
    for _ in 0..8 {
        match (c * v).try_normalize(1e-12 * trace) {
            Some(next) => v = next,
            None => break,
        }
    }
    Some(v)
}

impl Clusterer {
    /// The representatives of the final clusters (eqs. 30–32 and the shares of the crate docs;
    /// a torque pair per cluster when asked for, the module docs), in one pass over the
    /// contacts (two with torque pairs); the clusters' centroids and depths become the next
    /// call's history. Returns the cost `E` (eq. 28) of the final assignment and centroids.
    pub(crate) fn write_representatives(
        &mut self,
        contacts: &[Contact],
        delta_m: Real,
        out: &mut ContactSet,
    ) -> Real {
        let pairs = self.params.torque_pairs;
        let k = self.centroids.len();
        self.acc.clear();
        self.acc.resize(k, Accumulator::default());
        let mut total_w = 0.0;
        for (i, ((c, &a), &w)) in contacts
            .iter()
            .zip(&self.assign)
            .zip(&self.weights)
            .enumerate()
        {
            let origin = self.centroids[a as usize];
            let acc = &mut self.acc[a as usize];
            let off = c.p_a - origin;
            acc.cost += w * off.norm_squared();
            acc.w += w;
            acc.p_a += c.p_a * w;
            acc.r_a += c.r_a * w;
            let push = w * weight(c.depth_m, delta_m) * c.stiffness_share;
            acc.penalty += c.n * push;
            acc.unsigned += push;
            acc.d += c.depth_m * w;
            acc.area_m2 += c.area_m2;
            if acc.deepest == usize::MAX || c.depth_m > contacts[acc.deepest].depth_m {
                acc.deepest = i;
            }
            if pairs {
                acc.moment += off.cross(&c.n) * push;
                let wo = off * w;
                let q = &mut acc.second;
                q[0] += wo.x * off.x;
                q[1] += wo.y * off.y;
                q[2] += wo.z * off.z;
                q[3] += wo.x * off.y;
                q[4] += wo.x * off.z;
                q[5] += wo.y * off.z;
            }
            total_w += w;
        }
        if pairs {
            for (acc, origin) in self.acc.iter_mut().zip(&self.centroids) {
                if acc.deepest == usize::MAX {
                    continue;
                }
                // The sums about the local origin, moved to the centroid.
                let shift = acc.p_a / acc.w - origin;
                let couple = acc.moment - shift.cross(&acc.penalty);
                let q = acc.second.map(|x| x / acc.w);
                let cov = Mat3::new(
                    q[0], q[3], q[4], //
                    q[3], q[1], q[5], //
                    q[4], q[5], q[2],
                ) - shift * shift.transpose();
                acc.pair = torque_pair(&acc.penalty, &couple, &cov, acc.unsigned);
                acc.centre = acc.p_a / acc.w;
                acc.body_centre = acc.r_a / acc.w;
            }
            // The offsets in the body frame: Σ w ((p − c) · spread) (r − r̄) / W over each
            // cluster, as h is over (p − c).
            for ((c, &a), &w) in contacts.iter().zip(&self.assign).zip(&self.weights) {
                let acc = &mut self.acc[a as usize];
                if let Some(pair) = &acc.pair {
                    let along = (c.p_a - acc.centre).dot(&pair.spread);
                    acc.offset_body += (c.r_a - acc.body_centre) * (w * along);
                }
            }
        }
        let written = self.acc.iter().filter(|a| a.deepest != usize::MAX).count() as Real;
        self.previous.clear();
        for acc in &self.acc {
            if acc.deepest == usize::MAX {
                continue;
            }
            let deepest = &contacts[acc.deepest];
            let p_a = acc.p_a / acc.w;
            let r_a = acc.r_a / acc.w;
            let d = (acc.d / acc.w).max(-delta_m);
            self.previous.push((p_a, d));
            // s = K' |F| / (W g_k) for a spring pushing with F (penalty units).
            let share_per_force = written / (total_w * weight(d, delta_m));
            // Opposed normals can cancel: fall back to the deepest contact's normal (the share
            // is then about 0: the spring pushes as little as its contacts do).
            let spring = |p_a: Vec3, r_a: Vec3, f: Vec3, out: &mut ContactSet| {
                let size = f.norm();
                let n = if size > 1e-9 * acc.w * delta_m {
                    f * size.recip()
                } else {
                    deepest.n
                };
                out.push(Contact {
                    p_a,
                    r_a,
                    p_b: p_a - d * n,
                    n,
                    depth_m: d,
                    feature_a: deepest.feature_a,
                    feature_b: deepest.feature_b,
                    area_m2: acc.area_m2,
                    stiffness_share: share_per_force * size,
                });
            };
            match acc.pair {
                Some(pair) => {
                    let half = acc.penalty * 0.5;
                    let offset_body = acc.offset_body / acc.w;
                    self.representative_weights.push(0.5 * acc.w);
                    self.representative_weights.push(0.5 * acc.w);
                    spring(p_a + pair.offset, r_a + offset_body, half + pair.tilt, out);
                    spring(p_a - pair.offset, r_a - offset_body, half - pair.tilt, out);
                }
                None => {
                    self.representative_weights.push(acc.w);
                    spring(p_a, r_a, acc.penalty, out);
                }
            }
        }
        self.acc.iter().map(|a| a.cost).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn vec3() -> impl Strategy<Value = Vec3> {
        prop::array::uniform3(-1.0..1.0f64).prop_map(Vec3::from)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// The two springs push with `P` in all, their offset is across `M`, their couple is
        /// `t M` with `t ∈ [0, 1]` (1 when the bound leaves room), and their sizes stay within
        /// the bound.
        #[test]
        fn a_torque_pair_keeps_the_force_and_what_it_can_of_the_couple(
            p in vec3(),
            m in vec3(),
            a in prop::array::uniform3(vec3()),
            room in 1.0..20.0f64,
        ) {
            let a = Mat3::from_columns(&a);
            let c = a * a.transpose() * 1e-4;
            let unsigned = p.norm() * room + 1e-12;
            let Some(pair) = torque_pair(&p, &(m * 1e-2), &c, unsigned) else {
                // Only when the contacts do not spread.
                prop_assert!(c.trace() < 1e-12);
                return Ok(());
            };
            let m = m * 1e-2;
            let h = pair.offset;
            let (f1, f2) = (p * 0.5 + pair.tilt, p * 0.5 - pair.tilt);
            prop_assert!((f1 + f2 - p).norm() <= 1e-12 * (1.0 + p.norm()));
            prop_assert!(h.dot(&m).abs() <= 1e-9 * h.norm() * m.norm() + 1e-300);
            let couple = h.cross(&f1) - h.cross(&f2);
            // couple = t m, t in [0, 1]
            let t = couple.dot(&m) / m.norm_squared().max(1e-300);
            prop_assert!((couple - m * t).norm() <= 1e-9 * m.norm() + 1e-15, "{couple:?} not along {m:?}");
            prop_assert!((-1e-9..=1.0 + 1e-9).contains(&t), "t = {t}");
            prop_assert!(f1.norm() + f2.norm() <= unsigned * (1.0 + 1e-9));
            let needed = p.norm() + m.norm() / h.norm();
            if needed <= unsigned && m.norm() > 1e-9 {
                prop_assert!((t - 1.0).abs() < 1e-9, "t = {t} with room");
            }
            // The springs lie within the contacts' root-mean-square spread along h.
            let u = h.normalize();
            prop_assert!(h.norm() * h.norm() <= u.dot(&(c * u)) * (1.0 + 1e-9));
        }
    }

    #[test]
    fn contacts_at_one_point_make_no_pair() {
        let p = Vec3::new(0.0, 0.0, 1.0);
        assert!(torque_pair(&p, &Vec3::zeros(), &Mat3::zeros(), 1.0).is_none());
    }

    /// Contacts spread along one line only, with a couple across it: the offset lies along the
    /// line (the only spread there is), and the couple is kept.
    #[test]
    fn contacts_on_a_line_keep_their_couple() {
        let c = Mat3::new(4e-6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let p = Vec3::new(0.0, 0.0, 2.0);
        let m = Vec3::new(0.0, 1e-3, 0.0);
        let pair = torque_pair(&p, &m, &c, 10.0).unwrap();
        assert!((pair.offset - Vec3::new(2e-3, 0.0, 0.0)).norm() < 1e-15);
        let couple = 2.0 * pair.offset.cross(&pair.tilt);
        assert!((couple - m).norm() < 1e-15, "{couple:?}");
    }
}
