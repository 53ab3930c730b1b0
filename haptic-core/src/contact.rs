//! Contacts between the tool and the obstacles, and a reusable buffer of them.

use crate::error::CoreError;
use crate::math::{Real, Vec3};

/// Tolerance on `| |n| - 1 |` for a contact normal.
pub const UNIT_NORMAL_TOL: Real = 1e-6;

/// Marks a contact feature (triangle, node) that is not known.
pub const NO_FEATURE: u32 = u32::MAX;

/// One contact between the tool (`a`) and an obstacle (`b`) (Section VI-A).
///
/// - `p_a`: the point on the tool, world frame (m); `r_a = Rᵀ (p_a − x)` is the same point in the
///   tool's body frame, so the contact can be re-evaluated at nearby tool states.
/// - `p_b`: the point on the obstacle, world frame (m).
/// - `n`: unit normal pointing **out of the tool**, towards the obstacle.
/// - `depth_m`: positive when `p_a` is inside the obstacle, negative (down to `−δ`) when the two
///   are apart but closer than the distance tolerance `δ`.
/// - `feature_a`, `feature_b`: the triangle (or hierarchy node) on each side that produced the
///   contact, or [`NO_FEATURE`].
/// - `area_m2`: the area of the tool's surface this contact stands for (m²), so that a flat
///   face weighs the same however finely it is tessellated; 0 when the back-end does not
///   measure it (see [`Contact::with_area`]). Clustering weighs contacts by it.
/// - `stiffness_share`: the share of the contact model's stiffness and damping this contact
///   pushes with (dimensionless, ≥ 0): 1 for a contact as a back-end reports it. A clustered
///   representative carries its cluster's share of the `K` clusters' stiffness (`K` asked
///   for however many are written, where the contacts carry areas), in proportion to the
///   penalty its contacts make (`haptic_cluster`), so that the clustered penalty depends
///   neither on where the clusters' boundaries fall nor on how many contacts a surface gave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Point on the tool, world frame, m.
    pub p_a: Vec3,
    /// Point on the tool, tool body frame, m.
    pub r_a: Vec3,
    /// Point on the obstacle, world frame, m.
    pub p_b: Vec3,
    /// Unit normal out of the tool.
    pub n: Vec3,
    /// Penetration depth, m (negative: separation).
    pub depth_m: Real,
    /// Tool feature index, or [`NO_FEATURE`].
    pub feature_a: u32,
    /// Obstacle feature index, or [`NO_FEATURE`].
    pub feature_b: u32,
    /// Area of the tool's surface the contact stands for (m²), 0 when not measured.
    pub area_m2: Real,
    /// Share of the contact model's stiffness and damping this contact pushes with (≥ 0); 1 for
    /// a contact as a back-end reports it.
    pub stiffness_share: Real,
}

