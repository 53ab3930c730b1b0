//! The four integrators of the 13-state tool, behind [`haptic_core::Integrator`]: forward Euler,
//! classic RK4, semi-implicit backward Euler (the paper's method, eqs. 4–5) and full-Newton
//! backward Euler (its accuracy reference).
//!
//! All of them validate the step and the state before evaluating anything, check every wrench
//! (and Jacobian) the force model returns, renormalise the quaternion of the new state, return
//! an [`IntegrationError`] instead of a non-finite state, and allocate nothing: every matrix is
//! fixed-size on the stack. The explicit ones never ask for a Jacobian.
//!
//! Time: explicit methods evaluate the force model at their stage times (`t`, `t + h/2`, `t + h`);
//! both backward Eulers evaluate it at the end of the step, `t + h`, as `y₁ = y₀ + h f(t + h, y₁)`
//! requires. The haptic loop holds the device reading constant over a step, so there the time
//! argument does not matter.

use std::fmt;
use std::str::FromStr;

use haptic_core::math::{IL, IP, IQ, IX, all_finite};
use haptic_core::{
    ForceModel, IntegrationError, Integrator, JacobianKind, Kinematics, Real, RigidBody,
    StateVector, SystemJacobian, ToolState, WrenchJacobian,
};

use crate::eom::{quaternion_jacobian_blocks, state_derivative, system_jacobian};
use crate::error::DynamicsError;
use haptic_core::check;

/// Pivots of the LU factorisation smaller than this fraction of the largest one mean that
/// `I - h J` is singular to working precision.
pub const SINGULAR_PIVOT_RATIO: Real = 1e-13;

fn check_inputs(state: &ToolState, dt_s: Real) -> Result<StateVector, IntegrationError> {
    if !(dt_s > 0.0 && dt_s.is_finite()) {
        return Err(IntegrationError::InvalidStep { dt_s });
    }
    let y = state.to_vector();
    if !all_finite(&y) {
        return Err(IntegrationError::NonFiniteInput { what: "tool state" });
    }
    Ok(y)
}

/// `f(t, y)` through the force model, with its wrench checked.
fn derivative(
    body: &RigidBody,
    forces: &mut dyn ForceModel,
    t_s: Real,
    y: &StateVector,
) -> Result<StateVector, IntegrationError> {
    let kin = Kinematics::new(body, y);
    let w = forces.wrench(body, t_s, y, &kin);
    if !w.is_finite() {
        return Err(IntegrationError::NonFiniteForce { what: "wrench" });
    }
    Ok(state_derivative(body, y, &kin, &w))
}

/// `f(t, y)` and `J = ∂f/∂y` (eqs. 6–12 plus the force model's 6×13 Jacobian), checked.
fn derivative_and_jacobian(
    body: &RigidBody,
    forces: &mut dyn ForceModel,
    t_s: Real,
    y: &StateVector,
    jac: &mut SystemJacobian,
) -> Result<StateVector, IntegrationError> {
    let kin = Kinematics::new(body, y);
    let mut wj = WrenchJacobian::zeros();
    let w = forces.wrench_and_jacobian(body, t_s, y, &kin, &mut wj);
    if !w.is_finite() {
        return Err(IntegrationError::NonFiniteForce { what: "wrench" });
    }
    if !all_finite(&wj) {
        return Err(IntegrationError::NonFiniteForce { what: "jacobian" });
    }
    system_jacobian(body, y, &kin, &wj, jac);
    Ok(state_derivative(body, y, &kin, &w))
}

/// Whether the pivots (the diagonal of an LU factorisation's `U`) are all above
/// [`SINGULAR_PIVOT_RATIO`] times the largest. (`lu()` cannot be called generically over the
/// size, so callers pass the diagonal.)
fn pivots_ok(diagonal: impl Iterator<Item = Real>) -> bool {
    let (mut lo, mut hi) = (Real::INFINITY, 0.0_f64);
    for p in diagonal {
        lo = lo.min(p.abs());
        hi = hi.max(p.abs());
    }
    hi.is_finite() && lo > SINGULAR_PIVOT_RATIO * hi
}

