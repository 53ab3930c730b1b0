//! The budget's selection (`super`): which of the regions the first walk wrote are refined, the
//! fewest of the largest bounds that leave the rest's error within the budget.

use haptic_core::Real;

use super::Written;

/// The error a set of regions may make in its net force: their direction bounds added, their
/// weights' in quadrature (`Σ bᵢ + √(Σ eᵢ²)`, from the sums `Σ bᵢ` and `Σ eᵢ²`). A direction
/// bound is a bound, and the regions of one curved surface err the same way; a weight's is a
/// spread's half-width, a statistic whose sign differs from region to region.
fn error_of(directions: Real, weights_squared: Real) -> Real {
    directions.max(0.0) + weights_squared.max(0.0).sqrt()
}

/// Which moment of the regions' forces a budget holds (`super`, module docs): the penalty's,
/// `Σ w n` over the stiffness, or the clustering's, `Σ w g n`, in which each region's force and
/// bounds weigh its `g`-weighted mean gap times as much.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Moment {
    /// `Σ w n`: the force the contacts push with.
    Penalty,
    /// `Σ w g n`: what the clustering's representatives push with (`haptic-cluster`).
    Clustering,
}

impl Moment {
    /// What a force at the mean gap `gap_m` (m) weighs in this moment, per unit of the
    /// penalty's: 1, or the gap.
    #[inline]
    pub(crate) fn weight(self, gap_m: Real) -> Real {
        match self {
            Self::Penalty => 1.0,
            Self::Clustering => gap_m,
        }
    }

    /// What an entry's force and bounds weigh in this moment, per unit of the penalty's.
    #[inline]
    pub(crate) fn scale(self, w: &Written) -> Real {
        self.weight(w.gap_m)
    }
}

/// How many of `written` must be refined, moved to its front: every one marked `always`, then
/// the fewest of the others, largest `bound + weight_bound` first, that leave the rest's error
/// ([`error_of`]) at most `budget`, all in the `moment` held ([`Moment::scale`]). Entries with
/// neither bound (triangle pairs, flat pieces) are taken only when marked. The ones taken are
/// in no particular order.
///
/// The fewest largest are found by partitioning about pivots, as a selection does, keeping the
/// part that holds the answer: linear time expected, where sorting them took `k log k` (a
/// jaws query takes a thousand of two thousand entries, in up to eight rounds).
pub(crate) fn take_largest(written: &mut [Written], budget: Real, moment: Moment) -> usize {
    // The marked ones first (a partition, in place).
    let mut marked = 0;
    for i in 0..written.len() {
        if written[i].always {
            written.swap(marked, i);
            marked += 1;
        }
    }
    let rest = &mut written[marked..];
    let (total_b, total_e2) = sums(rest, moment);
    let left_within = |(b, e2): (Real, Real)| error_of(total_b - b, total_e2 - e2) <= budget;
    // (A NaN, from bounds that are not finite, refines nothing more.)
    let error = error_of(total_b, total_e2);
    if error.is_nan() || error <= budget {
        return marked;
    }
    // Those with no bound are never taken: out of the search, at the end.
    let mut hi = rest.len();
    let mut i = 0;
    while i < hi {
        if key(&rest[i], moment) > 0.0 {
            i += 1;
        } else {
            hi -= 1;
            rest.swap(i, hi);
        }
    }
    // `rest[..lo]` are taken, their sums `out`; the answer lies in `rest[lo..hi]`, every one of
    // which comes after those of `rest[..lo]` in `larger_first`.
    let (mut lo, mut out) = (0, (0.0, 0.0));
    while lo < hi {
        let part = &mut rest[lo..hi];
        let pivot = median_of_three(
            &part[0],
            &part[part.len() / 2],
            &part[part.len() - 1],
            moment,
        );
        // The ones before the pivot, then the pivot.
        let before = partition_about(part, &pivot, moment);
        let with_before = add(out, sums(&part[..before], moment));
        if left_within(with_before) {
            hi = lo + before;
            continue;
        }
        let with_pivot = add(with_before, sums(std::slice::from_ref(&pivot), moment));
        if left_within(with_pivot) {
            return marked + lo + before + 1;
        }
        lo += before + 1;
        out = with_pivot;
    }
    marked + lo
}