impl Contact {
    /// A validated contact without feature indices.
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] for NaN or Inf in any field, [`CoreError::BadNormal`] if `n` is
    /// not unit within 1e-6.
    pub fn new(p_a: Vec3, r_a: Vec3, p_b: Vec3, n: Vec3, depth_m: Real) -> Result<Self, CoreError> {
        let c = Self {
            p_a,
            r_a,
            p_b,
            n,
            depth_m,
            feature_a: NO_FEATURE,
            feature_b: NO_FEATURE,
            area_m2: 0.0,
            stiffness_share: 1.0,
        };
        c.validate()?;
        Ok(c)
    }

    /// The same contact tagged with the features that produced it.
    pub fn with_features(mut self, feature_a: u32, feature_b: u32) -> Self {
        self.feature_a = feature_a;
        self.feature_b = feature_b;
        self
    }

    /// The same contact standing for `area_m2` of the tool's surface (m²). The area is not
    /// checked here; [`Contact::validate`] refuses a negative or non-finite one.
    pub fn with_area(mut self, area_m2: Real) -> Self {
        self.area_m2 = area_m2;
        self
    }

    /// The same contact pushing with `share` of the contact model's stiffness and damping (see
    /// the type's docs). Not checked here; [`Contact::validate`] refuses a negative or
    /// non-finite share.
    pub fn with_stiffness_share(mut self, share: Real) -> Self {
        self.stiffness_share = share;
        self
    }

    /// The gap `g = d + δ` that weighs this contact in clustering (eq. 28's weights, with its
    /// area), floored at `10⁻³ δ` so that a contact at exactly `−δ` keeps a small positive
    /// weight. See [`gap_weight_m`].
    #[inline]
    pub fn gap_weight_m(&self, delta_m: Real) -> Real {
        gap_weight_m(self.depth_m, delta_m)
    }

    /// Checks finiteness, the unit normal, a non-negative area and a non-negative stiffness share.
    ///
    /// # Errors
    /// As [`Contact::new`], and [`CoreError::NonFinite`] (`"contact area"`, `"contact stiffness
    /// share"`) for an area or a share that is negative, NaN or infinite.
    pub fn validate(&self) -> Result<(), CoreError> {
        let finite = |v: &Vec3| v.iter().all(|c| c.is_finite());
        if !finite(&self.p_a) {
            return Err(CoreError::NonFinite {
                what: "contact p_a",
            });
        }
        if !finite(&self.r_a) {
            return Err(CoreError::NonFinite {
                what: "contact r_a",
            });
        }
        if !finite(&self.p_b) {
            return Err(CoreError::NonFinite {
                what: "contact p_b",
            });
        }
        if !finite(&self.n) {
            return Err(CoreError::NonFinite {
                what: "contact normal",
            });
        }
        if !self.depth_m.is_finite() {
            return Err(CoreError::NonFinite {
                what: "contact depth",
            });
        }
        if !(self.area_m2.is_finite() && self.area_m2 >= 0.0) {
            return Err(CoreError::NonFinite {
                what: "contact area",
            });
        }
        if !(self.stiffness_share.is_finite() && self.stiffness_share >= 0.0) {
            return Err(CoreError::NonFinite {
                what: "contact stiffness share",
            });
        }
        let norm = self.n.norm();
        if (norm - 1.0).abs() > UNIT_NORMAL_TOL {
            return Err(CoreError::BadNormal { norm });
        }
        Ok(())
    }
}

/// The gap `g = d + δ` (m) of a contact of depth `depth_m` under the tolerance `delta_m`,
/// floored at `10⁻³ δ`: the depth term of the clustering's weights (eq. 28), and how
/// `haptic-collision` shares a surface's area among the contacts that stand for it. One
/// definition, so that both agree.
#[inline]
pub fn gap_weight_m(depth_m: Real, delta_m: Real) -> Real {
    (depth_m + delta_m).max(1e-3 * delta_m)
}

/// A reusable buffer of contacts, filled by a [`crate::CollisionBackend`].
///
/// `clear` keeps the allocation, so after warm-up a query that returns no more contacts than
/// before allocates nothing.
#[derive(Debug, Clone, Default)]
pub struct ContactSet {
    contacts: Vec<Contact>,
}

impl ContactSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty set with room for `capacity` contacts.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            contacts: Vec::with_capacity(capacity),
        }
    }

    /// Removes every contact, keeping the allocation.
    #[inline]
    pub fn clear(&mut self) {
        self.contacts.clear();
    }

    /// Appends a contact.
    #[inline]
    pub fn push(&mut self, contact: Contact) {
        self.contacts.push(contact);
    }

    /// Keeps the contacts for which `keep` returns true, in their order; `keep` sees every
    /// contact once, in order (so it may count them). Keeps the allocation.
    pub fn retain(&mut self, keep: impl FnMut(&Contact) -> bool) {
        self.contacts.retain(keep);
    }

    /// The contacts.
    #[inline]
    pub fn as_slice(&self) -> &[Contact] {
        &self.contacts
    }

    /// The contacts, mutably.
    #[inline]
    pub fn as_mut_slice(&mut self) -> &mut [Contact] {
        &mut self.contacts
    }

    /// Number of contacts.
    #[inline]
    pub fn len(&self) -> usize {
        self.contacts.len()
    }

    /// Whether there is no contact.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.contacts.is_empty()
    }

    /// Allocated room.
    pub fn capacity(&self) -> usize {
        self.contacts.capacity()
    }

    /// Iterates over the contacts.
    pub fn iter(&self) -> std::slice::Iter<'_, Contact> {
        self.contacts.iter()
    }

    /// Largest depth (m), or `None` when empty.
    pub fn max_depth_m(&self) -> Option<Real> {
        self.contacts.iter().map(|c| c.depth_m).reduce(Real::max)
    }
}

