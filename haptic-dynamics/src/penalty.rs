//! The penalty contact model (eqs. 33–41): one viscoelastic planar constraint per contact (or
//! cluster representative), with pre-contact offset `δ`, and its analytic Jacobian.
//!
//! For a contact with body-frame point `r_a`, obstacle point `p_b` and unit normal `n` (out of
//! the tool), at tool state `y = (x, q, P, L)`:
//!
//! ```text
//! ρ   = R(q) r_a,       p_a = x + ρ,       v_a = v + ω × ρ
//! g   = n·(p_a − p_b) + δ                       (penetration plus pre-contact offset)
//! λ   = k_c g + b_c n·v_a                        (normal force magnitude)
//! F_k = −λ n = −k_c N (p_a − p_b + δ n) − b_c N v_a    while g > 0 and λ > 0, else 0   (eq. 33)
//! T_k = ρ × F_k
//! ```
//!
//! `N = n nᵀ`. The force never pulls: when damping would make `λ` negative (the tool leaving
//! the surface fast) the contact gives no force and no Jacobian (our choice, `formulation.md`).
//! Jacobians (eqs. 34–41): `∂F/∂y = −n ∂λ/∂y` with
//!
//! ```text
//! ∂λ/∂x   = k_c nᵀ
//! ∂λ/∂q_k = k_c n·(R_k r_a) + b_c [ (ρ × n)·∂ω/∂q_k + (n × ω)·(R_k r_a) ]
//! ∂λ/∂P   = (b_c/m) nᵀ
//! ∂λ/∂L   = b_c (ρ × n)ᵀ I_w⁻¹
//! ∂T/∂y   = [ρ]× ∂F/∂y − [F]× ∂ρ/∂y,     ∂ρ/∂q_k = R_k r_a
//! ```
//!
//! The contacts' `n`, `p_b` and `r_a` are constants within one evaluation. Each contact pushes
//! with its `stiffness_share` `s` of `k_c` and `b_c` (`k_c s`, `b_c s` above): 1 for a contact
//! as a back-end reports it, and for `K` clustered representatives shares that add up to at most
//! `K` (`haptic_cluster`), so the translational stiffness `‖∂F/∂x‖ ≤ K k_c` whatever the raw
//! contact count.

use haptic_core::contact_frame::{add_point_wrench_jacobian, normal_force_gradient};
use haptic_core::math::IX;
use haptic_core::{
    Contact, ContactModel, ContactModelError, CoreError, Kinematics, Real, RigidBody, StateVector,
    Vec3, Wrench, WrenchJacobian,
};

use crate::error::DynamicsError;
use haptic_core::check;

/// Parameters of the penalty model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyParams {
    /// Contact stiffness `k_c` (N/m) per contact.
    pub stiffness_n_per_m: Real,
    /// Contact damping `b_c` (N s/m) per contact.
    pub damping_ns_per_m: Real,
    /// Pre-contact offset `δ` (m): a contact pushes from `δ` before the surfaces touch. Use the
    /// same `δ` as the collision query's distance tolerance.
    pub delta_m: Real,
}

impl Default for PenaltyParams {
    /// `k_c = 2000 N/m`, `b_c = 2 N s/m`, `δ = 1 mm`: ten times the default coupling stiffness,
    /// so contact dominates the coupling as in the paper's experiments.
    fn default() -> Self {
        Self {
            stiffness_n_per_m: 2000.0,
            damping_ns_per_m: 2.0,
            delta_m: 1e-3,
        }
    }
}

impl PenaltyParams {
    /// Validated parameters.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::check`]) for a non-positive
    /// stiffness, a negative damping or a negative `δ`.
    pub fn new(
        stiffness_n_per_m: Real,
        damping_ns_per_m: Real,
        delta_m: Real,
    ) -> Result<Self, DynamicsError> {
        let p = Self {
            stiffness_n_per_m,
            damping_ns_per_m,
            delta_m,
        };
        p.validate()?;
        Ok(p)
    }

