//! The [`ContactModel`] trait and the [`LinearizedContact`] it publishes to the haptic thread.

use crate::body::RigidBody;
use crate::contact::Contact;
use crate::contact_frame::FixedFrame;
use crate::error::ContactModelError;
use crate::integrator::JacobianKind;
use crate::math::{IQ, Real, StateVector, Vec3, WrenchJacobian, WrenchVector};
use crate::state::{Kinematics, ToolState, Wrench};
use nalgebra::RowSVector;

/// The most contacts (cluster representatives) one [`LinearizedContact`] holds.
///
/// The linearized model keeps one tangent per representative so that each can be bounded on
/// its own; a fixed capacity keeps the model a plain `Copy` value that the contact thread hands
/// to the haptic thread without allocating. Clustering gives far fewer (the paper uses `K ≤ 5`).
pub const MAX_REPRESENTATIVES: usize = 16;

/// The release band `ε` of a [`ContactTangent`] as a fraction of its reach `k_n δ`.
pub const RELEASE_BAND_FRACTION: Real = 0.5;

/// Contacts (or cluster representatives) to a wrench on the tool and its Jacobian.
///
/// The contact thread calls [`ContactModel::linearize`] once per collision update, at the tool
/// state `y₀` it queried with, and publishes the resulting [`LinearizedContact`]; the haptic
/// thread evaluates that in constant time each step (paper eq. 42).
///
/// Contract for implementers:
/// - The wrench acts at the tool's centre of mass (force, N) and about it (torque, N m), world
///   frame, as for [`crate::ForceModel`].
/// - Contacts are fixed within one call: their `r_a` (body frame), `p_b`, `n` are constants and
///   the wrench varies with `y` through `p_a = x + R(q) r_a` and the tool's velocity.
/// - Each contact pushes the tool along `−n` (its normal force `λ = −n·F ≥ 0`) and contacts add
///   up: the wrench of a slice is the sum of the wrenches of its elements. The default
///   [`ContactModel::linearize`] relies on this to linearize each contact on its own.
/// - When `jacobian` is `Some`, write the full 6×13 derivative `∂(F, T)/∂y` of exactly the wrench
///   you return; when `None`, do not compute it.
/// - Validate the contacts: a NaN field or a non-unit normal is an error, not a NaN force.
///
/// ```
/// use haptic_core::{
///     Contact, ContactModel, ContactModelError, Kinematics, Real, RigidBody, StateVector, Wrench,
///     WrenchJacobian,
/// };
///
/// /// A constant push of 1 N along −n per contact (no Jacobian: it does not depend on `y`).
/// struct UnitPush;
///
/// impl ContactModel for UnitPush {
///     fn evaluate(
///         &mut self,
///         _: &RigidBody,
///         _: &StateVector,
///         kin: &Kinematics,
///         contacts: &[Contact],
///         jacobian: Option<&mut WrenchJacobian>,
///     ) -> Result<Wrench, ContactModelError> {
///         if let Some(j) = jacobian {
///             j.fill(0.0);
///         }
///         let mut w = Wrench::zero();
///         for c in contacts {
///             let f = -c.n;
///             w.force += f;
///             w.torque += (kin.r * c.r_a).cross(&f);
///         }
///         Ok(w)
///     }
///
///     fn extrapolation_reach_m(&self) -> Real {
///         1e-3
///     }
/// }
/// ```
pub trait ContactModel {
    /// The contact wrench at state `y` (with its kinematics `kin`), and optionally its Jacobian.
    ///
    /// # Errors
    /// [`ContactModelError`] for non-finite or malformed contacts.
    fn evaluate(
        &mut self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        contacts: &[Contact],
        jacobian: Option<&mut WrenchJacobian>,
    ) -> Result<Wrench, ContactModelError>;

    /// How much deeper (m) than at `y₀` a contact may be pressed before its linearization stops
    /// growing: the collision query's distance tolerance `δ`, within which the contacts
    /// reported at `y₀` are the ones the geometry has (see [`ContactTangent::lambda_max_n`]).
    fn extrapolation_reach_m(&self) -> Real;

