//! The [`CollisionBackend`] trait: tool geometry against static obstacles.

use crate::contact::ContactSet;
use crate::error::CoreError;
use crate::math::Real;
use crate::state::Pose;

/// What a query asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueryParams {
    /// Distance tolerance `δ` (m): report every pair of features closer than this, including
    /// pre-contacts that do not yet touch.
    pub delta_m: Real,
    /// Accuracy knob: the largest acceptable surface deviation, as a fraction of the tool's
    /// bounding radius (the paper used 0.025, 0.01 and 0.004). `0` asks for exact contacts. A
    /// back-end without levels of detail may ignore it.
    pub error_threshold: Real,
}

impl QueryParams {
    /// Validated parameters.
    ///
    /// # Errors
    /// [`CoreError::OutOfRange`] if `delta_m` is not positive and finite or `error_threshold` is
    /// negative or not finite.
    pub fn new(delta_m: Real, error_threshold: Real) -> Result<Self, CoreError> {
        let params = Self {
            delta_m,
            error_threshold,
        };
        params.validate()?;
        Ok(params)
    }

    /// Checks the fields (they are public, so a back-end re-checks what it is given).
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] naming `query.delta_m` (must be
    /// positive and finite) or `query.error_threshold` (non-negative and finite).
    pub fn validate(&self) -> Result<(), CoreError> {
        crate::check::positive("query.delta_m", self.delta_m)?;
        crate::check::non_negative("query.error_threshold", self.error_threshold)?;
        Ok(())
    }
}

/// What a query cost, for telemetry and benchmarks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QueryStats {
    /// Whether the broad phase found anything within `δ` (if not, nothing else was done).
    pub broad_phase_hit: bool,
    /// Bounding-volume (or hierarchy-node) pairs tested.
    pub node_pairs_tested: u64,
    /// Primitive (triangle or convex-piece) pairs tested exactly.
    pub primitive_pairs_tested: u64,
    /// Contacts found before the back-end compacted them into the ones it wrote; 0 when it
    /// does not compact (then the contacts written are all it found).
    pub raw_contacts: u64,
}

/// Tool geometry against static obstacles (Section VI-A).
///
/// The back-end owns the tool's geometry, expressed in the tool's **body frame** (origin at the
/// centre of mass, the frame whose pose is [`crate::ToolState::pose`]), and the obstacles'
/// geometry in the world frame. A query places the tool at `tool_pose` and writes into `out`
/// (after clearing it) every contact within `params.delta_m`, as [`crate::Contact`] defines it:
/// `p_a` on the tool and `r_a` the same point in the body frame, `p_b` on the obstacle, `n` unit
/// and pointing out of the tool, `depth_m` positive inside and down to `−δ` outside. A back-end
/// may instead write fewer contacts that stand for those (merged region by region, each with
/// the tool area `area_m2` it stands for, as `haptic-collision`'s `LodBackend` does), and then
/// says how many it found in [`QueryStats::raw_contacts`].
///
/// Contract for implementers:
/// - Reuse `out`'s allocation; allocate as little as possible per query.
/// - Run a cheap broad phase first, so that a tool far from everything costs almost nothing.
/// - Never panic on a bad pose: return an error.
/// - `query` takes `&mut self` so that a back-end can keep temporal coherence (last query's
///   front) between calls.
pub trait CollisionBackend {
    /// The back-end's error type.
    type Error: std::error::Error + Send + Sync + 'static;

    /// A short identifier, e.g. `"lod"` or `"parry"`.
    fn name(&self) -> &str;

    /// Radius (m) of the sphere about the tool's body origin that encloses the tool; error
    /// thresholds are fractions of it.
    fn tool_bounding_radius_m(&self) -> Real;

    /// Contacts between the tool at `tool_pose` and the obstacles.
    ///
    /// # Errors
    /// Back-end specific; at least a non-finite pose must give an error.
    fn query(
        &mut self,
        tool_pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, Self::Error>;

    /// The error threshold (a fraction of [`CollisionBackend::tool_bounding_radius_m`]) that a
    /// query at `params` holds: at most `params.error_threshold`, and less where the back-end
    /// bounds its error more tightly than asked (`haptic-collision`'s `LodBackend` never lets a
    /// piece lie farther than `δ` from its surface under its default stopping rule, so above
    /// `δ / radius` a larger threshold changes nothing). A contact stage reports it as each
    /// update's threshold, and a time budget asks for no coarser threshold than the largest one
    /// it can reach. The default, `params.error_threshold`, suits a back-end that reads the
    /// threshold as asked or not at all.
    fn threshold_reached(&self, params: &QueryParams) -> Real {
        params.error_threshold
    }
}

impl<B: CollisionBackend + ?Sized> CollisionBackend for &mut B {
    type Error = B::Error;
    fn name(&self) -> &str {
        (**self).name()
    }
    fn tool_bounding_radius_m(&self) -> Real {
        (**self).tool_bounding_radius_m()
    }
    fn query(
        &mut self,
        tool_pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, Self::Error> {
        (**self).query(tool_pose, params, out)
    }
    fn threshold_reached(&self, params: &QueryParams) -> Real {
        (**self).threshold_reached(params)
    }
}

impl<B: CollisionBackend + ?Sized> CollisionBackend for Box<B> {
    type Error = B::Error;
    fn name(&self) -> &str {
        (**self).name()
    }
    fn tool_bounding_radius_m(&self) -> Real {
        (**self).tool_bounding_radius_m()
    }
    fn query(
        &mut self,
        tool_pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, Self::Error> {
        (**self).query(tool_pose, params, out)
    }
    fn threshold_reached(&self, params: &QueryParams) -> Real {
        (**self).threshold_reached(params)
    }
}