impl<'a> IntoIterator for &'a ContactSet {
    type Item = &'a Contact;
    type IntoIter = std::slice::Iter<'a, Contact>;
    fn into_iter(self) -> Self::IntoIter {
        self.contacts.iter()
    }
}

impl Extend<Contact> for ContactSet {
    fn extend<T: IntoIterator<Item = Contact>>(&mut self, iter: T) {
        self.contacts.extend(iter);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok() -> Contact {
        Contact::new(Vec3::zeros(), Vec3::zeros(), Vec3::zeros(), Vec3::z(), 1e-4).unwrap()
    }

    #[test]
    fn retain_keeps_the_chosen_contacts_in_order_and_the_allocation() {
        let mut set = ContactSet::with_capacity(8);
        for k in 0..5 {
            set.push(ok().with_area(Real::from(k)));
        }
        let mut i = 0;
        set.retain(|_| {
            i += 1;
            i % 2 == 1
        });
        let areas: Vec<Real> = set.iter().map(|c| c.area_m2).collect();
        assert_eq!(areas, [0.0, 2.0, 4.0]);
        assert_eq!(set.capacity(), 8);
    }

    #[test]
    fn contact_rejects_bad_input() {
        let z = Vec3::zeros();
        let nan = Vec3::new(Real::NAN, 0.0, 0.0);
        assert!(matches!(
            Contact::new(nan, z, z, Vec3::z(), 0.0),
            Err(CoreError::NonFinite {
                what: "contact p_a"
            })
        ));
        assert!(matches!(
            Contact::new(z, nan, z, Vec3::z(), 0.0),
            Err(CoreError::NonFinite {
                what: "contact r_a"
            })
        ));
        assert!(matches!(
            Contact::new(z, z, nan, Vec3::z(), 0.0),
            Err(CoreError::NonFinite {
                what: "contact p_b"
            })
        ));
        assert!(matches!(
            Contact::new(z, z, z, nan, 0.0),
            Err(CoreError::NonFinite {
                what: "contact normal"
            })
        ));
        assert!(matches!(
            Contact::new(z, z, z, Vec3::z(), Real::INFINITY),
            Err(CoreError::NonFinite {
                what: "contact depth"
            })
        ));
        assert!(matches!(
            Contact::new(z, z, z, z, 0.0),
            Err(CoreError::BadNormal { .. })
        ));
        for area in [-1e-9, Real::NAN, Real::INFINITY] {
            let c = Contact::new(z, z, z, Vec3::z(), 0.0)
                .unwrap()
                .with_area(area);
            assert!(matches!(
                c.validate(),
                Err(CoreError::NonFinite {
                    what: "contact area"
                })
            ));
        }
        assert!(ok().with_area(2e-6).validate().is_ok());
        for share in [-1e-9, Real::NAN, Real::INFINITY] {
            assert!(matches!(
                ok().with_stiffness_share(share).validate(),
                Err(CoreError::NonFinite {
                    what: "contact stiffness share"
                })
            ));
        }
        assert_eq!(ok().stiffness_share, 1.0);
        assert!(ok().with_stiffness_share(0.0).validate().is_ok());
        assert!(matches!(
            Contact::new(z, z, z, Vec3::new(0.0, 0.0, 2.0), 0.0),
            Err(CoreError::BadNormal { .. })
        ));
    }

    #[test]
    fn contact_set_reuses_its_allocation() {
        let mut set = ContactSet::with_capacity(4);
        for _ in 0..4 {
            set.push(ok());
        }
        let cap = set.capacity();
        set.clear();
        assert!(set.is_empty());
        set.extend(std::iter::repeat_n(ok(), 4));
        assert_eq!(set.capacity(), cap);
        assert_eq!(set.max_depth_m(), Some(1e-4));
    }
}