    /// Linearizes the model at `state` (paper eq. 42) into `out`, for the haptic thread: one
    /// [`ContactTangent`] per contact that pushes at `y₀` (contacts that give no force are
    /// dropped: their tangent is zero).
    ///
    /// # Errors
    /// As [`ContactModel::evaluate`]; [`ContactModelError::NonFiniteState`] for a NaN state;
    /// [`ContactModelError::TooManyContacts`] for more than [`MAX_REPRESENTATIVES`] contacts
    /// (cluster them first).
    fn linearize(
        &mut self,
        body: &RigidBody,
        state: &ToolState,
        contacts: &[Contact],
        out: &mut LinearizedContact,
    ) -> Result<(), ContactModelError> {
        if contacts.len() > MAX_REPRESENTATIVES {
            return Err(ContactModelError::TooManyContacts {
                count: contacts.len(),
                max: MAX_REPRESENTATIVES,
            });
        }
        let y = state.to_vector();
        if y.iter().any(|v| !v.is_finite()) {
            return Err(ContactModelError::NonFiniteState);
        }
        let reach_m = self.extrapolation_reach_m().max(0.0);
        let kin = Kinematics::new(body, &y);
        out.clear();
        out.y0 = y;
        for (index, c) in contacts.iter().enumerate() {
            let mut jacobian = WrenchJacobian::zeros();
            let w = self
                .evaluate(body, &y, &kin, std::slice::from_ref(c), Some(&mut jacobian))
                .map_err(|e| e.at_index(index))?;
            out.max_depth_m = out.max_depth_m.max(c.depth_m);
            if let Some(t) = ContactTangent::new(c.n, w, jacobian, reach_m) {
                let frame = FixedFrame::new(
                    &y,
                    &kin,
                    body.mass_kg(),
                    c.r_a,
                    c.n,
                    t.lambda0_n,
                    &t.dlambda_dy,
                );
                out.push(ContactTangent { frame, ..t })?;
            }
        }
        Ok(())
    }
}

impl<M: ContactModel + ?Sized> ContactModel for &mut M {
    fn evaluate(
        &mut self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        contacts: &[Contact],
        jacobian: Option<&mut WrenchJacobian>,
    ) -> Result<Wrench, ContactModelError> {
        (**self).evaluate(body, y, kin, contacts, jacobian)
    }

    fn extrapolation_reach_m(&self) -> Real {
        (**self).extrapolation_reach_m()
    }
}

impl<M: ContactModel + ?Sized> ContactModel for Box<M> {
    fn evaluate(
        &mut self,
        body: &RigidBody,
        y: &StateVector,
        kin: &Kinematics,
        contacts: &[Contact],
        jacobian: Option<&mut WrenchJacobian>,
    ) -> Result<Wrench, ContactModelError> {
        (**self).evaluate(body, y, kin, contacts, jacobian)
    }

    fn extrapolation_reach_m(&self) -> Real {
        (**self).extrapolation_reach_m()
    }
}

/// How the haptic thread uses a [`LinearizedContact`] between contact updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LinearizationMode {
    /// Each contact's wrench `W_k(y₀) + ∂W_k/∂y (y − y₀)`, bounded (see [`ContactTangent`]), and
    /// its Jacobian enters the implicit solve (the paper's method, eq. 42).
    Linearized,
    /// `F(y) = F(y₀)` held constant, no Jacobian: the paper's ablation.
    Constant,
    /// Each contact evaluated at `y` as a spring-damper on its [`FixedFrame`] from `y₀` (its
    /// point on the tool, its normal, and the normal stiffness and damping it had at `y₀`), with
    /// the tool's exact kinematics instead of the tangent's first-order ones, and the same bounds
    /// as [`LinearizationMode::Linearized`] on its normal force; its exact Jacobian enters the
    /// implicit solve. It agrees with the tangent to first order at `y₀`, but a turned tool
    /// turns its contact points with it, so a stale model cannot give the tool energy through
    /// the rotation (`docs/stability.md`). A contact without a frame (a tangent built by hand
    /// with [`ContactTangent::new`]) is evaluated as in `Linearized`. The haptic stage also
    /// lets contacts pressed beyond their cap yield, once per step
    /// ([`LinearizedContact::yield_beyond_reach`]). The default.
    #[default]
    FixedFrames,
}