/// Solves `(I - h J) Δ = rhs` for the system Jacobian of the tool (eqs. 5–12) by block
/// elimination, using its structure: the `x` rows of `J` hold only `∂ẋ/∂P = I/m`, the `q` rows
/// only `∂q̇/∂q` and `∂q̇/∂L`. Eliminating `Δx = r_x + (h/m) ΔP` and
/// `Δq = A_qq⁻¹ (r_q − A_qL ΔL)` leaves a 6×6 system in `(ΔP, ΔL)`: one 4×4 and one 6×6 LU
/// with partial pivoting, on the stack, instead of a 13×13 one (same solution up to rounding,
/// a third of the cost).
///
/// The dense 13×13 solve is [`solve_shifted_dense`], kept as the reference of the tests.
fn solve_shifted(
    jac: &SystemJacobian,
    dt_s: Real,
    rhs: &StateVector,
) -> Result<StateVector, IntegrationError> {
    let wj: WrenchJacobian = jac.fixed_view::<6, 13>(IP, 0).into_owned();
    solve_blocks(
        jac[(IX, IP)],
        &jac.fixed_view::<4, 4>(IQ, IQ).into_owned(),
        &jac.fixed_view::<4, 3>(IQ, IL).into_owned(),
        &wj,
        dt_s,
        rhs,
    )
}

/// [`solve_shifted`] from the blocks of `J`: `1/m`, `∂q̇/∂q`, `∂q̇/∂L` and the wrench Jacobian
/// (the `P` and `L` rows), without forming the 13×13 matrix.
fn solve_blocks(
    inv_m: Real,
    j_qq: &nalgebra::Matrix4<Real>,
    j_ql: &nalgebra::Matrix4x3<Real>,
    wj: &WrenchJacobian,
    dt_s: Real,
    rhs: &StateVector,
) -> Result<StateVector, IntegrationError> {
    use nalgebra::{Matrix4, Matrix6, Matrix6x3, SMatrix, Vector3, Vector4, Vector6};
    let h = dt_s;
    let h_over_m = h * inv_m;
    // The blocks of the wrench rows, copied out once (small owned matrices multiply fastest).
    let j_wx: Matrix6x3<Real> = wj.fixed_view::<6, 3>(0, IX).into_owned();
    let j_wq: SMatrix<Real, 6, 4> = wj.fixed_view::<6, 4>(0, IQ).into_owned();
    let j_ww: Matrix6<Real> = wj.fixed_view::<6, 6>(0, IP).into_owned();
    let r_x: Vector3<Real> = rhs.fixed_rows::<3>(IX).into_owned();
    let r_q: Vector4<Real> = rhs.fixed_rows::<4>(IQ).into_owned();
    let r_w: Vector6<Real> = rhs.fixed_rows::<6>(IP).into_owned();

    // q rows: (I − h J_qq) Δq − h J_qL ΔL = r_q  ⇒  Δq = a + B ΔL.
    let lu_q = (Matrix4::identity() - j_qq * h).lu();
    if !pivots_ok(lu_q.u().diagonal().iter().copied()) {
        return Err(IntegrationError::SingularSystem);
    }
    let a = lu_q.solve(&r_q).ok_or(IntegrationError::SingularSystem)?;
    let b = lu_q
        .solve(&(j_ql * h))
        .ok_or(IntegrationError::SingularSystem)?;

    // P and L rows, with Δx = r_x + (h/m) ΔP and Δq = a + B ΔL substituted:
    // [I − h J_ww − (h²/m) J_wx | · − h J_wq B] (ΔP, ΔL) = r_w + h J_wx r_x + h J_wq a.
    let mut m: Matrix6<Real> = Matrix6::identity() - j_ww * h;
    {
        let mut mp = m.fixed_view_mut::<6, 3>(0, 0);
        mp -= j_wx * (h * h_over_m);
    }
    {
        let mut ml = m.fixed_view_mut::<6, 3>(0, 3);
        ml -= (j_wq * b) * h;
    }
    let s_rhs = r_w + (j_wx * r_x + j_wq * a) * h;
    let lu_m = m.lu();
    if !pivots_ok(lu_m.u().diagonal().iter().copied()) {
        return Err(IntegrationError::SingularSystem);
    }
    let z = lu_m.solve(&s_rhs).ok_or(IntegrationError::SingularSystem)?;
    let dp = z.fixed_rows::<3>(0).into_owned();
    let dl = z.fixed_rows::<3>(3).into_owned();
    let mut x = StateVector::zeros();
    x.fixed_rows_mut::<3>(IX).copy_from(&(r_x + dp * h_over_m));
    x.fixed_rows_mut::<4>(IQ).copy_from(&(a + b * dl));
    x.fixed_rows_mut::<3>(IP).copy_from(&dp);
    x.fixed_rows_mut::<3>(IL).copy_from(&dl);
    if !all_finite(&x) {
        // The pivots were fine, so the overflow comes from the size of the right-hand side.
        return Err(IntegrationError::NonFiniteState);
    }
    Ok(x)
}

