//! The hand motion of the free-space study: the built-in strokes (minimum-jerk sub-movements
//! plus tremor), and any motion read from a recording in the replay format.

use std::path::Path;

use anyhow::{Context, bail};
use haptic_core::{Device, DeviceLimits, DeviceState, Pose, Real, Twist, Vec3};
use haptic_device::{Recorder, ReplayDevice, ScriptedDevice, min_jerk};
use nalgebra::UnitQuaternion;

use super::RATE_HZ;

/// One minimum-jerk sub-movement (Flash & Hogan 1985): starts at `t0_s`, lasts `dur_s`, moves the
/// handle by `d_m` (m, world) and turns it by the rotation vector `phi_rad` (rad, world).
struct SubMovement {
    t0_s: Real,
    dur_s: Real,
    d_m: [Real; 3],
    phi_rad: [Real; 3],
}

/// The hand motion: overlapping point-to-point strokes of 5–9 cm and 0.6–0.9 rad (after the
/// gains below), each a minimum-jerk profile, so that the hand reverses and turns several times;
/// peak speed about 0.5 m/s and peak angular speed about 5 rad/s. Plus a physiological tremor of 0.2 mm / 9 Hz and
/// 3 mrad / 7 Hz.
const STROKES: [SubMovement; 7] = [
    SubMovement {
        t0_s: 0.10,
        dur_s: 0.40,
        d_m: [0.10, 0.02, 0.00],
        phi_rad: [0.0, 0.0, 0.8],
    },
    SubMovement {
        t0_s: 0.40,
        dur_s: 0.35,
        d_m: [-0.06, 0.05, 0.03],
        phi_rad: [0.6, 0.0, -0.5],
    },
    SubMovement {
        t0_s: 0.75,
        dur_s: 0.30,
        d_m: [-0.05, -0.08, 0.01],
        phi_rad: [0.0, -0.9, 0.3],
    },
    SubMovement {
        t0_s: 1.00,
        dur_s: 0.40,
        d_m: [0.03, 0.02, -0.08],
        phi_rad: [-0.5, 0.4, 0.0],
    },
    SubMovement {
        t0_s: 1.35,
        dur_s: 0.30,
        d_m: [0.07, 0.00, 0.04],
        phi_rad: [0.2, 0.0, 0.8],
    },
    SubMovement {
        t0_s: 1.65,
        dur_s: 0.35,
        d_m: [-0.08, 0.03, 0.00],
        phi_rad: [0.0, 0.8, -0.6],
    },
    SubMovement {
        t0_s: 2.00,
        dur_s: 0.35,
        d_m: [0.02, -0.06, 0.03],
        phi_rad: [-0.7, -0.3, 0.2],
    },
];

/// Scales the strokes' displacements so that the peak hand speed is about 0.5 m/s.
const LINEAR_GAIN: Real = 0.85;
/// Scales the strokes' rotations so that the peak angular speed is about 5 rad/s.
const ANGULAR_GAIN: Real = 0.84;

/// The handle's pose and twist at `t_s`, starting at the origin with identity orientation.
pub(crate) fn hand_at(t_s: Real) -> (Vec3, UnitQuaternion<Real>, Vec3, Vec3) {
    use std::f64::consts::TAU;
    let mut p = Vec3::zeros();
    let mut v = Vec3::zeros();
    let mut q = UnitQuaternion::identity();
    let mut w = Vec3::zeros();
    for s in &STROKES {
        // The minimum-jerk profile of the library, in the stroke's own time.
        let (a, da_ds, _) = min_jerk((t_s - s.t0_s) / s.dur_s);
        let da = da_ds / s.dur_s;
        let d = Vec3::from(s.d_m) * LINEAR_GAIN;
        p += d * a;
        v += d * da;
        // q ← exp(φ s) q: ω ← exp(φ s) ω + φ ds (fixed world axis per stroke).
        let phi = Vec3::from(s.phi_rad) * ANGULAR_GAIN;
        let e = UnitQuaternion::from_scaled_axis(phi * a);
        q = e * q;
        w = e * w + phi * da;
    }
    // Tremor.
    let (ft, fr) = (9.0 * TAU, 7.0 * TAU);
    let amp = 2e-4;
    p += Vec3::new((ft * t_s).sin(), (1.1 * ft * t_s).cos() - 1.0, 0.0) * amp;
    v += Vec3::new(
        ft * (ft * t_s).cos(),
        -1.1 * ft * (1.1 * ft * t_s).sin(),
        0.0,
    ) * amp;
    let (ang, dang) = (3e-3 * (fr * t_s).sin(), 3e-3 * fr * (fr * t_s).cos());
    let axis = Vec3::new(1.0, 1.0, 0.0).normalize();
    q = UnitQuaternion::from_scaled_axis(axis * ang) * q;
    w = UnitQuaternion::from_scaled_axis(axis * ang) * w + axis * dang;
    (p, q, v, w)
}