/// One contact's wrench linearized about `y₀` (eq. 42), with the bounds that keep a stale
/// tangent from doing what no penalty contact does.
///
/// Along the tangent the contact's normal force is `λ(y) = λ₀ + ∂λ/∂y (y − y₀)`, with
/// `λ = −n·F`. The haptic thread may evaluate the tangent tens of milliseconds after `y₀`, far
/// from where it is valid, so ([`ContactTangent::wrench_at`]):
/// - **it never pulls**: where `λ(y) ≤ 0` the surfaces have separated and the contact gives
///   nothing (the penalty model's own switch-off, eq. 33). The switch-off is made smooth: over
///   the release band `0 < λ < ε` the tangent wrench is multiplied by the smoothstep
///   `σ = t²(3 − 2t)`, `t = λ/ε`, so that the wrench and its Jacobian are continuous. A hard
///   switch-off made the full-Newton integrator cycle between its two sides (a third of the
///   stiff, slow-update stress runs failed to converge); `ε = ½ k_n δ`
///   ([`RELEASE_BAND_FRACTION`]), which also softens the onset of a contact that touches at
///   `y₀` with less than `ε`;
/// - **it never grows beyond its reach**: `λ(y)` is at most `λ_max = λ₀ + k_n δ`, what the
///   contact gives pressed `δ` deeper than at `y₀` (`k_n = ∂λ/∂x · n` its normal stiffness, `δ`
///   [`ContactModel::extrapolation_reach_m`]); beyond that the tangent wrench is scaled down to
///   it. Deeper than `δ` the query at `y₀` did not look, so nothing is known there.
///
/// Both bounds are continuous in `y` (the wrench goes to zero, or to the cap, without a jump),
/// and the Jacobian returned is exactly that of the bounded wrench.
///
/// Decided in `docs/decisions.md` ("Bounded linearized contacts"), with the stress runs that
/// chose the band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactTangent {
    /// The contact normal (unit, out of the tool).
    pub n: Vec3,
    /// The contact's wrench at `y₀`, `(F, T)` (N, N m).
    pub wrench0: WrenchVector,
    /// Its Jacobian `∂(F, T)/∂y` at `y₀` (6×13).
    pub jacobian: WrenchJacobian,
    /// Its normal force `λ₀ = −n·F(y₀) > 0` (N).
    pub lambda0_n: Real,
    /// `∂λ/∂y = −nᵀ ∂F/∂y` at `y₀` (1×13).
    pub dlambda_dy: RowSVector<Real, 13>,
    /// The largest normal force the tangent may give (N): `λ₀ + k_n δ`.
    pub lambda_max_n: Real,
    /// Width `ε` of the release band (N): below `λ = ε` the tangent wrench is faded out smoothly
    /// (see [`ContactTangent`]); `ε = ½ k_n δ`.
    pub release_band_n: Real,
    /// The contact's frame at `y₀`, for [`LinearizationMode::FixedFrames`]; `None` when the
    /// tangent was built without one.
    pub frame: Option<FixedFrame>,
}

impl ContactTangent {
    /// No contact.
    pub fn none() -> Self {
        Self {
            n: Vec3::z(),
            wrench0: WrenchVector::zeros(),
            jacobian: WrenchJacobian::zeros(),
            lambda0_n: 0.0,
            dlambda_dy: RowSVector::zeros(),
            lambda_max_n: 0.0,
            release_band_n: 0.0,
            frame: None,
        }
    }