/// Solves `(I - h J) Δ = rhs` by a dense 13×13 LU with partial pivoting (the reference for
/// [`solve_shifted`]).
#[cfg(test)]
fn solve_shifted_dense(
    jac: &SystemJacobian,
    dt_s: Real,
    rhs: &StateVector,
) -> Result<StateVector, IntegrationError> {
    let a = SystemJacobian::identity() - jac * dt_s;
    let lu = a.lu();
    if !pivots_ok(lu.u().diagonal().iter().copied()) {
        return Err(IntegrationError::SingularSystem);
    }
    lu.solve(rhs).ok_or(IntegrationError::SingularSystem)
}

#[cfg(test)]
mod solve_tests {
    use super::*;
    use crate::eom::system_jacobian;
    use crate::testutil::{arb_body, arb_raw_state};
    use haptic_core::{Kinematics, WrenchJacobian};
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(500))]

        /// The block elimination gives the dense solve's answer.
        #[test]
        fn structured_solve_matches_dense(
            body in arb_body(),
            s in arb_raw_state(),
            w in prop::collection::vec(-1e3..1e3f64, 78),
            r in prop::collection::vec(-1.0..1.0f64, 13),
            h in 1e-5..2e-3f64,
        ) {
            let y = s.state_vector(&body);
            let kin = Kinematics::new(&body, &y);
            let wj = WrenchJacobian::from_iterator(w.iter().copied());
            let mut jac = SystemJacobian::zeros();
            system_jacobian(&body, &y, &kin, &wj, &mut jac);
            let rhs = StateVector::from_iterator(r.iter().copied());
            let dense = solve_shifted_dense(&jac, h, &rhs);
            let fast = solve_shifted(&jac, h, &rhs);
            prop_assert_eq!(dense.is_ok(), fast.is_ok(), "dense {:?} against structured {:?}", dense, fast);
            if let (Ok(d), Ok(f)) = (dense, fast) {
                let err = (d - f).norm();
                prop_assert!(err <= 1e-9 * d.norm().max(1.0), "{err} vs {}", d.norm());
            }
        }
    }
}

fn finish(y: &StateVector) -> Result<ToolState, IntegrationError> {
    if !all_finite(y) {
        return Err(IntegrationError::NonFiniteState);
    }
    ToolState::from_vector_normalized(y).map_err(|_| IntegrationError::NonFiniteState)
}

/// Explicit (forward) Euler: `y₁ = y₀ + h f(t, y₀)`. First order; one force evaluation.
#[derive(Debug, Clone, Copy, Default)]
pub struct ForwardEuler;

impl Integrator for ForwardEuler {
    fn name(&self) -> &'static str {
        IntegratorKind::ForwardEuler.name()
    }

    fn uses_jacobian(&self) -> bool {
        false
    }

    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError> {
        let y0 = check_inputs(state, dt_s)?;
        let f0 = derivative(body, forces, t_s, &y0)?;
        finish(&(y0 + f0 * dt_s))
    }
}

/// Classic fourth-order Runge–Kutta. Four force evaluations, no Jacobian.
#[derive(Debug, Clone, Copy, Default)]
pub struct Rk4;

