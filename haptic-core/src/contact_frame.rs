//! A contact as a viscoelastic point-on-plane spring with its frame held fixed: the normal force
//! `λ` of one contact and its derivative `∂λ/∂y` (paper eqs. 33–37), and the torque Jacobian of
//! a force applied at a point of the tool (eqs. 38–41).
//!
//! The penalty model evaluates every contact this way on the contact thread; the haptic thread
//! does the same with the representatives' frames from the last update in
//! [`crate::LinearizationMode::FixedFrames`], so the two share one implementation.

use crate::math::{IL, IP, IQ, IX, skew};
use crate::state::Kinematics;
use crate::{Real, StateVector, Vec3, WrenchJacobian};
use nalgebra::{RowSVector, SMatrix};

/// `∂λ/∂y` (1×13) of the normal force `λ = k g + b n·v_a` of a point `r_a` of the tool (body
/// frame, `ρ = R r_a` in the world) pressed along the fixed normal `n`, with `∂g/∂x = nᵀ`
/// (eqs. 34–37):
///
/// ```text
/// ∂λ/∂x   = k nᵀ
/// ∂λ/∂q_k = k n·(R_k r_a) + b [ (ρ × n)·∂ω/∂q_k + (n × ω)·(R_k r_a) ]
/// ∂λ/∂P   = (b/m) nᵀ
/// ∂λ/∂L   = b (ρ × n)ᵀ I_w⁻¹
/// ```
///
/// `inv_mass_per_kg` is `1/m`.
pub fn normal_force_gradient(
    kin: &Kinematics,
    r_a: &Vec3,
    rho: &Vec3,
    n: &Vec3,
    stiffness_n_per_m: Real,
    damping_ns_per_m: Real,
    inv_mass_per_kg: Real,
) -> RowSVector<Real, 13> {
    let (k, b) = (stiffness_n_per_m, damping_ns_per_m);
    let rho_x_n = rho.cross(n);
    let n_x_omega = n.cross(&kin.omega);
    let mut dl = RowSVector::<Real, 13>::zeros();
    for q in 0..4 {
        let drho = kin.r_partials[q] * r_a;
        let domega = kin.omega_q.column(q);
        dl[IQ + q] = k * n.dot(&drho) + b * (rho_x_n.dot(&domega) + n_x_omega.dot(&drho));
    }
    for a in 0..3 {
        dl[IX + a] = k * n[a];
        dl[IP + a] = b * inv_mass_per_kg * n[a];
    }
    let dl_dl = (kin.inertia_world_inv.transpose() * rho_x_n) * b;
    for a in 0..3 {
        dl[IL + a] = dl_dl[a];
    }
    dl
}

/// Adds the Jacobian of the wrench `(F, ρ × F)` of a force `F` applied at the tool's point
/// `r_a` (`ρ = R r_a`) into `jacobian`, given `∂F/∂y` (eqs. 38–41):
/// `∂T/∂y = [ρ]× ∂F/∂y − [F]× ∂ρ/∂y`, with `∂ρ/∂q_k = R_k r_a`.
pub fn add_point_wrench_jacobian(
    kin: &Kinematics,
    r_a: &Vec3,
    rho: &Vec3,
    force: &Vec3,
    dforce_dy: &SMatrix<Real, 3, 13>,
    jacobian: &mut WrenchJacobian,
) {
    let mut dt = skew(rho) * dforce_dy;
    let f_x = skew(force);
    for q in 0..4 {
        let dt_q = f_x * (kin.r_partials[q] * r_a);
        for a in 0..3 {
            dt[(a, IQ + q)] -= dt_q[a];
        }
    }
    let mut top = jacobian.fixed_rows_mut::<3>(0);
    top += dforce_dy;
    let mut bottom = jacobian.fixed_rows_mut::<3>(3);
    bottom += dt;
}

/// How far below its cap a yielding contact lands, relative to the cap
/// ([`FixedFrame::yield_to`]): far above the rounding of the normal force, far below anything a
/// hand feels.
pub const YIELD_MARGIN: Real = 1e-9;

/// One contact's frame from the last collision update, held fixed on the haptic thread: the
/// tool's point `r_a`, the normal `n`, and the normal stiffness and damping the contact had at
/// `y₀` (see [`crate::LinearizationMode::FixedFrames`]).
///
/// At a tool state `y` the contact is the spring-damper
///
/// ```text
/// ρ = R(q) r_a,   p_a = x + ρ,   v_a = v + ω × ρ
/// λ(y) = λ_e0 + k_n n·(p_a − p_a0) + b_n n·v_a
/// ```
///
/// whose elastic part depends on the point's position alone: pressed along a fixed plane it is
/// conservative, so a stale frame cannot give the tool energy however far the tool has turned
/// (a stale tangent can, see `docs/stability.md`). For the penalty model (eq. 33) `λ(y)` is
/// exactly its normal force on the contact held fixed. [`FixedFrame::yield_to`] moves the
/// anchor `λ_e0` (once per haptic step, never within one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedFrame {
    /// The contact point on the tool, body frame (m).
    pub r_a: Vec3,
    /// The contact normal (unit, out of the tool).
    pub n: Vec3,
    /// The contact point on the tool at `y₀`, world frame (m).
    pub p_a0_m: Vec3,
    /// The elastic part of the normal force at `y₀`, `λ₀ − b_n n·v_a(y₀)` (N).
    pub elastic_force0_n: Real,
    /// Normal stiffness `k_n = ∂λ/∂x · n` at `y₀` (N/m).
    pub stiffness_n_per_m: Real,
    /// Normal damping `b_n = m ∂λ/∂P · n` at `y₀` (N s/m).
    pub damping_ns_per_m: Real,
    /// `1/m` of the tool (1/kg).
    pub inv_mass_per_kg: Real,
}

