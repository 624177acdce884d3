//! Loop period / execution-time measurement and overrun counting from a free-running cycle
//! counter (the DWT cycle counter on the board; any wrapping 32-bit counter works).
//!
//! A step is an **overrun** when it started more than 1.5 nominal periods after the previous
//! step (a missed tick) or when its own execution took longer than one nominal period. Each step
//! counts at most once. Periods and execution times are kept per reporting window
//! ([`LoopTimer::take_report`] starts a new window); the overrun count is cumulative.

/// One reporting window of a loop, in microseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoopReport {
    /// Mean period between step starts, µs (0 before two steps).
    pub period_mean_us: f32,
    /// Longest period, µs.
    pub period_max_us: f32,
    /// Longest execution time of one step, µs.
    pub exec_max_us: f32,
    /// Steps in the window.
    pub steps: u32,
    /// Overruns since boot (saturating).
    pub overruns: u32,
}

impl LoopReport {
    /// No step measured yet.
    pub const ZERO: Self =
        Self { period_mean_us: 0.0, period_max_us: 0.0, exec_max_us: 0.0, steps: 0, overruns: 0 };
}

/// Measures one periodic loop.
#[derive(Clone, Debug)]
pub struct LoopTimer {
    nominal_cycles: u32,
    cycles_per_us: f32,
    last_start: Option<u32>,
    current_start: u32,
    period_sum: u64,
    periods: u32,
    period_max: u32,
    exec_max: u32,
    steps: u32,
    overruns: u32,
    overrun_this_step: bool,
}

impl LoopTimer {
    /// A timer for a loop of `nominal_period_us` on a counter running at `cycles_per_us`.
    pub fn new(nominal_period_us: u32, cycles_per_us: u32) -> Self {
        Self {
            nominal_cycles: nominal_period_us.saturating_mul(cycles_per_us),
            cycles_per_us: cycles_per_us.max(1) as f32,
            last_start: None,
            current_start: 0,
            period_sum: 0,
            periods: 0,
            period_max: 0,
            exec_max: 0,
            steps: 0,
            overruns: 0,
            overrun_this_step: false,
        }
    }

    /// Call at the start of a step with the counter value.
    pub fn start(&mut self, now: u32) {
        self.overrun_this_step = false;
        if let Some(last) = self.last_start {
            let period = now.wrapping_sub(last);
            self.period_sum += u64::from(period);
            self.periods += 1;
            self.period_max = self.period_max.max(period);
            if u64::from(period) * 2 > u64::from(self.nominal_cycles) * 3 {
                self.count_overrun();
            }
        }
        self.last_start = Some(now);
        self.current_start = now;
    }

    /// Call at the end of the step with the counter value.
    pub fn end(&mut self, now: u32) {
        let exec = now.wrapping_sub(self.current_start);
        self.exec_max = self.exec_max.max(exec);
        self.steps = self.steps.saturating_add(1);
        if exec > self.nominal_cycles {
            self.count_overrun();
        }
    }

    fn count_overrun(&mut self) {
        if !self.overrun_this_step {
            self.overrun_this_step = true;
            self.overruns = self.overruns.saturating_add(1);
        }
    }

    /// Overruns since boot.
    pub fn overruns(&self) -> u32 {
        self.overruns
    }

    /// The current window's figures; starts a new window.
    pub fn take_report(&mut self) -> LoopReport {
        let r = self.report();
        self.period_sum = 0;
        self.periods = 0;
        self.period_max = 0;
        self.exec_max = 0;
        self.steps = 0;
        r
    }

    /// The current window's figures.
    pub fn report(&self) -> LoopReport {
        let us = |c: u32| c as f32 / self.cycles_per_us;
        LoopReport {
            period_mean_us: if self.periods == 0 {
                0.0
            } else {
                // f32 on purpose (no soft-float f64 on the Cortex-M4F); 24-bit mantissa is ample.
                (self.period_sum as f32 / self.periods as f32) / self.cycles_per_us
            },
            period_max_us: us(self.period_max),
            exec_max_us: us(self.exec_max),
            steps: self.steps,
            overruns: self.overruns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn period_and_overruns() {
        // 1 kHz loop on a 168 MHz counter that wraps during the test.
        let mut t = LoopTimer::new(1000, 168);
        let mut c: u32 = u32::MAX - 200_000;
        for _ in 0..10 {
            t.start(c);
            t.end(c.wrapping_add(16_800)); // 100 µs
            c = c.wrapping_add(168_000);
        }
        let r = t.report();
        assert!((r.period_mean_us - 1000.0).abs() < 0.01, "{r:?}");
        assert!((r.exec_max_us - 100.0).abs() < 0.01);
        assert_eq!(r.overruns, 0);
        // A missed tick (2 ms gap) and a step that runs 1.2 ms; the second also starts late but
        // counts once.
        c = c.wrapping_add(168_000);
        t.start(c);
        t.end(c.wrapping_add(1000));
        c = c.wrapping_add(168_000 * 2);
        t.start(c);
        t.end(c.wrapping_add(201_600));
        let r = t.take_report();
        assert_eq!(r.overruns, 2);
        assert_eq!(r.steps, 12);
        assert!((r.period_max_us - 2000.0).abs() < 0.01);
        assert_eq!(t.report().steps, 0);
        assert_eq!(t.report().overruns, 2);
    }
}