    /// The tangent of a contact with normal `n`, wrench `w` and Jacobian `jacobian` at `y₀`,
    /// extrapolated at most `reach_m` deeper; `None` when the contact does not push at `y₀`
    /// (`λ₀ ≤ 0`), whose tangent is zero.
    pub fn new(n: Vec3, w: Wrench, jacobian: WrenchJacobian, reach_m: Real) -> Option<Self> {
        let lambda0_n = -n.dot(&w.force);
        if lambda0_n.is_nan() || lambda0_n <= 0.0 {
            return None;
        }
        let jf = jacobian.fixed_rows::<3>(0);
        let dlambda_dy: RowSVector<Real, 13> = -(n.transpose() * jf);
        // eq. 34 for a penalty contact: ∂λ/∂x = k_c nᵀ, so k_n = k_c.
        let k_n = (dlambda_dy.fixed_columns::<3>(0) * n)[0].max(0.0);
        Some(Self {
            n,
            wrench0: w.to_vector(),
            jacobian,
            lambda0_n,
            dlambda_dy,
            lambda_max_n: lambda0_n + k_n * reach_m,
            release_band_n: RELEASE_BAND_FRACTION * k_n * reach_m,
            frame: None,
        })
    }

    /// The bounded normal force `φ(λ)` and its derivative `φ'(λ)`: zero where `λ ≤ 0`, the
    /// smoothstep fade `λ σ(λ/ε)` over the release band, `λ` up to `λ_max`, and `λ_max` beyond.
    #[inline]
    fn bounded_normal_force(&self, lambda: Real) -> (Real, Real) {
        if lambda <= 0.0 {
            return (0.0, 0.0);
        }
        let band = self.release_band_n;
        if lambda < band {
            let t = lambda / band;
            let sigma = t * t * (3.0 - 2.0 * t);
            return (lambda * sigma, sigma + 6.0 * t * t * (1.0 - t));
        }
        if lambda <= self.lambda_max_n {
            (lambda, 1.0)
        } else {
            (self.lambda_max_n, 0.0)
        }
    }

    /// The contact's wrench at `y` on its fixed frame ([`LinearizationMode::FixedFrames`]),
    /// its Jacobian added into `jacobian` when given; the tangent's
    /// ([`ContactTangent::wrench_at`]) when there is no frame.
    ///
    /// `F = −φ(λ(y)) n` and `T = ρ × F`, with `λ(y)` the frame's normal force
    /// ([`FixedFrame::normal_force`]) and `φ` the same bounds as the tangent's (never pulls,
    /// smooth release over `ε`, at most `λ_max`). `kind` says whether the Jacobian keeps the
    /// geometric term `−[F]× ∂ρ/∂q` ([`JacobianKind`]).
    #[inline]
    pub fn frame_wrench_at(
        &self,
        y: &StateVector,
        kin: &Kinematics,
        dy: &StateVector,
        jacobian: Option<&mut WrenchJacobian>,
        kind: JacobianKind,
    ) -> WrenchVector {
        let Some(frame) = &self.frame else {
            return self.wrench_at(dy, jacobian);
        };
        let (rho, lambda) = frame.normal_force(y, kin);
        let (phi, dphi) = self.bounded_normal_force(lambda);
        let force = -phi * frame.n;
        if let Some(j) = jacobian {
            if phi > 0.0 {
                // The material part `(∂F/∂y, [ρ]× ∂F/∂y)` is one rank-1 block: `∂F/∂y = c_F g`
                // with `c_F = −φ' n` and `g = ∂λ/∂y`, so `∂T/∂y = (ρ × c_F) g` (eqs. 38–41 with
                // the force along a fixed normal). Added as such, without the 3×13 products.
                let g = frame.normal_force_gradient(kin, &rho);
                let c_force = frame.n * -dphi;
                let c_torque = rho.cross(&c_force);
                let c = WrenchVector::new(
                    c_force.x, c_force.y, c_force.z, c_torque.x, c_torque.y, c_torque.z,
                );
                j.ger(1.0, &c, &g.transpose(), 1.0);
                // Exact: the torque also turns with ρ, `−[F]× ∂ρ/∂q_k` (capped, φ' = 0, this
                // is all there is).
                if kind == JacobianKind::Exact {
                    for q in 0..4 {
                        let dt_q = force.cross(&(kin.r_partials[q] * frame.r_a));
                        for a in 0..3 {
                            j[(3 + a, IQ + q)] -= dt_q[a];
                        }
                    }
                }
            }
        }
        let torque = rho.cross(&force);
        WrenchVector::new(force.x, force.y, force.z, torque.x, torque.y, torque.z)
    }

