//! Two wrenches of the collision bench's metric: the relative error between two wrenches, and
//! the penalty integrated over a contact set without clustering it.

use haptic_core::{Contact, Pose, Real, Vec3};

/// The penalty integrated over the contacts themselves, unclustered: `F = −Σ a g n` and
/// `T = Σ ρ × F_i` about the tool origin (`a` the area a contact stands for, `g = d + δ` its gap
/// weight, `ρ = R r_a`), with a unit stiffness per area, which cancels in the relative error.
/// What the contacts would push if every one were its own spring sharing the stiffness by area:
/// the back-end's own error, before the clustering's. `None` when a contact has no area (a
/// back-end that does not measure areas); an empty set gives zero.
pub(super) fn integrated_wrench(
    contacts: &[Contact],
    pose: &Pose,
    delta_m: Real,
) -> Option<[Real; 6]> {
    let (mut f, mut t) = (Vec3::zeros(), Vec3::zeros());
    for c in contacts {
        let fi = penalty_force(c, delta_m)?;
        f += fi;
        t += (pose.orientation * c.r_a).cross(&fi);
    }
    Some([f.x, f.y, f.z, t.x, t.y, t.z])
}

/// One contact's share of the integrated penalty, `−a g n` (unit stiffness per area); `None`
/// when it has no area.
fn penalty_force(c: &Contact, delta_m: Real) -> Option<Vec3> {
    (c.area_m2 > 0.0).then(|| -c.n * (c.area_m2 * c.gap_weight_m(delta_m)))
}

/// How many times the net force of the penalty integrated over the contacts themselves is
/// smaller than the forces that make it: `Σ |fᵢ| / |Σ fᵢ|` with `fᵢ = a g n` (as
/// [`integrated_wrench`]), at least 1. `None` when the net force is zero or a contact has no area.
///
/// Contacts whose own forces are each off by a fraction `e` (in depth or area, with no common
/// sign) move the net force by up to `e` times this: where it is large, as for a peg centred in
/// its hole or a bolt's threads loaded from both sides, the net force is a small residual of
/// large opposed forces and its relative error is that many times its contacts'.
pub(super) fn force_cancellation(contacts: &[Contact], delta_m: Real) -> Option<Real> {
    let (mut net, mut gross) = (Vec3::zeros(), 0.0);
    for c in contacts {
        let fi = penalty_force(c, delta_m)?;
        net += fi;
        gross += fi.norm();
    }
    let n = net.norm();
    (n > 0.0 && n.is_finite()).then(|| (gross / n).max(1.0))
}

/// Wrenches smaller than this fraction of a run's median reference wrench count as zero.
///
/// A back-end may write contacts whose force is at roundoff level: `LodBackend`'s coarse regions
/// grazing the outer edge of the penalty band (depth `−δ` to within a nanometre) push
/// 10⁻¹⁵–10⁻¹⁴ N where the regions push newtons, and its closest approach, a contact of
/// 10⁻¹⁸ m² that reports a distance, less. Where the reference has no contact, that is no error
/// a device could render; counted against a zero reference it would be an error of 1, as large as
/// missing every contact.
pub(super) const NEGLIGIBLE_WRENCH_REL: Real = 1e-9;

/// `|W − W₀| / |W₀|` with torques divided by `lever`; `None` when both wrenches are at most
/// `floor` (zero, or negligible: [`NEGLIGIBLE_WRENCH_REL`]), 1 when only the reference is.
pub(super) fn relative_error(
    w: &[Real; 6],
    w0: &[Real; 6],
    lever: Real,
    floor: Real,
) -> Option<Real> {
    let diff = scaled_norm(&std::array::from_fn(|i| w[i] - w0[i]), lever);
    let norm = scaled_norm(w0, lever);
    if norm > floor {
        Some(diff / norm)
    } else if diff > floor {
        Some(1.0)
    } else {
        None
    }
}

/// `|(F, T / lever)|`.
fn scaled_norm(w: &[Real; 6], lever: Real) -> Real {
    let scale = |i: usize| if i < 3 { 1.0 } else { 1.0 / lever };
    (0..6)
        .map(|i| (w[i] * scale(i)).powi(2))
        .sum::<Real>()
        .sqrt()
}