/// Duration of the built-in motion (s).
pub(crate) const BUILT_IN_DURATION_S: Real = 2.5;

/// Writes the built-in motion to `path` as a recording (the replay format of
/// `haptic_device::record`), sampled at [`RATE_HZ`] from 0 to [`BUILT_IN_DURATION_S`].
pub(crate) fn write_built_in(path: &Path) -> anyhow::Result<()> {
    let limits = DeviceLimits::new(0.0, 0.0, Vec3::repeat(-1.0), Vec3::repeat(1.0), RATE_HZ)?;
    let hand = ScriptedDevice::from_fn_with_twist(
        |t| {
            let (p, q, v, w) = hand_at(t);
            (
                Pose {
                    position: p,
                    orientation: q,
                },
                Twist {
                    linear: v,
                    angular: w,
                },
            )
        },
        limits,
    )
    .with_name("free-space study hand (built in)");
    let mut rec = Recorder::create(hand, path)?;
    let steps = (BUILT_IN_DURATION_S * RATE_HZ).round() as usize;
    for n in 0..=steps {
        rec.read(n as Real / RATE_HZ)?;
    }
    rec.finish()?;
    Ok(())
}

/// Reads a recording and samples it at [`RATE_HZ`] over its time span (interpolating between
/// rows, as a replay does), from its first row's time shifted to 0.
///
/// # Errors
/// An unreadable or malformed recording, or one shorter than 0.5 s.
pub(crate) fn read(path: &Path) -> anyhow::Result<Vec<DeviceState>> {
    let mut replay =
        ReplayDevice::open(path).with_context(|| format!("reading {}", path.display()))?;
    let (t0, t1) = replay.time_span_s();
    if t1 - t0 < 0.5 || (t1 - t0).is_nan() {
        bail!(
            "{}: {:.3} s of motion; the study needs at least 0.5 s",
            path.display(),
            t1 - t0
        );
    }
    let steps = ((t1 - t0) * RATE_HZ + 1e-9).floor() as usize;
    let mut out = Vec::with_capacity(steps + 1);
    for n in 0..=steps {
        let mut s = replay.read(t0 + n as Real / RATE_HZ)?;
        s.timestamp_s -= t0;
        out.push(s);
    }
    Ok(out)
}

/// Peak linear and angular speed of a motion.
pub(crate) fn peak_speeds(traj: &[DeviceState]) -> (Real, Real) {
    traj.iter().fold((0.0, 0.0), |(v, w), d| {
        (
            Real::max(v, d.twist.linear.norm()),
            Real::max(w, d.twist.angular.norm()),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn committed_motion_is_the_built_in_one() {
        let committed = read(&super::super::default_trajectory()).unwrap();
        assert_eq!(
            committed.len(),
            (BUILT_IN_DURATION_S * RATE_HZ) as usize + 1
        );
        for (n, d) in committed.iter().enumerate() {
            let t = n as Real / RATE_HZ;
            let (p, q, v, w) = hand_at(t);
            assert!((d.pose.position - p).norm() < 1e-12, "t = {t}");
            assert!(d.pose.orientation.angle_to(&q) < 1e-9, "t = {t}");
            assert!((d.twist.linear - v).norm() < 1e-9, "t = {t}");
            assert!((d.twist.angular - w).norm() < 1e-9, "t = {t}");
        }
    }

    #[test]
    fn twist_is_the_derivative_of_the_pose() {
        let h = 1e-6;
        for i in 0..250 {
            let t = 0.01 * i as Real;
            let (_, _, v, w) = hand_at(t);
            let (p1, q1, _, _) = hand_at(t + h);
            let (pm, qm, _, _) = hand_at(t - h);
            assert!(((p1 - pm) / (2.0 * h) - v).norm() < 1e-6, "t = {t}");
            let w_fd = (q1 * qm.inverse()).scaled_axis() / (2.0 * h);
            assert!(
                (w_fd - w).norm() < 1e-5 * (1.0 + w.norm()),
                "t = {t}: {w_fd} vs {w}"
            );
        }
    }

    #[test]
    fn a_short_recording_is_refused() {
        let dir = tempdir();
        let path = dir.join("short.csv");
        let limits =
            DeviceLimits::new(0.0, 0.0, Vec3::repeat(-1.0), Vec3::repeat(1.0), RATE_HZ).unwrap();
        let mut rec =
            Recorder::create(ScriptedDevice::from_fn(|_| Pose::identity(), limits), &path).unwrap();
        for n in 0..100 {
            rec.read(n as Real / RATE_HZ).unwrap();
        }
        rec.finish().unwrap();
        assert!(
            read(&path)
                .unwrap_err()
                .to_string()
                .contains("at least 0.5 s")
        );
    }

    /// A fresh folder under the system's temporary directory.
    pub(crate) fn tempdir() -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "haptic-free-space-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }
}
