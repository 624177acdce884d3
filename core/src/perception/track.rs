//! Velocity of small moving clusters: segments of a scan → α-β tracks of their centroids.
//!
//! **Segments.** The returns of one scan row (the row nearest to horizontal, in beam order)
//! are cut into segments wherever two consecutive returns are more than [`SEGMENT_GAP`]
//! voxels apart (or a beam has no return). A segment whose extent (the diagonal of its
//! returns' bounding box) is at most `track_size` is a *cluster* (a person, a pole, a
//! drone); larger segments are walls and stay static. At most [`MAX_SEGMENTS`] clusters
//! per scan are tracked (the rest are stored as static cells).
//!
//! **Tracks.** [`MAX_TRACKS`] slots. A cluster takes the free-or-matching track whose
//! predicted centroid `x + v·dt` is nearest and within `track_gate`; otherwise it opens a
//! new track (replacing the track updated longest ago when all are in use). Update with the
//! α-β filter (residual `e = c − (x + v·dt)`): `x ← x + v·dt + α e`, `v ← v + (β/dt) e`, with
//! `β = α²/(2 − α)` (Benedict–Bordner, critically damped). A track not updated for
//! `forget_s` is freed.
//!
//! **Convergence.** For a cluster moving at constant velocity `w`, sampled every `dt`, the
//! error `(x − c, v − w)` obeys a linear recursion with characteristic polynomial
//! `z² − (2 − α − β) z + (1 − α)`; for α = 0.5 (β = 1/6) its roots are a complex pair of
//! modulus `√(1 − α)` = 0.71, so the velocity error of a new track (which starts at `|w|`)
//! decays as 0.71ᵏ: a few per cent of `|w|` after 10 updates (1 s at 10 Hz). With centroid
//! noise σ per scan the steady velocity error has standard deviation
//! `σ/dt · √(2β²/(α(4 − 2α − β)))` ≈ 0.2 σ/dt (Kalata). Measured (`track_velocity_converges`,
//! 256 seeded cases, 1 m/s, centroid noise uniform ±2 cm, 10 Hz): the worst velocity error
//! is below 0.25 m/s after 10 updates and below 0.12 m/s after 30.
//! A track's velocity is handed out after [`CONFIRM`] updates and only when faster than
//! [`STATIC_SPEED`] (slower clusters are static: `velocity: None`).
//!
//! May import: `crate::Vec3`.

use crate::Vec3;

/// Track slots.
pub const MAX_TRACKS: usize = 8;
/// Clusters tracked per scan.
pub const MAX_SEGMENTS: usize = 8;
/// Consecutive returns farther apart than this many voxels start a new segment.
pub const SEGMENT_GAP: f32 = 2.0;
/// Updates before a track's velocity is used.
pub const CONFIRM: u16 = 3;
/// Tracks slower than this are static, m/s.
pub const STATIC_SPEED: f32 = 0.2;

/// One tracked cluster.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Track {
    /// Filtered centroid, NED, m.
    pub position: Vec3,
    /// Filtered velocity, NED, m/s.
    pub velocity: Vec3,
    /// Time of the last update, µs.
    pub t_us: u64,
    /// Updates so far (saturating).
    pub updates: u16,
}

impl Track {
    /// The velocity the filter may use: after [`CONFIRM`] updates and above [`STATIC_SPEED`].
    pub fn measured_velocity(&self) -> Option<Vec3> {
        (self.updates >= CONFIRM && self.velocity.norm_squared() > STATIC_SPEED * STATIC_SPEED)
            .then_some(self.velocity)
    }
}

/// The track slots.
#[derive(Clone, Debug)]
pub struct Tracker {
    slots: [Option<Track>; MAX_TRACKS],
}

impl Default for Tracker {
    fn default() -> Self {
        Self::new()
    }
}

impl Tracker {
    /// No tracks.
    pub const fn new() -> Self {
        Tracker { slots: [None; MAX_TRACKS] }
    }

    /// Track in slot `i`.
    pub fn get(&self, i: usize) -> Option<&Track> {
        self.slots.get(i).and_then(|s| s.as_ref())
    }

    /// Frees tracks not updated since `t_us − forget_us`.
    pub fn expire(&mut self, t_us: u64, forget_us: u64) {
        for s in self.slots.iter_mut() {
            if s.is_some_and(|tr| t_us.saturating_sub(tr.t_us) > forget_us) {
                *s = None;
            }
        }
    }

