//! A 5 cm, 100 g box over the floor `z = 0`: an analytic back-end (its corners are the contact
//! features) and a simulated hand that presses it into the floor. The runtime's tests and
//! examples of a pipeline without meshes use it.

use haptic_core::{
    CollisionBackend, Contact, ContactSet, CoreError, DeviceLimits, Pose, QueryParams, QueryStats,
    Real, RigidBody, Vec3,
};
use haptic_device::{HandDevice, HandParams, ScriptedDevice, Waypoint};

/// Half the edge of the test box (m): a 5 cm cube.
pub const HALF_M: Real = 0.025;

/// The 100 g test box, a uniform cube of edge `2 HALF_M`.
pub fn box_body() -> RigidBody {
    let i = 0.1 * (2.0 * HALF_M).powi(2) / 6.0;
    RigidBody::from_principal(0.1, [i, i, i]).unwrap()
}

/// Device limits of the tests: 10 N, 1 N m, a 1 m workspace, 1 kHz.
pub fn limits() -> DeviceLimits {
    DeviceLimits::new(10.0, 1.0, Vec3::repeat(-0.5), Vec3::repeat(0.5), 1000.0).unwrap()
}

/// A hand that lowers the box from 1 cm above the floor `z = 0` to 5 mm into it within 0.2 s,
/// and holds it there.
pub fn pressing_hand() -> HandDevice {
    let start = Pose::from_position(Vec3::new(0.0, 0.0, HALF_M + 0.01));
    let press = Pose::from_position(Vec3::new(0.0, 0.0, HALF_M - 0.005));
    let target = ScriptedDevice::from_waypoints(
        vec![Waypoint::new(0.0, start), Waypoint::new(0.2, press)],
        limits(),
    )
    .unwrap();
    HandDevice::new(HandParams::default(), target, limits()).unwrap()
}

/// A box tool (its 8 corners are the contact features) over the floor `z = 0`.
pub struct BoxOnFloor {
    /// Half the box's edges (m).
    pub half_extents_m: Vec3,
}

impl BoxOnFloor {
    /// A cube of half edge `half` (m).
    pub fn new(half: Real) -> Self {
        Self {
            half_extents_m: Vec3::repeat(half),
        }
    }

    fn corners(&self) -> [Vec3; 8] {
        let h = self.half_extents_m;
        let mut out = [Vec3::zeros(); 8];
        for (i, c) in out.iter_mut().enumerate() {
            *c = Vec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            );
        }
        out
    }
}

impl CollisionBackend for BoxOnFloor {
    type Error = CoreError;
    fn name(&self) -> &str {
        "box-on-floor"
    }
    fn tool_bounding_radius_m(&self) -> Real {
        self.half_extents_m.norm()
    }
    fn query(
        &mut self,
        pose: &Pose,
        params: &QueryParams,
        out: &mut ContactSet,
    ) -> Result<QueryStats, CoreError> {
        out.clear();
        if !pose.is_finite() {
            return Err(CoreError::NonFinite { what: "tool pose" });
        }
        if pose.position.z - self.tool_bounding_radius_m() > params.delta_m {
            return Ok(QueryStats::default());
        }
        for (i, r) in self.corners().iter().enumerate() {
            let p_a = pose.transform_point(r);
            let depth = -p_a.z;
            if depth >= -params.delta_m {
                let p_b = Vec3::new(p_a.x, p_a.y, 0.0);
                out.push(Contact::new(p_a, *r, p_b, -Vec3::z(), depth)?.with_features(i as u32, 0));
            }
        }
        Ok(QueryStats {
            broad_phase_hit: true,
            node_pairs_tested: 1,
            primitive_pairs_tested: 8,
            ..QueryStats::default()
        })
    }
}
