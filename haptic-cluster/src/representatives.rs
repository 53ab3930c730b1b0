//! From clusters to representatives: one spring per cluster (eqs. 30–32), or a torque pair.
//!
//! A cluster's contacts push with `u_i = w_i g_i s_i n_i` (in units of `N k_c / W`, the
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
//! - their shares `N |P/2 ± G| / (W g_k)` add up to at most the cluster's own bound
//!   `N Σ_{i∈k} w_i g_i s_i / (W g_k)`: where the whole couple would need more, `G` is scaled
//!   down until they fit (the pair then keeps part of `M`), so the total stiffness stays within
//!   `K k_c` as with one spring per cluster.
//!
//! A cluster whose contacts all lie at one point has no couple and no spread, and is written as
//! one spring.

use haptic_core::{Contact, ContactSet, Mat3, Real, Vec3};

use crate::{Clusterer, weight};

/// Weighted sums over one cluster's contacts.
#[derive(Debug, Clone, Copy)]
struct Sums {
    cost: Real,
    w: Real,
    p_a: Vec3,
    r_a: Vec3,
    /// `Σ w_i g_i s_i n_i`: the direction and size of the cluster's penalty.
    penalty: Vec3,
    /// `Σ w_i g_i s_i`: the penalty's size were every normal the same.
    unsigned: Real,
    d: Real,
    area_m2: Real,
    deepest: usize,
    /// Torque pairs only, about the cluster's centroid `c = Σ w_i p_i / W`: the couple
    /// `Σ (p_i − c) × u_i` and `Σ w_i (p_i − c)(p_i − c)ᵀ` (xx, yy, zz, xy, xz, yz).
    moment: Vec3,
    second: [Real; 6],
}

impl Default for Sums {
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
    // Not positive (or subnormal, or NaN): no spread.
    if !(trace.is_finite() && trace >= Real::MIN_POSITIVE) {
        return None;
    }
    // The directions are found on S = C / tr C (eigenvalues in [0, 1], the largest at least
    // 1/3) and on unit vectors, so that no product underflows or overflows however far apart
    // the contacts are or however small the couple is; h = √(tr C) S v / √(vᵀ S v).
    let inv_trace = trace.recip();
    let s_c = c * inv_trace;
    // The direction of largest spread ⊥ C M (then h ⊥ M); its length does not matter, since h
    // and the spread below are the same for any multiple of v.
    let sm = s_c * m;
    let sm_sq = sm.norm_squared();
    let v = if sm_sq > 1e-24 * m.norm_squared() && sm_sq >= Real::MIN_POSITIVE {
        widest_across(&s_c, &(sm * sm_sq.sqrt().recip()))
    } else {
        widest(&s_c)?
    };
    let v = v * v.norm().recip();
    let sv = s_c * v;
    let spread_sq = v.dot(&sv);
    if spread_sq.is_nan() || spread_sq <= 1e-12 {
        return None;
    }
    // h = √(tr C) S v / √(vᵀ S v), and h × G = M/2 with G ⊥ h: G = (M × h) / (2 |h|²); the
    // part of M along h (none, up to rounding) is left out.
    let root = spread_sq.sqrt();
    let root_trace = trace.sqrt();
    let offset = sv * (root_trace / root);
    let full = m.cross(&offset) * (0.5 * offset.norm_squared().recip());
    let spread = v * (root_trace * root).recip();
    if !(offset
        .iter()
        .chain(&spread)
        .chain(&full)
        .all(|x| x.is_finite()))
    {
        return None;
    }
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
        // Rounding: step back until it fits, eight times at most; then 0 (no couple).
        let mut steps = 0;
        while !fits(t) && steps < 8 {
            steps += 1;
            t *= 1.0 - 1e-9;
        }
        if steps < 8 || fits(t) { t } else { 0.0 }
    };
    Some(TorquePair {
        offset,
        spread,
        tilt: full * t,
    })
}