    /// The bounded tangent wrench at `dy = y − y₀` and, when `jacobian` is `Some`, its Jacobian
    /// added into it.
    #[inline]
    pub fn wrench_at(
        &self,
        dy: &StateVector,
        jacobian: Option<&mut WrenchJacobian>,
    ) -> WrenchVector {
        let lambda = self.lambda0_n + (self.dlambda_dy * dy)[0];
        let (phi, dphi) = self.bounded_normal_force(lambda);
        if phi == 0.0 {
            return WrenchVector::zeros(); // separated: it never pulls
        }
        // The tangent wrench scaled by s = φ(λ)/λ (1 between the band and the cap), with
        // ∂s/∂y = (φ' − s)/λ ∂λ/∂y.
        let w = self.wrench0 + self.jacobian * dy;
        let s = phi / lambda;
        let ds = (dphi - s) / lambda;
        if let Some(j) = jacobian {
            *j += self.jacobian * s;
            if ds != 0.0 {
                *j += (w * ds) * self.dlambda_dy;
            }
        }
        w * s
    }
}

/// A contact wrench linearized about `y₀` (paper eq. 42): what the contact thread publishes.
///
/// One bounded [`ContactTangent`] per contact (cluster representative): the haptic thread sums
/// them in constant time, whatever the number of triangles or raw contacts. A plain `Copy` value
/// of fixed size, so it can be exchanged through a lock-free single-slot buffer.
///
/// The value is large (about 15 kB, [`MAX_REPRESENTATIVES`] tangents of a 6×13 Jacobian each),
/// and only the first [`LinearizedContact::contact_count`] tangents mean anything: the rest is
/// storage, left as it was by [`LinearizedContact::clear`] and not copied by
/// [`LinearizedContact::copy_from`], and equality and `Debug` look at the tangents in use only.
/// Where a model is handed on often (every contact update, the haptic thread's receipt of one),
/// `clear` and `copy_from` cost what the contacts in use cost, not the whole capacity.
#[derive(Clone, Copy)]
pub struct LinearizedContact {
    /// The tool state the contacts were computed at.
    pub y0: StateVector,
    /// `(F(y₀), T(y₀))`, the sum over the contacts.
    pub wrench0: Wrench,
    /// The tangents; the first [`LinearizedContact::contact_count`] are in use.
    pub tangents: [ContactTangent; MAX_REPRESENTATIVES],
    /// Number of contacts (representatives) pushing at `y₀`; 0 means no contact.
    pub contact_count: usize,
    /// Largest depth among the contacts linearized (m); `-inf` when there is none.
    pub max_depth_m: Real,
    /// Factor on every wrench and Jacobian (1 unless faded, see [`LinearizedContact::scaled`]).
    pub scale: Real,
}

impl Default for LinearizedContact {
    fn default() -> Self {
        Self::none()
    }
}

/// A model's fields as `PartialEq` and `Debug` see them: the tangents in use only (the unused
/// storage is neither compared nor printed).
type ModelParts<'a> = (
    &'a StateVector,
    &'a Wrench,
    &'a [ContactTangent],
    usize,
    Real,
    Real,
);

impl LinearizedContact {
    /// The fields, destructured, so that a field added later is not left out of the comparison
    /// or the printout.
    fn parts(&self) -> ModelParts<'_> {
        let Self {
            y0,
            wrench0,
            tangents: _,
            contact_count,
            max_depth_m,
            scale,
        } = self;
        (
            y0,
            wrench0,
            self.tangents(),
            *contact_count,
            *max_depth_m,
            *scale,
        )
    }
}

impl PartialEq for LinearizedContact {
    /// Equal models: the same `y₀`, wrench, count, depth and scale, and the same tangents in
    /// use (the unused storage is not compared).
    fn eq(&self, other: &Self) -> bool {
        self.parts() == other.parts()
    }
}