impl FixedFrame {
    /// The frame of a contact at `r_a` (body frame) with normal `n`, whose normal force at `y0`
    /// (kinematics `kin0`) is `lambda0_n` with gradient `dlambda_dy`; `None` when a derived
    /// coefficient is not finite.
    pub fn new(
        y0: &StateVector,
        kin0: &Kinematics,
        mass_kg: Real,
        r_a: Vec3,
        n: Vec3,
        lambda0_n: Real,
        dlambda_dy: &RowSVector<Real, 13>,
    ) -> Option<Self> {
        let x0: Vec3 = y0.fixed_rows::<3>(IX).into_owned();
        let rho0 = kin0.r * r_a;
        let stiffness = (dlambda_dy.fixed_columns::<3>(IX) * n)[0].max(0.0);
        let damping = mass_kg * (dlambda_dy.fixed_columns::<3>(IP) * n)[0].max(0.0);
        let v_a0 = kin0.v + kin0.omega.cross(&rho0);
        let frame = Self {
            r_a,
            n,
            p_a0_m: x0 + rho0,
            elastic_force0_n: lambda0_n - damping * n.dot(&v_a0),
            stiffness_n_per_m: stiffness,
            damping_ns_per_m: damping,
            inv_mass_per_kg: 1.0 / mass_kg,
        };
        let finite = [
            frame.elastic_force0_n,
            frame.stiffness_n_per_m,
            frame.damping_ns_per_m,
            frame.inv_mass_per_kg,
        ]
        .iter()
        .chain(frame.p_a0_m.iter())
        .all(|v| v.is_finite());
        finite.then_some(frame)
    }

    /// `ρ = R r_a` and the elastic part of the normal force, `λ_e(y) = λ_e0 + k_n n·(p_a − p_a0)`
    /// (N, unbounded: it may be negative).
    #[inline]
    pub fn elastic_force(&self, y: &StateVector, kin: &Kinematics) -> (Vec3, Real) {
        let x: Vec3 = y.fixed_rows::<3>(IX).into_owned();
        let rho = kin.r * self.r_a;
        let lambda_e =
            self.elastic_force0_n + self.stiffness_n_per_m * self.n.dot(&(x + rho - self.p_a0_m));
        (rho, lambda_e)
    }

    /// `ρ = R r_a` and the normal force `λ(y) = λ_e(y) + b_n n·v_a` (N, unbounded: it may be
    /// negative).
    #[inline]
    pub fn normal_force(&self, y: &StateVector, kin: &Kinematics) -> (Vec3, Real) {
        let (rho, lambda_e) = self.elastic_force(y, kin);
        let v_a = kin.v + kin.omega.cross(&rho);
        (rho, lambda_e + self.damping_ns_per_m * self.n.dot(&v_a))
    }

    /// Moves the frame's anchor so that its normal force at `y` is at most `max_n`: pressed
    /// beyond that, the contact yields like a plastic stop rather than storing the excess as a
    /// spring would. Returns whether it yielded.
    ///
    /// It lands just below the cap (by [`YIELD_MARGIN`] of it), never on it: the bounded force
    /// has a kink at the cap, with the spring's slope below it and none above, so at the cap
    /// itself the rounding of `λ(y)` would decide whether the implicit step that starts there
    /// sees the contact's stiffness and damping. Without them the capped force acts explicitly,
    /// and at a lever of centimetres it spun a 0.7 g spoon from 80 to 5,000 rad/s in one step
    /// (`docs/stability.md`).
    #[inline]
    pub fn yield_to(&mut self, y: &StateVector, kin: &Kinematics, max_n: Real) -> bool {
        let (_, lambda) = self.normal_force(y, kin);
        if lambda <= max_n {
            return false;
        }
        let mut margin = YIELD_MARGIN * max_n.abs();
        let mut excess = lambda - max_n;
        // Where the margin is below the rounding of `λ(y)` (a cap of micronewtons), widen it
        // until the force is at or below the cap.
        for _ in 0..8 {
            self.elastic_force0_n -= excess + margin;
            let (_, after) = self.normal_force(y, kin);
            if after <= max_n {
                break;
            }
            excess = after - max_n;
            margin = (2.0 * margin).max(Real::EPSILON * lambda.abs());
        }
        true
    }

    /// `∂λ/∂y` at `y` (kinematics `kin`, `ρ = R r_a`).
    #[inline]
    pub fn normal_force_gradient(&self, kin: &Kinematics, rho: &Vec3) -> RowSVector<Real, 13> {
        normal_force_gradient(
            kin,
            &self.r_a,
            rho,
            &self.n,
            self.stiffness_n_per_m,
            self.damping_ns_per_m,
            self.inv_mass_per_kg,
        )
    }
}
