//! # haptic-cluster
//!
//! k-means contact clustering by Lloyd's method with temporal coherence (Otaduy & Lin 2006,
//! Section VI-B, eqs. 28–32, Algorithm VI.1).
//!
//! A collision query near a large contact area returns tens to hundreds of contacts. Summing a
//! penalty spring per contact would make the contact stiffness grow with the number of contacts,
//! and the haptic loop unstable. The [`Clusterer`] reduces them to at most `K` clusters
//! (default 5), so the total translational stiffness is bounded by `K · k_c` whatever the
//! triangle count.
//!
//! - Contacts are weighted by depth and by the area they stand for, `w_i = a_i (d_i + δ)` (the
//!   depth term floored at `δ · 1e-3`, so pre-contacts at exactly `−δ` keep a small positive
//!   weight). `a_i` is the contact's `area_m2` when every contact of the call has one, and 1
//!   otherwise (a back-end that does not measure areas): with areas, a flat face pulls a
//!   centroid as hard however finely it is tessellated.
//! - Lloyd's iterations minimise `E = Σ w_i |p_i − c_k(i)|²` (eq. 28) with weighted centroids
//!   (eq. 29), until the assignment stops changing or the iteration cap is hit. `E` never
//!   increases from one iteration to the next.
//! - Warm start from the previous call: the old clusters with the smallest depth are dropped when
//!   fewer are wanted; each kept cluster is seeded at its old centroid, so that contacts that
//!   barely moved start at a fixed point of Lloyd's method (one iteration); more seeds go to the
//!   contacts furthest from the seeds chosen so far. Where an old centroid then has no contact
//!   nearest to it (the contacts jumped), the seeds are the paper's instead: each kept cluster at
//!   the free contact nearest its old centroid (greedy closest pairs), so every cluster starts
//!   with a contact. A cold start seeds the deepest contact first, then furthest points
//!   (`seeding.rs`).
//! - The representative of a cluster (eqs. 30–32, our choice where the paper is silent):
//!   `p_a = c_k`, `r_a` the weighted mean of the `r_a`, `d = Σ w_i d_i / Σ w_i`,
//!   `n = normalize(Σ w_i g_i n_i)` (`g_i = d_i + δ`: the direction of the penalty its contacts
//!   make), `p_b = p_a − d n`.
//! - **Stiffness shares** (not in the paper, which gives every representative the same `k_c`):
//!   representative `k` pushes with the share
//!   `s_k = N |Σ_{i∈k} w_i g_i n_i| / (W g_k)` of the contact stiffness and damping
//!   (`Contact::stiffness_share`), with `W = Σ_i w_i` over all contacts, `g_k = d_k + δ`, and
//!   `N` the clusters asked for, `K` ([`ClusterParams::max_clusters`]), where the contacts
//!   carry areas, or the clusters written, `K' ≤ K`, where they do not. A penalty model then
//!   pushes each with `k_c s_k g_k n_k = N k_c Σ_{i∈k} w_i g_i n_i / W`, and their sum,
//!   `N k_c Σ_i w_i g_i n_i / W`, is the contacts' weighted penalty whatever the partition:
//!   where Lloyd's method draws its boundaries moves the torque a little (each cluster's force
//!   acts at its centroid) but not the force. With contacts that stand for surface, it does
//!   not depend on how many there were either: `K'` falls below `K` where there are fewer
//!   contacts than `K` (a coarse level of detail, a coarse tessellation: one region where the
//!   fine mesh has twenty contacts), and out of `K'` the force jumped by `K'/K` there (a fork on
//!   the teacup at 0.4 %, whose contacts' own error was 0.006 at p90, was off by exactly 0.2 or
//!   0.4 once clustered). Points without areas are each a spring of the paper's model, and
//!   share the `K'` springs' stiffness. With clusters of one depth and normal and equal
//!   weights, the shares are 1 (the paper's model, every representative `k_c`) when there are
//!   `N` of them; the shares add up to at most `N ≤ K`, so the total translational stiffness
//!   stays within `K · k_c`. A cluster whose normals cancel pushes as little as they do. A
//!   contact's own share (1 from a back-end) scales the penalty it adds.
//! - **Torque pairs** (not in the paper; [`ClusterParams::torque_pairs`], on by default): one
//!   spring at its cluster's centroid keeps the cluster's force but not the couple of its
//!   contacts about that point, and where a cluster's forces nearly cancel (a thread pressed on
//!   both flanks) that couple is most of what turns the tool. Each cluster is then written as
//!   two springs either side of its centroid, pushing with `P/2 ± G`, that keep its force and
//!   its torque (`representatives.rs`): up to `2K` representatives, each a point pressed on a
//!   fixed plane (so the pair has a potential), their shares within the cluster's part of the
//!   `K k_c` bound. With them the clustered wrench is the contacts' own penalty wrench whatever
//!   the partition, force and torque.
//! - After warm-up (the largest contact count seen so far), a call allocates nothing.
//!
//! It owns only the clustering: contacts come from a `haptic_core::CollisionBackend`, and the
//! representatives go to a `haptic_core::ContactModel` (the penalty model lives in
//! `haptic-dynamics`).
//!
//! ```
//! use haptic_cluster::{ClusterParams, Clusterer};
//! use haptic_core::{Contact, ContactSet, Vec3};
//!
//! // Two patches of contacts on the floor, 10 cm apart.
//! let mut raw = Vec::new();
//! for i in 0..20 {
//!     let x = if i % 2 == 0 { 0.0 } else { 0.1 } + 1e-3 * i as f64;
//!     let p = Vec3::new(x, 0.0, 0.0);
//!     raw.push(Contact::new(p, p, p, -Vec3::z(), 1e-4).unwrap());
//! }
//! let mut clusterer = Clusterer::new(ClusterParams { max_clusters: 2, ..Default::default() }).unwrap();
//! let mut reps = ContactSet::new();
//! let stats = clusterer.cluster(&raw, 1e-3, &mut reps).unwrap();
//! assert_eq!(stats.clusters, 2);
//! assert!(stats.converged);
//! // Each cluster is a torque pair of two springs (the default).
//! assert_eq!(reps.len(), 4);
//! // The paper's model: one spring per cluster.
//! let paper = ClusterParams { max_clusters: 2, torque_pairs: false, ..Default::default() };
//! Clusterer::new(paper).unwrap().cluster(&raw, 1e-3, &mut reps).unwrap();
//! assert_eq!(reps.len(), 2);
//! ```

