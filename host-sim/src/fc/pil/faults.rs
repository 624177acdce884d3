//! Fault injection into the host → firmware stream during the flight (not the
//! start-up): frames dropped or corrupted (one payload byte flipped: a CRC
//! error) at given rates, and the lockstep trigger (HIL_SENSOR) of every n-th
//! step lost, all drawn from a seeded RNG.
//!
//! May import: rand, [`super::telemetry`] (the counters in the PIL figures).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::telemetry::PilFigures;

/// Faults injected into the host → firmware stream during the flight (not the start-up).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultInjection {
    /// Probability that a frame other than HIL_SENSOR is sent with one payload byte flipped (CRC error).
    pub corrupt_rate: f64,
    /// Probability that a frame other than HIL_SENSOR is not sent at all.
    pub drop_rate: f64,
    /// Lose the HIL_SENSOR of every n-th flight step (the host must time out and re-send it).
    pub lose_trigger_every: Option<u64>,
    /// Seed of the injection draws.
    pub seed: u64,
}

/// The injector of a link: the settings and their RNG.
pub(super) struct Injector {
    cfg: FaultInjection,
    rng: ChaCha8Rng,
}

impl Injector {
    pub(super) fn new(cfg: FaultInjection) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        Injector { cfg, rng }
    }

    /// The bytes to send for the queued `frames`: with `inject`, some dropped or corrupted
    /// (counted in `fig`); every frame sent is counted in `fig.frames_sent`.
    pub(super) fn frames(&mut self, frames: Vec<Vec<u8>>, inject: bool, fig: &mut PilFigures) -> Vec<u8> {
        let mut out = Vec::new();
        for mut f in frames {
            if inject && self.cfg.drop_rate > 0.0 && self.rng.random::<f64>() < self.cfg.drop_rate {
                fig.injected_dropped += 1;
                continue;
            }
            if inject && self.cfg.corrupt_rate > 0.0 && self.rng.random::<f64>() < self.cfg.corrupt_rate {
                // Flip one payload byte (header is 10 bytes, CRC the last 2): a CRC error.
                let n = f.len();
                let i = 10 + self.rng.random_range(0..(n - 12).max(1));
                f[i.min(n - 3)] ^= 0x5A;
                fig.injected_corrupted += 1;
            }
            out.extend_from_slice(&f);
            fig.frames_sent += 1;
        }
        out
    }

    /// `true` when the trigger of flight step `step` (1-based) is to be lost.
    pub(super) fn lose_trigger(&self, inject: bool, step: u64) -> bool {
        inject && self.cfg.lose_trigger_every.is_some_and(|n| n > 0 && step.is_multiple_of(n))
    }
}
