//! The area a contact stands for (`Contact::area_m2`), for the contacts of triangle pairs.
//!
//! A triangle-pair contact stands for the tool triangle it came from. A tool triangle within
//! `δ` of several obstacle triangles (a tool face over a finely tessellated floor) gives one
//! contact per pair, so its area is split among them in proportion to their gaps
//! `g = d + δ` (floored at `10⁻³ δ`, as the clustering floors its weights): the contacts of one
//! triangle always add up to its area, a flat face weighs the same however either side is
//! tessellated, and a pair that comes within `δ` (at `g = 0`) takes its share gradually. (An
//! even split halved the other contacts' areas at once when a second pair came within `δ`:
//! the spoon pressed into the cup chattered at 30 Hz.) Back-ends write the whole triangle's
//! area into each contact, tagged with the triangle (`feature_a`); [`AreaSplit::split`] then
//! shares it.
//!
//! Used by [`crate::parry::ParryBackend`]; `LodBackend` and the reference write each contact
//! with the area of its region instead (`crate::slab`).

use haptic_core::{Contact, NO_FEATURE, Real, Vec3};

/// Area of a triangle (m² for vertices in m).
#[inline]
pub(crate) fn triangle_area(t: &[Vec3; 3]) -> Real {
    0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm()
}

/// Sums of the gaps `g = d + δ` of each tool triangle's contacts, reused between queries (see
/// the module docs).
#[derive(Debug, Clone, Default)]
pub(crate) struct AreaSplit {
    gap_sum: Vec<Real>,
}

impl AreaSplit {
    /// Room for a tool of `triangles` triangles (allocated once, so a query allocates nothing).
    pub fn new(triangles: usize) -> Self {
        Self {
            gap_sum: vec![0.0; triangles],
        }
    }

    /// Shares the area of each contact tagged with a tool triangle among that triangle's
    /// contacts, in proportion to their gaps `d + δ` (`delta_m` the query's δ). Contacts
    /// without a triangle ([`NO_FEATURE`]) keep theirs.
    pub fn split(&mut self, contacts: &mut [Contact], delta_m: Real) {
        let gap = |c: &Contact| c.gap_weight_m(delta_m);
        for c in contacts.iter() {
            if let Some(s) = self.slot(c.feature_a) {
                *s += gap(c);
            }
        }
        for c in contacts.iter_mut() {
            let g = gap(c);
            if let Some(s) = self.slot(c.feature_a)
                && *s > g
            {
                c.area_m2 *= g / *s;
            }
        }
        // Reset only what was touched.
        for c in contacts.iter() {
            if let Some(s) = self.slot(c.feature_a) {
                *s = 0.0;
            }
        }
    }

    #[inline]
    fn slot(&mut self, feature: u32) -> Option<&mut Real> {
        if feature == NO_FEATURE {
            None
        } else {
            self.gap_sum.get_mut(feature as usize)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DELTA: Real = 1.0;

    /// A contact of tool triangle `feature_a` with gap `g = d + δ`.
    fn contact(feature_a: u32, area: Real, g: Real) -> Contact {
        let z = Vec3::zeros();
        Contact::new(z, z, z, Vec3::z(), g - DELTA)
            .unwrap()
            .with_features(feature_a, 0)
            .with_area(area)
    }

    #[test]
    fn each_triangle_area_is_shared_by_its_contacts_by_gap() {
        let mut split = AreaSplit::new(3);
        let mut cs = vec![
            contact(0, 6.0, 1.0),
            contact(1, 2.0, 0.5),
            contact(0, 6.0, 2.0),
            contact(NO_FEATURE, 5.0, 1.0),
            contact(0, 6.0, 3.0),
            contact(7, 4.0, 1.0), // out of range: kept as is
        ];
        split.split(&mut cs, DELTA);
        let areas: Vec<Real> = cs.iter().map(|c| c.area_m2).collect();
        assert_eq!(areas, vec![1.0, 2.0, 2.0, 5.0, 3.0, 4.0]);
        // The sums were reset: a second query starts from zero.
        let mut again = vec![contact(0, 6.0, 1.0)];
        split.split(&mut again, DELTA);
        assert_eq!(again[0].area_m2, 6.0);
    }

    #[test]
    fn a_pair_coming_within_reach_takes_its_share_gradually() {
        // A second contact of the same triangle appears at the edge of δ: the first keeps
        // almost all of the area (an even split would halve it at once).
        let mut split = AreaSplit::new(1);
        let mut cs = vec![contact(0, 6.0, 1.0), contact(0, 6.0, 1e-9)];
        split.split(&mut cs, DELTA);
        assert!(cs[0].area_m2 > 5.99 && cs[1].area_m2 < 0.01);
        assert!((cs[0].area_m2 + cs[1].area_m2 - 6.0).abs() < 1e-12);
    }

    #[test]
    fn triangle_area_is_half_the_cross_product() {
        let t = [
            Vec3::zeros(),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 3.0, 0.0),
        ];
        assert_eq!(triangle_area(&t), 3.0);
    }
}