/// A direction `v ⊥ u` of largest `vᵀ S v / |v|²` (`u` unit), of no particular length: the
/// larger eigenvector of `S` on the plane across `u`, in closed form.
fn widest_across(s_c: &Mat3, u: &Vec3) -> Vec3 {
    // An orthogonal basis of the plane, both of one length: e1 = u × (u's smallest axis),
    // e2 = u × e1. The plane's block of S in it is B / |e1|² (b_ij = e_iᵀ S e_j), with the
    // eigenvectors of the orthonormal basis.
    let e1 = u.cross(&Vec3::ith(u.iamin(), 1.0));
    let e2 = u.cross(&e1);
    let (c1, c2) = (s_c * e1, s_c * e2);
    let (b11, b22, b12) = (e1.dot(&c1), e2.dot(&c2), e1.dot(&c2));
    let half_gap = 0.5 * (b11 - b22);
    let lambda = 0.5 * (b11 + b22) + (half_gap * half_gap + b12 * b12).sqrt();
    // (λ − b22, b12) and (b12, λ − b11) are both eigenvectors; the longer is the better
    // conditioned.
    let v = if lambda - b22 >= lambda - b11 {
        e1 * (lambda - b22) + e2 * b12
    } else {
        e1 * b12 + e2 * (lambda - b11)
    };
    if v.norm_squared() > 0.0 { v } else { e1 }
}

/// A direction of largest `vᵀ S v / |v|²` for `S = C / tr C` (eigenvalues in [0, 1], the
/// largest at least 1/3), of no particular length: eight steps of power iteration from `S`'s
/// largest column, which need no normalisation; `None` when `S` has no column of size. A
/// cluster of two contacts (`S` of rank one, `S M = 0`) comes here every call: the largest
/// column is then already the answer.
fn widest(s_c: &Mat3) -> Option<Vec3> {
    let mut v = s_c.column(0).into_owned();
    for i in 1..3 {
        let col = s_c.column(i);
        if col.norm_squared() > v.norm_squared() {
            v = col.into_owned();
        }
    }
    if v.norm_squared() <= 1e-18 {
        return None;
    }
    for _ in 0..8 {
        v = s_c * v;
    }
    (v.norm_squared() > 0.0).then_some(v)
}