use haptic_core::{Contact, ContactSet, CoreError, Real, Vec3};

mod points;
mod representatives;
mod seeding;
use points::Points;
use seeding::Seeds;
use thiserror::Error;

/// Parameters of the clustering.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClusterParams {
    /// `K`, the largest number of clusters (the paper used 5). With fewer contacts (or fewer
    /// distinct contact points) than `K`, there are as many clusters as those.
    pub max_clusters: usize,
    /// Cap on Lloyd iterations per call (assignment + centroid update each).
    pub max_iterations: usize,
    /// Seed from the previous call's clusters (temporal coherence); `false` always cold-starts.
    pub warm_start: bool,
    /// Write each cluster as a torque pair: two springs that keep its contacts' torque as well
    /// as their force (the crate docs), so up to `2K` representatives
    /// ([`ClusterParams::max_representatives`]). `false` writes one spring per cluster, the
    /// paper's model.
    pub torque_pairs: bool,
}

impl ClusterParams {
    /// The most representatives a call writes: `K`, or `2K` with torque pairs.
    pub fn max_representatives(&self) -> usize {
        if self.torque_pairs {
            2 * self.max_clusters
        } else {
            self.max_clusters
        }
    }
}

impl Default for ClusterParams {
    /// `K = 5`, at most 16 iterations, warm start on, torque pairs.
    fn default() -> Self {
        Self {
            max_clusters: 5,
            max_iterations: 16,
            warm_start: true,
            torque_pairs: true,
        }
    }
}

/// Bad input to the clustering.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
#[non_exhaustive]
pub enum ClusterError {
    /// `K = 0` was asked for.
    #[error("the number of clusters K must be at least 1")]
    ZeroClusters,
    /// An iteration cap of 0 was asked for.
    #[error("the iteration cap must be at least 1")]
    ZeroIterations,
    /// More clusters than [`MAX_CLUSTERS`] were asked for.
    #[error("at most {max} clusters, {asked} asked for", max = MAX_CLUSTERS)]
    TooManyClusters {
        /// The number asked for.
        asked: usize,
    },
    /// An iteration cap above [`MAX_ITERATIONS`] was asked for.
    #[error("at most {max} iterations, {asked} asked for", max = MAX_ITERATIONS)]
    TooManyIterations {
        /// The cap asked for.
        asked: usize,
    },
    /// `δ` was not finite and positive.
    #[error("the contact tolerance δ must be finite and > 0, got {delta_m} m")]
    BadDelta {
        /// The value given (m).
        delta_m: Real,
    },
    /// A contact had a NaN or infinite field.
    #[error("contact {index} has a non-finite {what}")]
    NonFiniteContact {
        /// Index of the contact in the input.
        index: usize,
        /// Which field.
        what: &'static str,
    },
    /// A contact normal was not unit length (a zero normal among them).
    #[error("contact {index} has a normal of norm {norm}, expected 1")]
    BadNormal {
        /// Index of the contact in the input.
        index: usize,
        /// The norm found.
        norm: Real,
    },
}