/// The order entries are taken in: the larger `bound + weight_bound` first, then the larger
/// weight bound, then the smaller index (a total order, so that which of equal bounds are taken
/// does not depend on where they stood).
fn larger_first(x: &Written, y: &Written, moment: Moment) -> std::cmp::Ordering {
    key(y, moment)
        .total_cmp(&key(x, moment))
        .then((y.weight_bound * moment.scale(y)).total_cmp(&(x.weight_bound * moment.scale(x))))
        .then(x.index.cmp(&y.index))
        .then(x.pair.cmp(&y.pair))
}

/// What an entry is taken by: its two bounds added, in `moment`.
fn key(w: &Written, moment: Moment) -> Real {
    (w.bound + w.weight_bound) * moment.scale(w)
}

/// The sums [`error_of`] reads of `ws` in `moment`: their direction bounds, and their weight
/// bounds squared.
fn sums(ws: &[Written], moment: Moment) -> (Real, Real) {
    ws.iter().fold((0.0, 0.0), |(b, e2), w| {
        let k = moment.scale(w);
        let e = w.weight_bound * k;
        (b + w.bound * k, e2 + e * e)
    })
}

/// Two pairs of sums added.
fn add(a: (Real, Real), b: (Real, Real)) -> (Real, Real) {
    (a.0 + b.0, a.1 + b.1)
}

/// The middle of three entries in [`larger_first`] order.
fn median_of_three(a: &Written, b: &Written, c: &Written, moment: Moment) -> Written {
    use std::cmp::Ordering::Greater;
    let (a, b) = if larger_first(a, b, moment) == Greater {
        (b, a)
    } else {
        (a, b)
    };
    // `a` before `b`: the middle is `b` unless `c` comes before it.
    if larger_first(b, c, moment) != Greater {
        *b
    } else if larger_first(a, c, moment) == Greater {
        *a
    } else {
        *c
    }
}

/// Reorders `part` (which holds `pivot`) into the entries before `pivot` in [`larger_first`]
/// order, then `pivot`, then the rest; returns how many come before it.
fn partition_about(part: &mut [Written], pivot: &Written, moment: Moment) -> usize {
    use std::cmp::Ordering::{Equal, Less};
    let mut before = 0;
    for i in 0..part.len() {
        if larger_first(&part[i], pivot, moment) == Less {
            part.swap(before, i);
            before += 1;
        }
    }
    // The pivot itself (the only entry equal to it) next.
    if let Some(at) = (before..part.len()).find(|&i| larger_first(&part[i], pivot, moment) == Equal)
    {
        part.swap(before, at);
    }
    before
}

