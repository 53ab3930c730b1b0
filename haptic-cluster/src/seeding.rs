//! Where Lloyd's method starts: the seeds of a call (Algorithm VI.1's initialisation).
//!
//! - **Cold** (no history): the deepest contact, then furthest points.
//! - **Warm, at the old centroids** (the first try): the kept old clusters' centroids, so that
//!   contacts that barely moved start at a fixed point of Lloyd's method and the first
//!   assignment is the last (one iteration).
//! - **Warm, at the nearest contacts** (the paper's seeds; the fallback when an old centroid
//!   has no contact nearest to it, because the contacts jumped): each kept old cluster at the
//!   free contact nearest its centroid (greedy closest pairs), so that every cluster starts
//!   with a contact.
//!
//! Either warm kind keeps the old clusters' order, so cluster identities persist from frame to
//! frame; seeds beyond the old clusters go to the contacts furthest from the seeds so far.

use haptic_core::{Contact, Real, Vec3};

use crate::Clusterer;

/// Which warm seeds to use (the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Seeds {
    /// The old clusters' centroids.
    AtOldCentroids,
    /// The free contacts nearest the old clusters' centroids (greedy closest pairs).
    AtNearestContacts,
}

impl Clusterer {
    /// Picks up to `k_max` distinct seeds into `centroids`: the kept old clusters as `warm`
    /// says, or the deepest contact when `warm` is `None`; then the contacts furthest from the
    /// seeds so far.
    pub(crate) fn seed(&mut self, contacts: &[Contact], k_max: usize, warm: Option<Seeds>) {
        self.centroids.clear();
        // Keep the K deepest old clusters: drop the shallowest.
        if warm.is_some() && self.previous.len() > k_max {
            self.previous.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
            self.previous.truncate(k_max);
        }
        match warm {
            Some(Seeds::AtOldCentroids) => {
                for &(old, _) in &self.previous {
                    // Two old clusters at one point would make one empty: keep the first. A
                    // non-finite history (from `warm_start_from`) seeds nothing.
                    if old.iter().all(|x| x.is_finite()) && !self.centroids.contains(&old) {
                        self.centroids.push(old);
                    }
                }
            }
            Some(Seeds::AtNearestContacts) => self.seed_at_nearest_contacts(),
            None => {
                // The deepest contact (lowest index among equals).
                let mut first = 0;
                for (i, c) in contacts.iter().enumerate() {
                    if c.depth_m > contacts[first].depth_m {
                        first = i;
                    }
                }
                self.centroids.push(self.points.get(first));
            }
        }
        self.seed_furthest_points(k_max);
    }

    /// Whether the last assignment left a cluster without a contact.
    pub(crate) fn has_empty_cluster(&mut self) -> bool {
        self.count_members();
        self.count.contains(&0)
    }

    /// Each old cluster at the free contact nearest its centroid: greedy closest pairs, the
    /// closest pair first (ties: the lowest old index, then the lowest contact index).
    fn seed_at_nearest_contacts(&mut self) {
        let n = self.points.len();
        let m = self.previous.len();
        self.taken_new.clear();
        self.taken_new.resize(n, false);
        self.taken_old.clear();
        self.taken_old.resize(m, false);
        self.seed_of_old.clear();
        self.seed_of_old.resize(m, usize::MAX);
        self.best_of_old.clear();
        // Nothing is taken yet: a plain arg-min per old cluster.
        for j in 0..m {
            let row = &mut self.dist[..n];
            self.points.distances_squared(&self.previous[j].0, row);
            self.best_of_old.push(closest_free(row, &self.taken_new));
        }
        for _ in 0..m {
            let mut pick = usize::MAX;
            for j in 0..m {
                if !self.taken_old[j]
                    && self.best_of_old[j].1 != usize::MAX
                    && (pick == usize::MAX || self.best_of_old[j].0 < self.best_of_old[pick].0)
                {
                    pick = j;
                }
            }
            if pick == usize::MAX {
                break;
            }
            let i = self.best_of_old[pick].1;
            self.taken_old[pick] = true;
            self.taken_new[i] = true;
            self.seed_of_old[pick] = i;
            // Old clusters whose closest contact was just taken look again (rare).
            for j in 0..m {
                if !self.taken_old[j] && self.best_of_old[j].1 == i {
                    let row = &mut self.dist[..n];
                    self.points.distances_squared(&self.previous[j].0, row);
                    self.best_of_old[j] = closest_free(row, &self.taken_new);
                }
            }
        }
        for &i in &self.seed_of_old {
            if i == usize::MAX {
                continue;
            }
            let p = self.points.get(i);
            // Coincident contacts could give two old clusters the same seed position: skip.
            if !self.centroids.contains(&p) {
                self.centroids.push(p);
            }
        }
    }

    /// Adds the contacts furthest from the seeds so far until there are `k_max` seeds (or every
    /// contact coincides with a seed).
    fn seed_furthest_points(&mut self, k_max: usize) {
        if self.centroids.len() >= k_max {
            return;
        }
        let n = self.points.len();
        self.min_d2.clear();
        self.min_d2.resize(n, Real::INFINITY);
        let row = &mut self.dist[..n];
        for c in &self.centroids {
            self.points.distances_squared(c, row);
            for (m, d) in self.min_d2.iter_mut().zip(row.iter()) {
                *m = m.min(*d);
            }
        }
        while self.centroids.len() < k_max {
            let mut best = (0.0, usize::MAX);
            for (i, &d2) in self.min_d2.iter().enumerate() {
                if d2 > best.0 {
                    best = (d2, i);
                }
            }
            if best.1 == usize::MAX {
                break; // every remaining contact coincides with a seed
            }
            let s: Vec3 = self.points.get(best.1);
            self.centroids.push(s);
            self.points.distances_squared(&s, row);
            for (m, d) in self.min_d2.iter_mut().zip(row.iter()) {
                *m = m.min(*d);
            }
        }
    }
}

/// The arg-min of a row over the entries not `taken` (ties: lowest index), or `usize::MAX`.
fn closest_free(row: &[Real], taken: &[bool]) -> (Real, usize) {
    let mut best = (Real::INFINITY, usize::MAX);
    for (i, (&d2, &t)) in row.iter().zip(taken).enumerate() {
        if !t && d2 < best.0 {
            best = (d2, i);
        }
    }
    best
}