impl Integrator for Rk4 {
    fn name(&self) -> &'static str {
        IntegratorKind::Rk4.name()
    }

    fn uses_jacobian(&self) -> bool {
        false
    }

    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError> {
        let y0 = check_inputs(state, dt_s)?;
        let h = dt_s;
        let k1 = derivative(body, forces, t_s, &y0)?;
        let k2 = derivative(body, forces, t_s + 0.5 * h, &(y0 + k1 * (0.5 * h)))?;
        let k3 = derivative(body, forces, t_s + 0.5 * h, &(y0 + k2 * (0.5 * h)))?;
        let k4 = derivative(body, forces, t_s + h, &(y0 + k3 * h))?;
        finish(&(y0 + (k1 + (k2 + k3) * 2.0 + k4) * (h / 6.0)))
    }
}

/// The paper's semi-implicit (linearized) backward Euler, eqs. 4–5: one linearized solve
/// `(I - h J) Δy = h f(y₀)`, `J = ∂f/∂y` at `y₀`, `y₁ = y₀ + Δy`. First order, unconditionally
/// stable for the linear coupling, one force-and-Jacobian evaluation and one 13×13 solve per
/// step. It is backward Euler's first Newton iterate; [`NewtonBackwardEuler`] iterates to the
/// true backward Euler step. Named `backward_euler` (or `be`) on command lines and in JSON.
///
/// It asks for [`JacobianKind::Material`]: as a one-step linearly implicit method it is
/// first-order consistent with any `J`, and leaving out the contacts' indefinite geometric
/// stiffness keeps a light tool from being turned over in one step (`docs/stability.md`).
#[derive(Debug, Clone, Copy, Default)]
pub struct LinearizedBackwardEuler;

impl Integrator for LinearizedBackwardEuler {
    fn name(&self) -> &'static str {
        IntegratorKind::LinearizedBackwardEuler.name()
    }

    fn uses_jacobian(&self) -> bool {
        true
    }

    fn jacobian_kind(&self) -> JacobianKind {
        JacobianKind::Material
    }

    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError> {
        let y0 = check_inputs(state, dt_s)?;
        let kin = Kinematics::new(body, &y0);
        let mut wj = WrenchJacobian::zeros();
        let w = forces.wrench_and_jacobian(body, t_s + dt_s, &y0, &kin, &mut wj);
        if !w.is_finite() {
            return Err(IntegrationError::NonFiniteForce { what: "wrench" });
        }
        if !all_finite(&wj) {
            return Err(IntegrationError::NonFiniteForce { what: "jacobian" });
        }
        let f0 = state_derivative(body, &y0, &kin, &w);
        // The system Jacobian by blocks (eqs. 6–12), never formed as a 13×13 matrix.
        let (j_qq, j_ql) = quaternion_jacobian_blocks(&y0, &kin);
        let dy = solve_blocks(1.0 / body.mass_kg(), &j_qq, &j_ql, &wj, dt_s, &(f0 * dt_s))?; // eq. 5
        finish(&(y0 + dy))
    }
}

/// Backward Euler solved by full Newton iteration: `y₁ = y₀ + h f(t + h, y₁)` to a tolerance.
/// The accuracy reference for [`LinearizedBackwardEuler`] (its first iterate is the semi-implicit step).
///
/// Converged when, for each of the four blocks `x, q, P, L`, the last Newton update is at most
/// `tolerance` times the block's size (max norm of `y₀` and the iterate; for the momenta at
/// least the momentum that moves the pose by its own size in one step, see
/// `momentum_floors`).
#[derive(Debug, Clone, Copy)]
pub struct NewtonBackwardEuler {
    /// Relative tolerance on the Newton update, per block.
    pub tolerance: Real,
    /// Largest number of Newton iterations before [`IntegrationError::NotConverged`].
    pub max_iterations: usize,
}

impl Default for NewtonBackwardEuler {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_iterations: 20,
        }
    }
}

impl NewtonBackwardEuler {
    /// A validated configuration.
    ///
    /// # Errors
    /// [`DynamicsError::Core`] ([`haptic_core::check`]) unless `tolerance > 0` (finite) and
    /// `max_iterations >= 1`.
    pub fn new(tolerance: Real, max_iterations: usize) -> Result<Self, DynamicsError> {
        check::positive("newton.tolerance", tolerance)?;
        if max_iterations == 0 {
            return Err(haptic_core::CoreError::OutOfRange {
                what: "newton.max_iterations",
                value: 0.0,
                expected: ">= 1",
            }
            .into());
        }
        Ok(Self {
            tolerance,
            max_iterations,
        })
    }
}