/// Entries of the given direction bounds and no weight bound, indexed in order (for tests).
#[cfg(test)]
pub(super) fn written_with_bounds(bounds: &[Real]) -> Vec<Written> {
    bounds
        .iter()
        .enumerate()
        .map(|(i, &b)| Written {
            index: i as u32,
            pair: (i as u32, 0),
            bound: b,
            weight_bound: 0.0,
            force: haptic_core::Vec3::zeros(),
            gap_m: 1.0,
            always: false,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use haptic_core::Vec3;

    /// Weight errors add in quadrature, direction bounds linearly: four weight errors of 1
    /// make 2, not 4; with a direction bound of 1 beside them, 3.
    #[test]
    fn weight_errors_add_in_quadrature_and_direction_bounds_linearly() {
        let mut w = written_with_bounds(&[0.0; 4]);
        for x in &mut w {
            x.weight_bound = 1.0;
        }
        assert_eq!(take_largest(&mut w, 2.0, Moment::Penalty), 0);
        assert_eq!(take_largest(&mut w, 1.9, Moment::Penalty), 1);
        // Taking one leaves √3 ≤ 1.8.
        let mut w = written_with_bounds(&[0.0, 0.0, 0.0, 0.0, 1.0]);
        for x in &mut w[..4] {
            x.weight_bound = 1.0;
        }
        assert_eq!(take_largest(&mut w, 3.0, Moment::Penalty), 0);
        // 2.8: one taken leaves 1 + √3 or 2, within it (every key is 1).
        let k = take_largest(&mut w, 2.8, Moment::Penalty);
        assert_eq!(k, 1);
        let (b, e2) = sums(&w[k..], Moment::Penalty);
        assert!(error_of(b, e2) <= 2.8, "{b} {e2}");
    }

    /// The fewest largest by a full sort, as `take_largest` once found them: the count taken.
    fn taken_by_sorting(written: &[Written], budget: Real, moment: Moment) -> usize {
        let marked = written.iter().filter(|w| w.always).count();
        let mut rest: Vec<Written> = written.iter().filter(|w| !w.always).copied().collect();
        let total = sums(&rest, moment);
        let within = |(b, e2): (Real, Real)| error_of(total.0 - b, total.1 - e2) <= budget;
        if within((0.0, 0.0)) {
            return marked;
        }
        rest.sort_by(|x, y| larger_first(x, y, moment));
        let (mut taken, mut out) = (0, (0.0, 0.0));
        for w in &rest {
            if within(out) || key(w, moment) <= 0.0 {
                break;
            }
            out = add(out, sums(std::slice::from_ref(w), moment));
            taken += 1;
        }
        marked + taken
    }

    proptest::proptest! {
        /// The selection takes as many as sorting them all would, the largest (ties aside), the
        /// marked ones first, and leaves the rest within the budget where the bounds allow.
        #[test]
        fn the_selection_takes_what_a_full_sort_takes(
            entries in proptest::collection::vec(
                (0u32..6, 0u32..6, proptest::bool::weighted(0.05), 0u32..4),
                0..300,
            ),
            share in 0.0f64..1.2,
            clustering in proptest::bool::ANY,
        ) {
            // Few distinct values, so that ties are many; a fifth with neither bound.
            let moment = if clustering { Moment::Clustering } else { Moment::Penalty };
            let mut w: Vec<Written> = entries
                .iter()
                .enumerate()
                .map(|(i, &(b, e, always, gap))| Written {
                    index: i as u32,
                    pair: (i as u32, 0),
                    bound: 0.25 * Real::from(b),
                    weight_bound: 0.5 * Real::from(e),
                    force: Vec3::zeros(),
                    gap_m: 0.5 * Real::from(gap),
                    always,
                })
                .collect();
            let total = sums(&w, moment);
            let budget = share * error_of(total.0, total.1);
            let expected = taken_by_sorting(&w, budget, moment);
            let k = take_largest(&mut w, budget, moment);
            proptest::prop_assert_eq!(k, expected);
            let marked = w.iter().filter(|w| w.always).count();
            proptest::prop_assert!(w[..marked].iter().all(|w| w.always));
            let least_taken = w[marked..k]
                .iter()
                .map(|w| key(w, moment))
                .fold(Real::INFINITY, Real::min);
            let most_left = w[k..].iter().map(|w| key(w, moment)).fold(0.0, Real::max);
            proptest::prop_assert!(k == marked || least_taken >= most_left);
            proptest::prop_assert!(w[marked..k].iter().all(|w| key(w, moment) > 0.0));
        }
    }

    #[test]
    fn the_fewest_largest_bounds_that_bring_the_rest_within_budget_are_taken() {
        // 40 small bounds and three large ones: the rest must come within 1.0.
        let mut bounds = vec![0.01; 40];
        bounds.extend([3.0, 0.5, 2.0]);
        let mut w = written_with_bounds(&bounds);
        let k = take_largest(&mut w, 1.0, Moment::Penalty);
        // Total 5.9: taking 3.0 leaves 2.9, then 2.0 leaves 0.9 ≤ 1.0.
        assert_eq!(k, 2);
        let mut taken: Vec<Real> = w[..k].iter().map(|w| w.bound).collect();
        taken.sort_by(|a, b| b.total_cmp(a));
        assert_eq!(taken, [3.0, 2.0]);
        let rest: Real = w[k..].iter().map(|w| w.bound).sum();
        assert!(rest <= 1.0 + 1e-12);
    }

    #[test]
    fn marked_regions_are_taken_whatever_the_budget() {
        let mut w = written_with_bounds(&[0.0, 0.2, 0.0, 5.0]);
        w[2].always = true;
        // Within budget without it: only the marked one.
        let k = take_largest(&mut w, 10.0, Moment::Penalty);
        assert_eq!(k, 1);
        assert_eq!(w[0].index, 2);
        // Over budget: the marked one, then the largest.
        let mut w = written_with_bounds(&[0.0, 0.2, 0.0, 5.0]);
        w[0].always = true;
        let k = take_largest(&mut w, 1.0, Moment::Penalty);
        assert_eq!(k, 2);
        assert_eq!((w[0].index, w[1].index), (0, 3));
    }

    #[test]
    fn nothing_is_taken_within_budget_and_zero_bounds_never() {
        let mut w = written_with_bounds(&[0.2, 0.3]);
        assert_eq!(take_largest(&mut w, 0.5, Moment::Penalty), 0);
        // A budget of zero takes every positive bound and no zero one.
        let mut w = written_with_bounds(&[0.0, 0.4, 0.0, 0.1]);
        assert_eq!(take_largest(&mut w, 0.0, Moment::Penalty), 2);
        assert!(w[..2].iter().all(|w| w.bound > 0.0));
        // Many entries: the doubling partition finds the same answer as a full sort.
        let bounds: Vec<Real> = (0..1000)
            .map(|i| ((i * 7919) % 1000) as Real * 1e-3)
            .collect();
        let mut w = written_with_bounds(&bounds);
        let total: Real = bounds.iter().sum();
        let k = take_largest(&mut w, 0.5 * total, Moment::Penalty);
        let mut sorted = bounds.clone();
        sorted.sort_by(|a, b| b.total_cmp(a));
        let mut left = 0.5 * total;
        let expected = sorted
            .iter()
            .take_while(|&&b| {
                let take = left > 0.0;
                left -= b;
                take
            })
            .count();
        assert_eq!(k, expected);
    }

    /// In the clustering's moment each entry's bounds weigh its gap times as much: of two equal
    /// bounds, the one at three times the gap is taken first, and alone brings the rest within
    /// a budget the penalty's moment would meet by taking either.
    #[test]
    fn the_clustering_moment_weighs_each_bound_by_its_gap() {
        let mut w = written_with_bounds(&[1.0, 1.0]);
        w[1].gap_m = 3.0;
        // Penalty: 2 against 1.5, one taken, the tie broken by index.
        assert_eq!(take_largest(&mut w, 1.5, Moment::Penalty), 1);
        assert_eq!(w[0].index, 0);
        // Clustering: 1 + 3 against 2.5; the one at gap 3 taken, leaving 1.
        let mut w = written_with_bounds(&[1.0, 1.0]);
        w[1].gap_m = 3.0;
        assert_eq!(take_largest(&mut w, 2.5, Moment::Clustering), 1);
        assert_eq!(w[0].index, 1);
        // Within 4, none; within 0.5, both.
        assert_eq!(take_largest(&mut w, 4.0, Moment::Clustering), 0);
        assert_eq!(take_largest(&mut w, 0.5, Moment::Clustering), 2);
    }
}