impl std::fmt::Debug for LinearizedContact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (y0, wrench0, tangents, contact_count, max_depth_m, scale) = self.parts();
        f.debug_struct("LinearizedContact")
            .field("y0", y0)
            .field("wrench0", wrench0)
            .field("tangents", &tangents)
            .field("contact_count", &contact_count)
            .field("max_depth_m", &max_depth_m)
            .field("scale", &scale)
            .finish()
    }
}

impl LinearizedContact {
    /// Makes this model [`LinearizedContact::none`] without writing its tangents' storage
    /// (which is unused once the count is 0): a few dozen bytes written instead of 15 kB.
    #[inline]
    pub fn clear(&mut self) {
        let Self {
            y0,
            wrench0,
            tangents: _,
            contact_count,
            max_depth_m,
            scale,
        } = self;
        *y0 = StateVector::zeros();
        *wrench0 = Wrench::zero();
        *contact_count = 0;
        *max_depth_m = Real::NEG_INFINITY;
        *scale = 1.0;
    }

    /// Makes this model equal to `other`, copying only the tangents `other` has in use (a
    /// model with five contacts copies five tangents, not [`MAX_REPRESENTATIVES`]).
    #[inline]
    pub fn copy_from(&mut self, other: &Self) {
        let Self {
            y0,
            wrench0,
            tangents,
            contact_count,
            max_depth_m,
            scale,
        } = other;
        let count = (*contact_count).min(MAX_REPRESENTATIVES);
        self.y0 = *y0;
        self.wrench0 = *wrench0;
        self.tangents[..count].copy_from_slice(&tangents[..count]);
        self.contact_count = *contact_count;
        self.max_depth_m = *max_depth_m;
        self.scale = *scale;
    }

    /// No contact: zero wrench and zero Jacobian.
    pub fn none() -> Self {
        Self {
            y0: StateVector::zeros(),
            wrench0: Wrench::zero(),
            tangents: [ContactTangent::none(); MAX_REPRESENTATIVES],
            contact_count: 0,
            max_depth_m: Real::NEG_INFINITY,
            scale: 1.0,
        }
    }