/// How many times [`NewtonBackwardEuler`] halves a step that fails the monotonicity test.
const LINE_SEARCH_HALVINGS: i32 = 4;

/// The largest block-relative size of `delta` (blocks x, q, P, L) against `a` and `b`, each
/// block's size at least its `floors` entry.
fn block_relative(
    delta: &StateVector,
    a: &StateVector,
    b: &StateVector,
    floors: &[Real; 4],
) -> Real {
    const BLOCKS: [(usize, usize); 4] = [(0, 3), (3, 7), (7, 10), (10, 13)];
    let mut worst = 0.0_f64;
    for ((lo, hi), floor) in BLOCKS.into_iter().zip(floors) {
        let (mut d, mut s) = (0.0_f64, *floor);
        for i in lo..hi {
            d = d.max(delta[i].abs());
            s = s.max(a[i].abs()).max(b[i].abs());
        }
        if d > 0.0 {
            worst = worst.max(d / s.max(Real::MIN_POSITIVE));
        }
    }
    worst
}

/// The least sizes of the momentum blocks in [`NewtonBackwardEuler`]'s convergence test: the
/// momenta whose effect over one step is the size of the pose blocks. `P` is measured against
/// `m |x| / h` (a momentum that moves the tool by `|x|` in one step) and `L` against
/// `1 / (h ‖I⁻¹‖)` (one that turns it by a radian, the size of the unit quaternion). Without
/// them a tool at rest, whose momenta are round-off, can never pass a test relative to the
/// momenta's own size: a 1.6 g plank at rest on stiff contacts stalled at 1e-7.
fn momentum_floors(body: &RigidBody, y0: &StateVector, dt_s: Real) -> [Real; 4] {
    let x_size = y0.fixed_rows::<3>(IX).amax();
    let inv_inertia = body.inertia_body_inv();
    let inv_inertia_norm = (0..3)
        .map(|r| inv_inertia.row(r).iter().map(|v| v.abs()).sum::<Real>())
        .fold(0.0, Real::max);
    [
        0.0,
        0.0,
        body.mass_kg() * x_size / dt_s,
        1.0 / (dt_s * inv_inertia_norm.max(Real::MIN_POSITIVE)),
    ]
}

impl Integrator for NewtonBackwardEuler {
    fn name(&self) -> &'static str {
        IntegratorKind::NewtonBackwardEuler.name()
    }

    fn uses_jacobian(&self) -> bool {
        true
    }

    fn step(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        t_s: Real,
        dt_s: Real,
        forces: &mut dyn ForceModel,
    ) -> Result<ToolState, IntegrationError> {
        let y0 = check_inputs(state, dt_s)?;
        let t1 = t_s + dt_s;
        let mut y = y0;
        let mut jac = SystemJacobian::zeros();
        let mut trial_jac = SystemJacobian::zeros();
        let f = derivative_and_jacobian(body, forces, t1, &y, &mut jac)?;
        let mut g = y - y0 - f * dt_s; // residual of y = y0 + h f(y)
        let floors = momentum_floors(body, &y0, dt_s);
        let mut residual = Real::INFINITY;
        for _ in 0..self.max_iterations {
            let delta = solve_shifted(&jac, dt_s, &(-g))?;
            residual = block_relative(&delta, &y0, &(y + delta), &floors);
            if residual <= self.tolerance {
                let y1 = y + delta;
                if !all_finite(&y1) {
                    return Err(IntegrationError::NonFiniteState);
                }
                return finish(&y1);
            }
            // Damped Newton with the natural monotonicity test (Deuflhard 2004, NLEQ-ERR): the
            // contact forces are piecewise smooth (a contact switches off, or reaches its cap),
            // where full Newton steps can cycle between the pieces. A trial `y + α Δ` is taken
            // when its simplified Newton correction `Δ̄ = −J(y)⁻¹ g(y + α Δ)` is smaller than
            // `(1 − α/2) Δ`; otherwise α is halved, at most LINE_SEARCH_HALVINGS times. The
            // test is affine invariant: no scaling of the residual's units is needed.
            let size = block_relative(&delta, &y0, &y, &floors);
            let mut alpha = 1.0;
            loop {
                let trial = y + delta * alpha;
                if !all_finite(&trial) {
                    return Err(IntegrationError::NonFiniteState);
                }
                let f = derivative_and_jacobian(body, forces, t1, &trial, &mut trial_jac)?;
                let g_trial = trial - y0 - f * dt_s;
                let last = alpha < 0.5_f64.powi(LINE_SEARCH_HALVINGS);
                let monotone = last || {
                    let simplified = solve_shifted(&jac, dt_s, &(-g_trial))?;
                    block_relative(&simplified, &y0, &y, &floors) <= (1.0 - alpha / 2.0) * size
                };
                if monotone {
                    y = trial;
                    g = g_trial;
                    std::mem::swap(&mut jac, &mut trial_jac);
                    break;
                }
                alpha *= 0.5;
            }
        }
        Err(IntegrationError::NotConverged {
            iterations: self.max_iterations,
            residual,
        })
    }
}