/// The error of each pose's wrench in `ws` against the same pose's in `w0s` (torques divided by
/// `lever`), skipping the poses where either has none or both are negligible: at most
/// [`NEGLIGIBLE_WRENCH_REL`] times the median of the reference's non-zero wrenches.
///
/// # Errors
/// When the two runs do not have the same number of poses, when there are no poses, or when
/// none could be compared (no contact at any pose, or contacts without areas): an error figure over
/// nothing would be a NaN in the report, not a measurement.
pub(super) fn pose_errors<'a>(
    ws: impl IntoIterator<Item = Option<&'a [Real; 6]>>,
    w0s: impl IntoIterator<Item = Option<&'a [Real; 6]>>,
    lever: Real,
) -> anyhow::Result<Vec<Real>> {
    let (mut ws, mut w0s) = (ws.into_iter(), w0s.into_iter());
    let mut pairs = Vec::new();
    loop {
        match (ws.next(), w0s.next()) {
            (Some(w), Some(w0)) => pairs.push(w.zip(w0)),
            (None, None) => break,
            _ => anyhow::bail!("a run and its reference have different numbers of poses"),
        }
    }
    let mut sizes: Vec<Real> = pairs
        .iter()
        .flatten()
        .map(|(_, w0)| scaled_norm(w0, lever))
        .filter(|n| *n > 0.0)
        .collect();
    sizes.sort_by(Real::total_cmp);
    let floor = sizes
        .get(sizes.len() / 2)
        .map_or(0.0, |m| NEGLIGIBLE_WRENCH_REL * m);
    let errors: Vec<Real> = pairs
        .iter()
        .flatten()
        .filter_map(|(w, w0)| relative_error(w, w0, lever, floor))
        .collect();
    anyhow::ensure!(!pairs.is_empty(), "no poses to compare");
    if errors.is_empty() {
        anyhow::bail!(
            "none of the {} poses has a wrench to compare with its reference (no contact at any pose, or contacts without areas)",
            pairs.len()
        );
    }
    Ok(errors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    /// A contact on a face of normal `n` (out of the tool), at body point `r_a`, `depth_m` deep,
    /// standing for `area_m2`, with the tool at `pose`.
    fn on_face(pose: &Pose, r_a: Vec3, n: Vec3, depth_m: Real, area_m2: Real) -> Contact {
        let p_a = pose.position + pose.orientation * r_a;
        Contact::new(p_a, r_a, p_a - n * depth_m, n, depth_m)
            .unwrap()
            .with_area(area_m2)
    }

    #[test]
    fn a_face_split_in_two_pushes_as_the_whole_face() {
        let pose = Pose {
            position: Vec3::new(0.1, -0.2, 0.3),
            orientation: UnitQuaternion::from_scaled_axis(Vec3::new(0.3, -0.1, 0.2)),
        };
        let n = Vec3::new(0.0, 0.0, -1.0);
        let (delta, depth) = (1e-3, 2e-4);
        // One contact at the face's centre for 4 cm², or two at the centres of its halves.
        let whole = [on_face(&pose, Vec3::new(0.0, 0.0, -0.01), n, depth, 4e-4)];
        let halves = [
            on_face(&pose, Vec3::new(-0.005, 0.0, -0.01), n, depth, 2e-4),
            on_face(&pose, Vec3::new(0.005, 0.0, -0.01), n, depth, 2e-4),
        ];
        let w = integrated_wrench(&whole, &pose, delta).unwrap();
        let h = integrated_wrench(&halves, &pose, delta).unwrap();
        assert!(
            relative_error(&h, &w, 0.05, 0.0).unwrap() < 1e-12,
            "{h:?} against {w:?}"
        );
        // It pushes the tool away from the obstacle: along −n, by area × (d + δ).
        assert!((w[2] - 4e-4 * (depth + delta)).abs() < 1e-18);
    }

    #[test]
    fn cancellation_is_one_for_aligned_forces_and_grows_as_they_oppose() {
        let pose = Pose::identity();
        let (delta, area) = (1e-3, 1e-4);
        let n = Vec3::new(0.0, 0.0, 1.0);
        let up = on_face(&pose, Vec3::new(0.0, 0.0, 0.01), n, 2e-4, area);
        let also_up = on_face(&pose, Vec3::new(0.01, 0.0, 0.01), n, 1e-4, area);
        let aligned = force_cancellation(&[up, also_up], delta).unwrap();
        assert!((aligned - 1.0).abs() < 1e-12, "{aligned}");
        // Two opposed faces, one pushed 10 % harder than the other: the net is a twenty-first
        // of the forces that make it.
        let down = on_face(&pose, Vec3::new(0.0, 0.0, -0.01), -n, 0.0, area);
        let harder = on_face(&pose, Vec3::new(0.0, 0.0, 0.01), n, 0.1 * delta, area);
        let opposed = force_cancellation(&[down, harder], delta).unwrap();
        assert!((opposed - 21.0).abs() < 1e-9, "{opposed}");
        // Exactly balanced: no net force to be relative to.
        let other = on_face(&pose, Vec3::new(0.0, 0.0, 0.01), n, 0.0, area);
        assert_eq!(force_cancellation(&[down, other], delta), None);
        assert_eq!(force_cancellation(&[], delta), None);
        assert_eq!(force_cancellation(&[down.with_area(0.0)], delta), None);
    }

    #[test]
    fn the_torque_is_about_the_tool_origin() {
        let pose = Pose::from_position(Vec3::new(0.0, 0.0, 1.0));
        let n = Vec3::new(1.0, 0.0, 0.0);
        let c = on_face(&pose, Vec3::new(0.0, 0.5, 0.0), n, 0.0, 1.0);
        let w = integrated_wrench(&[c], &pose, 1.0).unwrap();
        // F = (−1, 0, 0) at ρ = (0, 0.5, 0): T = ρ × F = (0, 0, 0.5).
        let expected = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.5];
        assert!(
            relative_error(&w, &expected, 1.0, 0.0).unwrap() < 1e-12,
            "{w:?}"
        );
    }

    #[test]
    fn contacts_without_an_area_have_no_integrated_wrench() {
        let pose = Pose::identity();
        let n = Vec3::new(0.0, 0.0, -1.0);
        let with = on_face(&pose, Vec3::zeros(), n, 0.0, 1e-4);
        let without = with.with_area(0.0);
        assert!(integrated_wrench(&[with, without], &pose, 1e-3).is_none());
        assert_eq!(integrated_wrench(&[], &pose, 1e-3), Some([0.0; 6]));
    }

    #[test]
    fn relative_error_scales_the_torque_by_the_lever() {
        let w0 = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let w = [1.0, 0.0, 0.0, 0.0, 0.0, 0.2];
        assert!((relative_error(&w, &w0, 2.0, 0.0).unwrap() - 0.1).abs() < 1e-15);
        assert_eq!(relative_error(&[0.0; 6], &[0.0; 6], 1.0, 0.0), None);
        assert_eq!(relative_error(&w, &[0.0; 6], 1.0, 0.0), Some(1.0));
        // Below the floor, a wrench is none; above it, against none, an error of 1.
        assert_eq!(relative_error(&w, &[0.0; 6], 1.0, 2.0), None);
        assert_eq!(relative_error(&w, &[0.0; 6], 1.0, 0.5), Some(1.0));
    }

    #[test]
    fn pose_errors_count_negligible_wrenches_as_none() {
        let big = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let tiny = [1e-14, 0.0, 0.0, 0.0, 0.0, 0.0];
        let (zero, half) = ([0.0; 6], [0.5, 0.0, 0.0, 0.0, 0.0, 0.0]);
        // A grazing region's 10⁻¹⁴ against no contact: skipped; a missed contact, or a
        // phantom of a visible size: 1.
        let ws = [Some(&big), Some(&tiny), Some(&zero), Some(&half)];
        let w0s = [Some(&big), Some(&zero), Some(&big), Some(&zero)];
        assert_eq!(pose_errors(ws, w0s, 1.0).unwrap(), vec![0.0, 1.0, 1.0]);
        // Negligible is relative to the run's median reference wrench, not absolute.
        let small = [1e-13, 0.0, 0.0, 0.0, 0.0, 0.0];
        let ws = [Some(&small), Some(&tiny)];
        let w0s = [Some(&small), Some(&zero)];
        assert_eq!(pose_errors(ws, w0s, 1.0).unwrap(), vec![0.0, 1.0]);
    }

    #[test]
    fn pose_errors_skip_poses_without_a_wrench() {
        let (a, b) = (
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        let zero = [0.0; 6];
        let ws = [Some(&a), None, Some(&zero), Some(&b)];
        let w0s = [Some(&b), Some(&b), Some(&zero), None];
        assert_eq!(pose_errors(ws, w0s, 1.0).unwrap(), vec![0.5]);
    }

    #[test]
    fn pose_errors_refuse_to_compare_nothing() {
        let (a, zero) = ([1.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0; 6]);
        // Every pose skipped: no contact anywhere, or no areas.
        let err = pose_errors([Some(&zero), None], [Some(&zero), Some(&a)], 1.0).unwrap_err();
        assert!(err.to_string().contains("none of the 2 poses"), "{err}");
        // Runs of different lengths.
        let err = pose_errors([Some(&a)], [Some(&a), Some(&a)], 1.0).unwrap_err();
        assert!(err.to_string().contains("numbers of poses"), "{err}");
        // No poses at all: nothing measured, not an empty list of errors.
        let err = pose_errors([], [], 1.0).unwrap_err();
        assert!(err.to_string().contains("no poses"), "{err}");
    }
}