    /// Whether there is any contact.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.contact_count == 0
    }

    /// The tangents in use.
    #[inline]
    pub fn tangents(&self) -> &[ContactTangent] {
        &self.tangents[..self.contact_count.min(MAX_REPRESENTATIVES)]
    }

    /// Whether, at `y`, some contact is pressed deeper than its tangent's reach
    /// (`λ > λ_max`): the tool has moved into the surface farther than the query at `y₀` could
    /// see, as happens when it travels more than `δ` between two queries.
    pub fn beyond_reach(&self, y: &StateVector) -> bool {
        let dy = y - self.y0;
        self.tangents()
            .iter()
            .any(|t| t.lambda0_n + (t.dlambda_dy * dy)[0] > t.lambda_max_n)
    }

    /// In [`LinearizationMode::FixedFrames`], once per haptic step at the accepted state `y`
    /// (kinematics `kin`): every contact whose elastic force there exceeds its cap `λ_max`
    /// yields, its anchor moved so that the elastic force is `λ_max` (see
    /// [`FixedFrame::yield_to`]). Returns how many yielded.
    ///
    /// Without it a contact pressed far beyond its reach (the tool travelled there between two
    /// updates, or the update arrived late) would push with `λ_max` until the tool had come all
    /// the way back: the capped spring stores `λ_max` times the excess depth and gives it to the
    /// tool, which is what threw light tools out of the cup in the stress runs. Having yielded,
    /// the contact stores at most `λ_max² / 2k_n`, and starts each step at or below its cap,
    /// where its stiffness is in the Jacobian of the implicit solve.
    pub fn yield_beyond_reach(&mut self, y: &StateVector, kin: &Kinematics) -> usize {
        let count = self.contact_count.min(MAX_REPRESENTATIVES);
        let mut yielded = 0;
        for t in &mut self.tangents[..count] {
            let cap = t.lambda_max_n;
            if let Some(frame) = &mut t.frame {
                yielded += usize::from(frame.yield_to(y, kin, cap));
            }
        }
        yielded
    }

    /// Adds a tangent (and its wrench to `wrench0`).
    ///
    /// # Errors
    /// [`ContactModelError::TooManyContacts`] when [`MAX_REPRESENTATIVES`] are in use already.
    pub fn push(&mut self, tangent: ContactTangent) -> Result<(), ContactModelError> {
        if self.contact_count >= MAX_REPRESENTATIVES {
            return Err(ContactModelError::TooManyContacts {
                count: self.contact_count + 1,
                max: MAX_REPRESENTATIVES,
            });
        }
        self.wrench0.force += tangent.wrench0.fixed_rows::<3>(0);
        self.wrench0.torque += tangent.wrench0.fixed_rows::<3>(3);
        self.tangents[self.contact_count] = tangent;
        self.contact_count += 1;
        Ok(())
    }

    /// The wrench at `y` (constant time); `kin` is the tool's kinematics at `y`.
    #[inline]
    pub fn wrench_at(&self, y: &StateVector, kin: &Kinematics, mode: LinearizationMode) -> Wrench {
        self.evaluate(y, kin, mode, 1.0, None)
    }

    /// The wrench at `y` (kinematics `kin`) and, unless the mode is
    /// [`LinearizationMode::Constant`], its exact Jacobian added into `jacobian`; in `Constant`
    /// `jacobian` is left as it is.
    #[inline]
    pub fn add_wrench_and_jacobian(
        &self,
        y: &StateVector,
        kin: &Kinematics,
        mode: LinearizationMode,
        jacobian: &mut WrenchJacobian,
    ) -> Wrench {
        self.evaluate(y, kin, mode, 1.0, Some((jacobian, JacobianKind::Exact)))
    }

    /// The wrench at `y` (kinematics `kin`) times `factor` and, when `jacobian` is given (and
    /// the mode is not [`LinearizationMode::Constant`]), its Jacobian of that kind times
    /// `factor` added into it: what a blend of two models needs, without copying either.
    #[inline]
    pub fn weighted(
        &self,
        y: &StateVector,
        kin: &Kinematics,
        mode: LinearizationMode,
        factor: Real,
        jacobian: Option<(&mut WrenchJacobian, JacobianKind)>,
    ) -> Wrench {
        self.evaluate(y, kin, mode, factor, jacobian)
    }

    fn evaluate(
        &self,
        y: &StateVector,
        kin: &Kinematics,
        mode: LinearizationMode,
        factor: Real,
        jacobian: Option<(&mut WrenchJacobian, JacobianKind)>,
    ) -> Wrench {
        let scale = self.scale * factor;
        if self.contact_count == 0 {
            return Wrench::zero();
        }
        if mode == LinearizationMode::Constant {
            return Wrench::new(self.wrench0.force * scale, self.wrench0.torque * scale);
        }
        let dy = y - self.y0;
        let kind = jacobian.as_ref().map_or(JacobianKind::Exact, |(_, k)| *k);
        let one = |t: &ContactTangent, j: Option<&mut WrenchJacobian>| match mode {
            LinearizationMode::FixedFrames => t.frame_wrench_at(y, kin, &dy, j, kind),
            _ => t.wrench_at(&dy, j),
        };
        let mut sum = WrenchVector::zeros();
        match jacobian {
            None => {
                for t in self.tangents() {
                    sum += one(t, None);
                }
            }
            // Unscaled (the usual case) the tangents add into `j` directly.
            Some((j, _)) if scale == 1.0 => {
                for t in self.tangents() {
                    sum += one(t, Some(&mut *j));
                }
            }
            Some((j, _)) => {
                let mut jac = WrenchJacobian::zeros();
                for t in self.tangents() {
                    sum += one(t, Some(&mut jac));
                }
                *j += jac * scale;
            }
        }
        sum *= scale;
        Wrench::new(sum.fixed_rows::<3>(0).into(), sum.fixed_rows::<3>(3).into())
    }

    /// The same model with every wrench and Jacobian scaled by `s` (used to fade contact forces
    /// out when the contact thread stalls).
    pub fn scaled(&self, s: Real) -> Self {
        let mut out = *self;
        out.scale *= s;
        out
    }
}

#[cfg(test)]
mod tests;