/// Most clusters a [`Clusterer`] takes (the haptic thread's model takes 16 representatives;
/// studies of the clustering itself may ask for more).
pub const MAX_CLUSTERS: usize = 4096;
/// Most Lloyd iterations a [`Clusterer`] takes.
pub const MAX_ITERATIONS: usize = 100_000;

/// What one call did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ClusterStats {
    /// Number of clusters produced.
    pub clusters: usize,
    /// Lloyd iterations run.
    pub iterations: usize,
    /// Whether the assignment stopped changing before the cap.
    pub converged: bool,
    /// Whether the call was seeded from the previous one.
    pub warm: bool,
    /// Final cost `E` (eq. 28), in kg-free units of `m³` (weight in m times squared distance).
    pub cost: Real,
}

/// Weight of a contact, `d + δ`, floored so it stays positive (`haptic_core::gap_weight_m`).
#[inline]
fn weight(depth_m: Real, delta_m: Real) -> Real {
    haptic_core::gap_weight_m(depth_m, delta_m)
}

/// k-means contact clustering with reusable buffers and warm start (see the crate docs).
#[derive(Debug, Clone)]
pub struct Clusterer {
    params: ClusterParams,
    /// Contact positions `p_a` (world, m) and weights of the current call.
    points: Points,
    weights: Vec<Real>,
    /// Cluster index of each contact.
    assign: Vec<u32>,
    /// Scratch row of the seeding: squared distances from one point to every contact (m²).
    dist: Vec<Real>,
    /// Hamerly bounds per contact: upper on the distance to its centroid, lower on the distance
    /// to any other (m); and how far each centroid moved in the last update (m).
    upper: Vec<Real>,
    lower: Vec<Real>,
    moves: Vec<Real>,
    /// Whether to record the cost after each assignment ([`Clusterer::record_costs`]).
    record_costs: bool,
    /// Squared distance of each contact to the nearest seed (seeding).
    min_d2: Vec<Real>,
    /// Scratch of the seeds at contacts: which old clusters / contacts are taken during the
    /// greedy pairing, the contact chosen for each old cluster, and each old cluster's closest
    /// free contact (squared distance, index).
    taken_old: Vec<bool>,
    taken_new: Vec<bool>,
    seed_of_old: Vec<usize>,
    best_of_old: Vec<(Real, usize)>,
    /// Seeds, then centroids (m), and per-cluster sums.
    centroids: Vec<Vec3>,
    sums: Vec<[Real; 4]>,
    count: Vec<u32>,
    /// Old cluster index to new, when empty clusters are dropped.
    remap: Vec<u32>,
    /// Previous call's representatives (position m, depth m), for the warm start.
    previous: Vec<(Vec3, Real)>,
    /// Scratch: the contacts' indices in cluster order, and where each cluster's run ends.
    order: Vec<u32>,
    starts: Vec<u32>,
    /// Cost after each assignment of the last call.
    costs: Vec<Real>,
    /// Each representative's weight `Σ w_i` of the last call, in the order written.
    representative_weights: Vec<Real>,
}

