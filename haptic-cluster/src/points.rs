//! The contacts' positions in structure-of-arrays form, for the seeding's distance rows.

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