    /// Assigns the cluster centroid `c` seen at `t_us` to a track and updates it; returns
    /// the slot. `taken`: slots already updated by this scan (not eligible). O([`MAX_TRACKS`]).
    pub fn update(&mut self, c: &Vec3, t_us: u64, alpha: f32, gate: f32, taken: u16) -> usize {
        let beta = alpha * alpha / (2.0 - alpha);
        let mut best: Option<(usize, f32)> = None;
        for (i, s) in self.slots.iter().enumerate() {
            let Some(tr) = s else { continue };
            if taken & (1 << i) != 0 || t_us <= tr.t_us {
                continue;
            }
            let dt = (t_us - tr.t_us) as f32 * 1e-6;
            let d = (tr.position + tr.velocity * dt - c).norm();
            if d <= gate && best.is_none_or(|(_, bd)| d < bd) {
                best = Some((i, d));
            }
        }
        if let Some((i, _)) = best {
            if let Some(Some(tr)) = self.slots.get_mut(i) {
                let dt = (t_us - tr.t_us) as f32 * 1e-6;
                let pred = tr.position + tr.velocity * dt;
                let e = c - pred;
                tr.position = pred + e * alpha;
                tr.velocity += e * (beta / dt);
                tr.t_us = t_us;
                tr.updates = tr.updates.saturating_add(1);
            }
            return i;
        }
        // New track: a free slot, else the one updated longest ago (not taken this scan).
        let mut slot = 0usize;
        let mut oldest = u64::MAX;
        for (i, s) in self.slots.iter().enumerate() {
            match s {
                None => {
                    slot = i;
                    break;
                }
                Some(tr) if taken & (1 << i) == 0 && tr.t_us < oldest => {
                    oldest = tr.t_us;
                    slot = i;
                }
                _ => {}
            }
        }
        if let Some(s) = self.slots.get_mut(slot) {
            *s = Some(Track { position: *c, velocity: Vec3::zeros(), t_us, updates: 1 });
        }
        slot
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*, fixed seed: uniform samples for the seeded cases.
    struct Rng(u64);
    impl Rng {
        fn gen_range(&mut self, r: core::ops::Range<f32>) -> f32 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let u = (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32;
            r.start + (r.end - r.start) * u
        }
    }

    /// A cluster at 1 m/s (random direction), centroid noise ±2 cm uniform (σ ≈ 1.2 cm),
    /// 10 Hz: after 10 updates the velocity error is below 0.25 m/s, after 30 below 0.12 m/s
    /// on every one of 256 seeded cases.
    #[test]
    fn track_velocity_converges() {
        let mut rng = Rng(0x19_19_19_19);
        let mut worst10 = 0.0f32;
        let mut worst30 = 0.0f32;
        for _ in 0..256 {
            let a: f32 = rng.gen_range(0.0..core::f32::consts::TAU);
            let w = Vec3::new(libm::cosf(a), libm::sinf(a), 0.0);
            let x0 = Vec3::new(rng.gen_range(-5.0..5.0), rng.gen_range(-5.0..5.0), -1.0);
            let mut t = Tracker::new();
            for k in 0..31u64 {
                let tk = 1_000_000 + k * 100_000;
                let n = Vec3::new(rng.gen_range(-0.02..0.02), rng.gen_range(-0.02..0.02), 0.0);
                let c = x0 + w * (k as f32 * 0.1) + n;
                let i = t.update(&c, tk, 0.5, 0.5, 0);
                assert_eq!(i, 0, "one cluster keeps one track");
                let err = (t.get(0).unwrap().velocity - w).norm();
                if k == 10 {
                    worst10 = worst10.max(err);
                }
                if k == 30 {
                    worst30 = worst30.max(err);
                }
            }
        }
        assert!(worst10 < 0.25, "after 10 updates: {worst10}");
        assert!(worst30 < 0.12, "after 30 updates: {worst30}");
    }

    #[test]
    fn gate_separates_clusters_and_full_slots_recycle_the_oldest() {
        let mut t = Tracker::new();
        for i in 0..MAX_TRACKS {
            let c = Vec3::new(i as f32 * 2.0, 0.0, 0.0);
            assert_eq!(t.update(&c, 1_000 + i as u64, 0.5, 0.5, 0), i);
        }
        // Far from every track: replaces slot 0 (updated longest ago).
        assert_eq!(t.update(&Vec3::new(100.0, 0.0, 0.0), 10_000, 0.5, 0.5, 0), 0);
        assert_eq!(t.get(0).unwrap().updates, 1);
        // Near track 3 but taken this scan: a new track instead.
        let s = t.update(&Vec3::new(6.1, 0.0, 0.0), 20_000, 0.5, 0.5, 1 << 3);
        assert_ne!(s, 3);
        t.expire(20_000 + 5_000_000, 4_000_000);
        assert!((0..MAX_TRACKS).all(|i| t.get(i).is_none()));
    }
}