impl Clusterer {
    /// The representatives of the final clusters (eqs. 30–32 and the shares of the crate docs;
    /// a torque pair per cluster when asked for, the module docs), cluster by cluster over each
    /// one's contacts (twice with torque pairs); the clusters' centroids and depths become the
    /// next call's history. `with_areas`: whether the contacts carry the areas they stand for
    /// (the shares are then out of the `K` clusters asked for, otherwise out of those written;
    /// the crate docs). Returns the cost `E` (eq. 28) of the final assignment and centroids.
    pub(crate) fn write_representatives(
        &mut self,
        contacts: &[Contact],
        delta_m: Real,
        with_areas: bool,
        out: &mut ContactSet,
    ) -> Real {
        let pairs = self.params.torque_pairs;
        let k = self.centroids.len();
        // The contacts in cluster order (a stable counting sort), so that each cluster's sums
        // build up in registers rather than in memory.
        self.starts.clear();
        self.starts.resize(k + 1, 0);
        for &a in &self.assign {
            self.starts[a as usize + 1] += 1;
        }
        for j in 0..k {
            self.starts[j + 1] += self.starts[j];
        }
        self.order.resize(contacts.len(), 0);
        for (i, &a) in self.assign.iter().enumerate() {
            let slot = &mut self.starts[a as usize];
            self.order[*slot as usize] = i as u32;
            *slot += 1;
        }
        // `starts[j]` is now where cluster j ends; it began where cluster j − 1 ends.
        let total_w: Real = self.weights.iter().sum();
        // Contacts with areas stand for surface: the shares are out of K, the clusters asked
        // for, so that the clustered penalty is the same whether the surface came as few
        // contacts (a coarse level, a coarse tessellation) or many. Points without areas are
        // springs each (the paper's model): out of K', the clusters written.
        let stiffness_total = if with_areas {
            self.params.max_clusters as Real
        } else {
            k as Real
        };
        self.previous.clear();
        let mut cost = 0.0;
        for j in 0..k {
            let begin = if j == 0 {
                0
            } else {
                self.starts[j - 1] as usize
            };
            let members = &self.order[begin..self.starts[j] as usize];
            let origin = self.centroids[j];
            let mut acc = Sums::default();
            for &i in members {
                let (c, w) = (&contacts[i as usize], self.weights[i as usize]);
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
                    acc.deepest = i as usize;
                }
            }
            if pairs {
                // Apart from the sums above, so that each loop's sums stay in registers; about
                // the centroid itself, as the springs' body-frame offsets are below. Sums about
                // another point moved to the centroid (`Σ w o oᵀ / W − s sᵀ`) cancel where the
                // contacts' spread is small beside that point's distance, and the rounding left
                // over would place a pair where the contacts have no spread.
                let centroid = acc.p_a * acc.w.recip();
                for &i in members {
                    let (c, w) = (&contacts[i as usize], self.weights[i as usize]);
                    let off = c.p_a - centroid;
                    let push = w * weight(c.depth_m, delta_m) * c.stiffness_share;
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
            }
            cost += acc.cost;
            let Some(deepest) = contacts.get(acc.deepest) else {
                continue; // no contact (not after an assignment; kept for safety)
            };
            let inv_w = acc.w.recip();
            let p_a = acc.p_a * inv_w;
            let r_a = acc.r_a * inv_w;
            let d = (acc.d * inv_w).max(-delta_m);
            self.previous.push((p_a, d));
            // A spread within the rounding of the contacts' positions is no spread: contacts at
            // one point differ from their weighted mean by an ulp or so, which a pair would
            // read as a direction.
            let rounding_m = 16.0 * Real::EPSILON * p_a.norm();
            let spread_m2 = (acc.second[0] + acc.second[1] + acc.second[2]) * inv_w;
            let pair = if pairs && spread_m2 > rounding_m * rounding_m {
                let q = acc.second.map(|x| x * inv_w);
                let cov = Mat3::new(
                    q[0], q[3], q[4], //
                    q[3], q[1], q[5], //
                    q[4], q[5], q[2],
                );
                torque_pair(&acc.penalty, &acc.moment, &cov, acc.unsigned).map(|pair| {
                    // The offset in the body frame: Σ w ((p − c) · spread) (r − r̄) / W over the
                    // cluster, as h is over (p − c).
                    let mut offset_body = Vec3::zeros();
                    for &i in members {
                        let (c, w) = (&contacts[i as usize], self.weights[i as usize]);
                        let along = (c.p_a - p_a).dot(&pair.spread);
                        offset_body += (c.r_a - r_a) * (w * along);
                    }
                    (pair, offset_body * inv_w)
                })
            } else {
                None
            };
            // s = K |F| / (W g_k) for a spring pushing with F (penalty units).
            let share_per_force = stiffness_total / (total_w * weight(d, delta_m));
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
            match pair {
                Some((pair, offset_body)) => {
                    let half = acc.penalty * 0.5;
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
        cost
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

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]

        /// Whatever the scales of the spread, couple and force (down to contacts nanometres
        /// apart and couples near rounding), a pair is finite or there is none.
        #[test]
        fn a_torque_pair_is_finite_at_any_scale(
            p in vec3(),
            m in vec3(),
            a in prop::array::uniform3(vec3()),
            spread_exp in -40i32..2,
            couple_exp in -60i32..2,
            rank_one in any::<bool>(),
        ) {
            let a = Mat3::from_columns(&a);
            let mut c = a * a.transpose() * (10.0f64).powi(spread_exp);
            if rank_one {
                let d = a.column(0).into_owned();
                c = d * d.transpose() * (10.0f64).powi(spread_exp);
            }
            let m = m * (10.0f64).powi(couple_exp);
            if let Some(pair) = torque_pair(&p, &m, &c, p.norm() * 2.0 + 1e-12) {
                let finite = |v: &Vec3| v.iter().all(|x| x.is_finite());
                prop_assert!(finite(&pair.offset) && finite(&pair.spread) && finite(&pair.tilt),
                    "{pair:?} from c = {c:?}, m = {m:?}");
            }
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