/// The integrators by name, for configuration files, command lines and sweeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum IntegratorKind {
    /// [`LinearizedBackwardEuler`] (semi-implicit, the paper's method).
    LinearizedBackwardEuler,
    /// [`NewtonBackwardEuler`] with its default tolerance.
    NewtonBackwardEuler,
    /// [`Rk4`].
    Rk4,
    /// [`ForwardEuler`].
    ForwardEuler,
}

impl IntegratorKind {
    /// Every kind, in the order the studies report them.
    pub const ALL: [IntegratorKind; 4] = [
        IntegratorKind::LinearizedBackwardEuler,
        IntegratorKind::NewtonBackwardEuler,
        IntegratorKind::Rk4,
        IntegratorKind::ForwardEuler,
    ];

    /// The snake_case name used in JSON output: `backward_euler`, `newton_backward_euler`,
    /// `rk4`, `forward_euler`.
    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::LinearizedBackwardEuler => "backward_euler",
            IntegratorKind::NewtonBackwardEuler => "newton_backward_euler",
            IntegratorKind::Rk4 => "rk4",
            IntegratorKind::ForwardEuler => "forward_euler",
        }
    }

    /// Whether the integrator needs the force model's Jacobian.
    pub fn is_implicit(self) -> bool {
        matches!(
            self,
            IntegratorKind::LinearizedBackwardEuler | IntegratorKind::NewtonBackwardEuler
        )
    }

    /// A boxed integrator of this kind with default settings.
    pub fn boxed(self) -> Box<dyn Integrator + Send> {
        match self {
            IntegratorKind::LinearizedBackwardEuler => Box::new(LinearizedBackwardEuler),
            IntegratorKind::NewtonBackwardEuler => Box::new(NewtonBackwardEuler::default()),
            IntegratorKind::Rk4 => Box::new(Rk4),
            IntegratorKind::ForwardEuler => Box::new(ForwardEuler),
        }
    }
}

impl fmt::Display for IntegratorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for IntegratorKind {
    type Err = DynamicsError;

    /// Accepts `be`/`backward_euler`/`linearized_backward_euler`,
    /// `newton-be`/`newton_backward_euler`, `rk4`, `fe`/`forward_euler`; case-insensitive, `-` and
    /// `_` interchangeable.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let norm = s.trim().to_ascii_lowercase().replace('-', "_");
        match norm.as_str() {
            "be" | "backward_euler" | "linearized_backward_euler" | "semi_implicit" => {
                Ok(IntegratorKind::LinearizedBackwardEuler)
            }
            "newton_be" | "newton_backward_euler" | "newton" => {
                Ok(IntegratorKind::NewtonBackwardEuler)
            }
            "rk4" | "runge_kutta" => Ok(IntegratorKind::Rk4),
            "fe" | "forward_euler" | "euler" => Ok(IntegratorKind::ForwardEuler),
            _ => Err(DynamicsError::UnknownIntegrator { name: s.to_owned() }),
        }
    }
}
