//! The contacts' positions in structure-of-arrays form, and the nearest-point searches of the
//! seeding and the assignment.

use haptic_core::{Real, Vec3};

/// Contact positions in structure-of-arrays form, so that distance loops vectorise.
#[derive(Debug, Clone, Default)]
pub(crate) struct Points {
    pub(crate) x: Vec<Real>,
    pub(crate) y: Vec<Real>,
    pub(crate) z: Vec<Real>,
}

impl Points {
    pub(crate) fn len(&self) -> usize {
        self.x.len()
    }

    pub(crate) fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// The point closest to `c`: (squared distance, index); ties go to the lowest index.
    pub(crate) fn closest(&self, c: &Vec3) -> (Real, usize) {
        let n = self.x.len();
        let (x, y, z) = (&self.x[..n], &self.y[..n], &self.z[..n]);
        let mut best = (Real::INFINITY, usize::MAX);
        for i in 0..n {
            let (dx, dy, dz) = (x[i] - c.x, y[i] - c.y, z[i] - c.z);
            let d = dx * dx + dy * dy + dz * dz;
            if d < best.0 {
                best = (d, i);
            }
        }
        best
    }

    /// `out[i] = |p_i − c|²` for every point.
    pub(crate) fn distances_squared(&self, c: &Vec3, out: &mut [Real]) {
        let n = out.len();
        let (x, y, z) = (&self.x[..n], &self.y[..n], &self.z[..n]);
        for i in 0..n {
            let (dx, dy, dz) = (x[i] - c.x, y[i] - c.y, z[i] - c.z);
            out[i] = dx * dx + dy * dy + dz * dz;
        }
    }
}

/// The arg-min of a row over the entries not `taken` (ties: lowest index), or `usize::MAX`.
pub(crate) fn closest_free(row: &[Real], taken: &[bool]) -> (Real, usize) {
    let mut best = (Real::INFINITY, usize::MAX);
    for (i, (&d2, &t)) in row.iter().zip(taken).enumerate() {
        if !t && d2 < best.0 {
            best = (d2, i);
        }
    }
    best
}
