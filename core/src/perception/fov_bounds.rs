//! A scan's beam lattice as tangent bounds (azimuth, elevation), for the memory's
//! see-through clearing: a cell whose direction is outside the lattice's angles by more than
//! [`FovBounds::SPARE`] has no nearest beam, found without the two `atan2f` of the exact test
//! ([`ScanGeometry::nearest_beam`]; most cells are outside a camera's fan or a planar lidar's
//! plane). A shortcut only: the exact test decides everything else.
//!
//! May import: the parent module (`ScanGeometry`), `crate::fmath`, `crate::Vec3`.

use super::ScanGeometry;
use crate::fmath::hypotf;
use crate::Vec3;

/// Tangents of a scan's beam-lattice bounds, widened by [`FovBounds::SPARE`]: a direction
/// outside them has no nearest beam (the `round` of `beam_clears` leaves the lattice), found
/// without its two `atan2f` (most cells are outside a camera's or a planar lidar's beams).
/// A bound is `None` where the lattice wraps or reaches within 0.01 rad of ±π/2.
pub(super) struct FovBounds {
    az: Option<(f32, f32)>,
    el: Option<(f32, f32)>,
}

impl FovBounds {
    /// Rad: far above the `f32` round-off of the angles compared (≈ 1e-7 rad).
    const SPARE: f32 = 1e-3;

    pub(super) fn of(g: &ScanGeometry) -> Self {
        let tan_bounds = |lo: f32, hi: f32| {
            let (lo, hi) = (lo - Self::SPARE, hi + Self::SPARE);
            let edge = core::f32::consts::FRAC_PI_2 - 0.01;
            (lo > -edge && hi < edge).then(|| (libm::tanf(lo), libm::tanf(hi)))
        };
        let span = |first: f32, step: f32, n: u16| (first - 0.5 * step, first + (f32::from(n) - 0.5) * step);
        let (a0, a1) = span(g.az0, g.daz, g.n_az);
        let (e0, e1) = span(g.el0, g.del, g.n_el);
        FovBounds { az: if g.wraps() { None } else { tan_bounds(a0, a1) }, el: tan_bounds(e0, e1) }
    }

    /// The sensor-frame direction `q` is outside the lattice's angles (azimuth
    /// `atan2(q.y, q.x)`, elevation `atan2(−q.z, |q_xy|)`) by more than the spare.
    pub(super) fn surely_outside(&self, q: &Vec3) -> bool {
        if let Some((lo, hi)) = self.az {
            // Behind (|azimuth| > π/2) or beside; q.x = 0 is left to the exact test.
            if q.x < 0.0 || (q.x > 0.0 && (q.y > q.x * hi || q.y < q.x * lo)) {
                return true;
            }
        }
        if let Some((lo, hi)) = self.el {
            let h = hypotf(q.x, q.y);
            if h > 0.0 && (-q.z > h * hi || -q.z < h * lo) {
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use proptest::test_runner::{RngAlgorithm, TestRng};

    /// The shortcut of `beam_clears` only skips directions whose nearest beam is off the
    /// lattice (the exact `atan2f`/`roundf` test), for a camera, a ToF grid, single beams,
    /// a planar and a multi-row 360° lidar; and it does skip most directions of a camera.
    #[test]
    fn the_field_of_view_shortcut_skips_only_directions_off_the_lattice() {
        let geoms = [
            ScanGeometry::grid(16, 10, 87f32.to_radians(), 58f32.to_radians(), 0.2, 6.0),
            ScanGeometry::grid(8, 8, 45f32.to_radians(), 45f32.to_radians(), 0.05, 4.0),
            ScanGeometry::grid(1, 1, 0.1, 0.1, 0.05, 4.0),
            ScanGeometry::grid(4, 1, 170f32.to_radians(), 0.05, 0.05, 4.0),
            ScanGeometry::planar_360(72, 0.05, 0.1, 12.0),
            ScanGeometry {
                n_el: 16,
                del: 0.035,
                el0: -0.26,
                ..ScanGeometry::planar_360(360, 0.0, 0.1, 12.0)
            },
        ];
        let mut rng = TestRng::from_seed(RngAlgorithm::ChaCha, &[21; 32]);
        for (gi, g) in geoms.iter().enumerate() {
            let fov = FovBounds::of(g);
            let mut skipped = 0;
            for k in 0..20_000 {
                let mut q = Vec3::new(
                    rng.random_range(-1.0f32..1.0),
                    rng.random_range(-1.0f32..1.0),
                    rng.random_range(-1.0f32..1.0),
                );
                if k % 4 == 0 {
                    // Near the lattice's edges: a beam direction nudged by up to 2 beam widths.
                    let (row, col) = (rng.random_range(0..g.n_el), rng.random_range(0..g.n_az));
                    let d = g.direction(row, col);
                    q = d
                        + Vec3::new(d.y, -d.x, 0.0) * (rng.random_range(-2.0f32..2.0) * g.daz)
                        + Vec3::new(0.0, 0.0, rng.random_range(-2.0f32..2.0) * g.del);
                }
                if !fov.surely_outside(&q) {
                    continue;
                }
                skipped += 1;
                let beam = g.nearest_beam(&q);
                assert!(beam.is_none(), "geometry {gi}: {q:?} skipped but on beam {beam:?}");
            }
            if gi == 0 {
                assert!(skipped > 10_000, "camera: {skipped} of 20 000 skipped");
            }
        }
    }
}
