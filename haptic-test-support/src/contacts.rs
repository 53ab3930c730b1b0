//! Contact sets to cluster.

use haptic_core::{Contact, Real, Vec3};

/// `n` contacts of a patch like a spoon on a cup wall, at frame `t`: points on a 2 cm × 1 cm
/// curved strip drifting by 10 µm per frame, normals tilting with the strip, depths varying
/// smoothly between 0 and 0.6 mm. The clustering benches and tests use it.
pub fn drifting_patch(t: usize, n: usize) -> Vec<Contact> {
    (0..n)
        .map(|i| {
            let u = (i as Real * 0.618_034).fract();
            let v = (i as Real * 0.414_214).fract();
            let x = 0.02 * u + 1e-5 * t as Real;
            let y = 0.01 * v;
            let p = Vec3::new(x, y, 0.002 * (30.0 * x).sin());
            let n = Vec3::new(-0.06 * (30.0 * x).cos(), 0.0, 1.0).normalize();
            let d = 3e-4 * (1.0 + (200.0 * x + 100.0 * y).sin());
            Contact::new(p, p, p - d * n, n, d).expect("finite, unit normal")
        })
        .collect()
}