    /// Checks the ranges (see [`PenaltyParams::new`]).
    ///
    /// # Errors
    /// As [`PenaltyParams::new`].
    pub fn validate(&self) -> Result<(), DynamicsError> {
        check::positive("penalty.stiffness_n_per_m", self.stiffness_n_per_m)?;
        check::non_negative("penalty.damping_ns_per_m", self.damping_ns_per_m)?;
        check::non_negative("penalty.delta_m", self.delta_m)?;
        Ok(())
    }
}

/// The penalty contact model (eq. 33) behind [`ContactModel`]. Stateless apart from its
/// parameters; evaluating it allocates nothing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyModel {
    params: PenaltyParams,
}

impl PenaltyModel {
    /// A model with validated parameters.
    ///
    /// # Errors
    /// As [`PenaltyParams::validate`].
    pub fn new(params: PenaltyParams) -> Result<Self, DynamicsError> {
        params.validate()?;
        Ok(Self { params })
    }

    /// The parameters.
    pub fn params(&self) -> &PenaltyParams {
        &self.params
    }
}

/// Maps a contact's validation error to the contact model's, with its index.
fn contact_error(index: usize, e: CoreError) -> ContactModelError {
    match e {
        CoreError::BadNormal { norm } => ContactModelError::BadNormal { index, norm },
        CoreError::NonFinite { what } => ContactModelError::NonFiniteContact { index, what },
        other => ContactModelError::Parameter(other),
    }
}

impl ContactModel for PenaltyModel {
    fn evaluate(
        &mut self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        contacts: &[Contact],
        mut jacobian: Option<&mut WrenchJacobian>,
    ) -> Result<Wrench, ContactModelError> {
        if y.iter().any(|v| !v.is_finite()) {
            return Err(ContactModelError::NonFiniteState);
        }
        let (k_c, b_c, delta) = (
            self.params.stiffness_n_per_m,
            self.params.damping_ns_per_m,
            self.params.delta_m,
        );
        let x: Vec3 = y.fixed_rows::<3>(IX).into_owned();
        let inv_m = 1.0 / body.mass_kg();
        let mut force = Vec3::zeros();
        let mut torque = Vec3::zeros();
        if let Some(j) = jacobian.as_deref_mut() {
            j.fill(0.0);
        }
        for (index, c) in contacts.iter().enumerate() {
            c.validate().map_err(|e| contact_error(index, e))?;
            // A representative pushes with its share of k_c and b_c (haptic-cluster); 1 for a
            // contact as a back-end reports it.
            let (k_c, b_c) = (k_c * c.stiffness_share, b_c * c.stiffness_share);
            if k_c <= 0.0 {
                continue; // a zero share: no force
            }
            let n = c.n;
            let rho = kin.r * c.r_a; // ρ = R r_a
            let p_a = x + rho;
            let g = n.dot(&(p_a - c.p_b)) + delta;
            if g <= 0.0 {
                continue; // farther than δ: no constraint
            }
            let v_a = kin.v + kin.omega.cross(&rho);
            let lambda = k_c * g + b_c * n.dot(&v_a);
            if lambda <= 0.0 {
                continue; // the force never pulls
            }
            let f = -lambda * n; // eq. 33
            force += f;
            torque += rho.cross(&f);
            let Some(jac) = jacobian.as_deref_mut() else {
                continue;
            };
            // ∂λ/∂y (1×13), eqs. 34–37; ∂F/∂y = −n ∂λ/∂y and ∂T/∂y (eqs. 38–41).
            let dl = normal_force_gradient(kin, &c.r_a, &rho, &n, k_c, b_c, inv_m);
            let df = -n * dl;
            add_point_wrench_jacobian(kin, &c.r_a, &rho, &f, &df, jac);
        }
        Ok(Wrench::new(force, torque))
    }

    /// `δ`: a contact reported at `y₀` is at most `δ` from touching, and the query looked no
    /// farther, so its tangent is trusted up to `δ` deeper.
    fn extrapolation_reach_m(&self) -> Real {
        self.params.delta_m
    }
}

#[cfg(test)]
mod tests;