impl Clusterer {
    /// A clusterer with empty history.
    ///
    /// # Errors
    /// [`ClusterError::ZeroClusters`] for `K = 0`, [`ClusterError::ZeroIterations`] for a zero
    /// iteration cap.
    pub fn new(params: ClusterParams) -> Result<Self, ClusterError> {
        if params.max_clusters == 0 {
            return Err(ClusterError::ZeroClusters);
        }
        if params.max_iterations == 0 {
            return Err(ClusterError::ZeroIterations);
        }
        // The scratch buffers are reserved for K up front: a K beyond any use is an error, not
        // an allocation that fails.
        if params.max_clusters > MAX_CLUSTERS {
            return Err(ClusterError::TooManyClusters {
                asked: params.max_clusters,
            });
        }
        if params.max_iterations > MAX_ITERATIONS {
            return Err(ClusterError::TooManyIterations {
                asked: params.max_iterations,
            });
        }
        let k = params.max_clusters;
        Ok(Self {
            params,
            points: Points::default(),
            weights: Vec::new(),
            assign: Vec::new(),
            dist: Vec::new(),
            upper: Vec::new(),
            lower: Vec::new(),
            moves: Vec::with_capacity(k),
            record_costs: false,
            min_d2: Vec::new(),
            taken_old: Vec::with_capacity(k),
            taken_new: Vec::new(),
            seed_of_old: Vec::with_capacity(k),
            best_of_old: Vec::with_capacity(k),
            centroids: Vec::with_capacity(k),
            sums: Vec::with_capacity(k),
            count: Vec::with_capacity(k),
            remap: Vec::with_capacity(k),
            previous: Vec::with_capacity(k),
            order: Vec::new(),
            starts: Vec::with_capacity(k + 1),
            costs: Vec::with_capacity(params.max_iterations + 2),
            representative_weights: Vec::with_capacity(k),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &ClusterParams {
        &self.params
    }

    /// Forgets the previous clusters, so the next call cold-starts.
    pub fn reset(&mut self) {
        self.previous.clear();
    }

    /// The weight of each representative written by the last call, in its order: the sum of its
    /// contacts' weights `w_i = a_i (d_i + δ)` (eq. 28's weights; m³ with areas, m without, see
    /// the crate docs). Empty after an empty input or an error.
    pub fn representative_weights(&self) -> &[Real] {
        &self.representative_weights
    }

    /// Makes `representatives` the history that the next call warm-starts from, as if they had
    /// been the previous call's output (only their `p_a` and `depth_m` are used). Useful to
    /// restore a saved state, or to cluster two contact sets of the same configuration from the
    /// same seeds, so that they are compared in the same basin of Lloyd's method rather than in
    /// whichever local minimum each chain of warm starts reached. With torque pairs
    /// ([`ClusterParams::torque_pairs`]) the representatives are springs beside their clusters'
    /// centres: use [`Clusterer::warm_start_from_centres`] with another clusterer's
    /// [`Clusterer::cluster_centres`] instead.
    pub fn warm_start_from(&mut self, representatives: &[Contact]) {
        self.previous.clear();
        self.previous
            .extend(representatives.iter().map(|r| (r.p_a, r.depth_m)));
    }

    /// The centre (world, m) and mean depth (m) of each cluster of the last call, the history
    /// the next call warm-starts from. With one spring per cluster they are the
    /// representatives' `p_a` and `depth_m`; a torque pair's two springs sit either side of its
    /// cluster's centre. Empty after an empty input, a [`Clusterer::reset`] or an error.
    pub fn cluster_centres(&self) -> &[(Vec3, Real)] {
        &self.previous
    }

    /// Makes `centres` (as [`Clusterer::cluster_centres`] gives them) the history that the next
    /// call warm-starts from: [`Clusterer::warm_start_from`] for any kind of representative.
    pub fn warm_start_from_centres(&mut self, centres: &[(Vec3, Real)]) {
        self.previous.clear();
        self.previous.extend_from_slice(centres);
    }

    /// The cluster index of each contact of the last call.
    pub fn assignments(&self) -> &[u32] {
        &self.assign
    }

    /// The cost `E` (eq. 28) after each assignment of the last call (and after the final
    /// centroid update when the iteration cap was hit), when recording is on
    /// ([`Clusterer::record_costs`]); empty otherwise.
    pub fn cost_history(&self) -> &[Real] {
        &self.costs
    }

    /// Turns the per-iteration cost record on or off (off by default: it costs a pass over the
    /// contacts per iteration). For diagnostics and tests.
    pub fn record_costs(&mut self, on: bool) {
        self.record_costs = on;
        self.costs.clear();
    }

    /// Clusters `contacts` (queried with tolerance `delta_m`) into at most `K` representatives,
    /// written to `out` (cleared first). An empty input gives no representative and forgets the
    /// history.
    ///
    /// # Errors
    /// [`ClusterError::BadDelta`], [`ClusterError::NonFiniteContact`] or
    /// [`ClusterError::BadNormal`]; `out` is left empty and the history unchanged.
    pub fn cluster(
        &mut self,
        contacts: &[Contact],
        delta_m: Real,
        out: &mut ContactSet,
    ) -> Result<ClusterStats, ClusterError> {
        out.clear();
        self.costs.clear();
        self.representative_weights.clear();
        if !(delta_m.is_finite() && delta_m > 0.0) {
            return Err(ClusterError::BadDelta { delta_m });
        }
        let n = contacts.len();
        self.points.x.resize(n, 0.0);
        self.points.y.resize(n, 0.0);
        self.points.z.resize(n, 0.0);
        self.weights.resize(n, 0.0);
        // Validate and copy in one pass over the contacts.
        let mut with_areas = true;
        for (i, c) in contacts.iter().enumerate() {
            if !screen(c) {
                validate_one(i, c)?;
            }
            self.points.x[i] = c.p_a.x;
            self.points.y[i] = c.p_a.y;
            self.points.z[i] = c.p_a.z;
            self.weights[i] = weight(c.depth_m, delta_m);
            with_areas &= c.area_m2 > 0.0;
        }
        if with_areas {
            for (w, c) in self.weights.iter_mut().zip(contacts) {
                *w *= c.area_m2;
            }
        }
        self.assign.clear();
        if n == 0 {
            self.previous.clear();
            return Ok(ClusterStats::default());
        }
        self.assign.resize(n, 0);
        let k_max = self.params.max_clusters.min(n);
        self.dist.resize(n, 0.0);

        // Seeds (`seeding.rs`): warm at the old centroids; where a cluster then has no contact
        // (the contacts jumped), the paper's seeds at the contacts nearest the old centroids.
        let warm = self.params.warm_start && !self.previous.is_empty();
        self.seed(contacts, k_max, warm.then_some(Seeds::AtOldCentroids));
        self.scan(true);
        if warm && self.has_empty_cluster() {
            self.seed(contacts, k_max, Some(Seeds::AtNearestContacts));
            self.scan(true);
        }
        self.finish_pass();

        // Lloyd: assign to the closest centroid, then move centroids to the weighted means.
        let mut iterations = 0;
        let mut converged = false;
        while iterations < self.params.max_iterations {
            iterations += 1;
            self.update_centroids();
            if !self.reassign() {
                converged = true;
                break;
            }
        }
        if !converged {
            // The assignment changed in the last iteration: make the centroids its means, which
            // can only lower the cost further.
            self.update_centroids();
        }
        // The final cost comes out of the representatives' pass.
        let cost = self.write_representatives(contacts, delta_m, with_areas, out);
        if self.record_costs && !converged {
            self.costs.push(cost);
        }

        Ok(ClusterStats {
            clusters: self.previous.len(),
            iterations,
            converged,
            warm,
            cost,
        })
    }

    /// Assigns every contact to its closest centroid again after a centroid update (ties: lowest
    /// index) and drops clusters left empty; records the cost (eq. 28) when asked to. Returns
    /// whether any assignment changed.
    fn reassign(&mut self) -> bool {
        let changed = self.scan(false);
        self.finish_pass();
        changed
    }

    /// After an assignment pass: records the cost when asked to, and drops empty clusters.
    fn finish_pass(&mut self) {
        if self.record_costs {
            let cost = self.cost();
            self.costs.push(cost);
        }
        self.drop_empty();
    }

    /// One assignment pass. The first scans every contact against every centroid. Later passes
    /// use Hamerly's bounds: each contact keeps an upper bound on the distance to its own
    /// centroid and a lower bound on the distance to any other; centroid moves loosen them
    /// (triangle inequality) and only contacts whose bounds cross are scanned again. The result
    /// is exactly Lloyd's assignment. Returns whether any assignment changed (always `true`
    /// when `first`).
    fn scan(&mut self, first: bool) -> bool {
        let n = self.points.len();
        self.upper.resize(n, 0.0);
        self.lower.resize(n, 0.0);
        let (x, y, z) = (
            &self.points.x[..n],
            &self.points.y[..n],
            &self.points.z[..n],
        );
        let (assign, upper, lower) = (
            &mut self.assign[..n],
            &mut self.upper[..n],
            &mut self.lower[..n],
        );
        let centroids = &self.centroids[..];
        // Largest and second largest centroid moves since the last pass (none before the first).
        let (mut m1, mut k1, mut m2) = (0.0, usize::MAX, 0.0);
        let moves = if first { &[][..] } else { &self.moves[..] };
        for (k, &m) in moves.iter().enumerate() {
            if m > m1 {
                (m2, m1, k1) = (m1, m, k);
            } else if m > m2 {
                m2 = m;
            }
        }
        let mut changed = first;
        for i in 0..n {
            if !first {
                let a = assign[i] as usize;
                upper[i] += moves[a];
                lower[i] -= if a == k1 { m2 } else { m1 };
                if upper[i] < lower[i] {
                    continue;
                }
            }
            // The bounds cross (or the first pass): scan this contact against every centroid.
            let (px, py, pz) = (x[i], y[i], z[i]);
            let (mut d1, mut b1, mut d2) = (Real::INFINITY, 0u32, Real::INFINITY);
            for (k, c) in centroids.iter().enumerate() {
                let (dx, dy, dz) = (px - c.x, py - c.y, pz - c.z);
                let d = dx * dx + dy * dy + dz * dz;
                if d < d1 {
                    (d2, d1, b1) = (d1, d, k as u32);
                } else if d < d2 {
                    d2 = d;
                }
            }
            changed |= assign[i] != b1;
            assign[i] = b1;
            upper[i] = d1.sqrt();
            lower[i] = d2.sqrt();
        }
        changed
    }

    /// `count[j]`: how many contacts the assignment gives cluster `j`.
    fn count_members(&mut self) {
        self.count.clear();
        self.count.resize(self.centroids.len(), 0);
        for &a in &self.assign {
            self.count[a as usize] += 1;
        }
    }

    /// Removes clusters with no contact and renumbers the assignment.
    fn drop_empty(&mut self) {
        let k = self.centroids.len();
        self.count_members();
        if self.count.iter().all(|&c| c > 0) {
            return;
        }
        self.remap.clear();
        let mut next = 0;
        for j in 0..k {
            self.remap.push(next as u32);
            if self.count[j] > 0 {
                self.centroids[next] = self.centroids[j];
                next += 1;
            }
        }
        self.centroids.truncate(next);
        for a in &mut self.assign {
            *a = self.remap[*a as usize];
        }
    }

    /// Moves each centroid to the weighted mean of its contacts (eq. 29).
    fn update_centroids(&mut self) {
        let k = self.centroids.len();
        let n = self.points.len();
        self.sums.clear();
        self.sums.resize(k, [0.0; 4]);
        let (x, y, z) = (
            &self.points.x[..n],
            &self.points.y[..n],
            &self.points.z[..n],
        );
        let (w, assign) = (&self.weights[..n], &self.assign[..n]);
        for i in 0..n {
            let s = &mut self.sums[assign[i] as usize];
            s[0] += w[i] * x[i];
            s[1] += w[i] * y[i];
            s[2] += w[i] * z[i];
            s[3] += w[i];
        }
        self.moves.clear();
        for (c, s) in self.centroids.iter_mut().zip(&self.sums) {
            let mut moved = 0.0;
            if s[3] > 0.0 {
                let new = Vec3::new(s[0], s[1], s[2]) / s[3];
                moved = (new - *c).norm();
                *c = new;
            }
            self.moves.push(moved);
        }
    }

    /// `E = Σ w_i |p_i − c_k(i)|²` (eq. 28).
    fn cost(&self) -> Real {
        (0..self.points.len())
            .map(|i| {
                self.weights[i]
                    * (self.points.get(i) - self.centroids[self.assign[i] as usize]).norm_squared()
            })
            .sum()
    }
}

/// A cheap screen of a contact: the sum of all its fields is finite only if each is, and
/// `|n|² ≈ 1` (within about 1.9e-6, inside [`Contact::validate`]'s 1e-6 on `|n|`). `true` means
/// valid; `false` calls for [`validate_one`], which gives the precise error (or accepts).
#[inline]
fn screen(c: &Contact) -> bool {
    let sum = c.p_a.sum()
        + c.r_a.sum()
        + c.p_b.sum()
        + c.n.sum()
        + c.depth_m
        + c.area_m2
        + c.stiffness_share;
    sum.is_finite()
        && c.area_m2 >= 0.0
        && c.stiffness_share >= 0.0
        && (c.n.norm_squared() - 1.0).abs() <= 1.9e-6
}

/// [`Contact::validate`], with the error mapped to the clustering's and the contact's index.
fn validate_one(index: usize, c: &Contact) -> Result<(), ClusterError> {
    c.validate().map_err(|e| match e {
        CoreError::BadNormal { norm } => ClusterError::BadNormal { index, norm },
        CoreError::NonFinite { what } => ClusterError::NonFiniteContact { index, what },
        _ => ClusterError::NonFiniteContact {
            index,
            what: "field",
        },
    })
}

#[cfg(test)]
mod tests;
