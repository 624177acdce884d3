//! State shared between tasks of different priorities, through critical-section mutexes (no
//! `static mut`): the cascade (one instance, used by the inner loop, the outer loop and the link)
//! and small `Copy` reports (loop timing) published by one task and read by another.
//!
//! Each access holds a critical section for the duration of one cascade call, so a lower-priority
//! caller delays the inner loop by at most one such call (the outer step is the longest; its
//! execution time is reported in `LOOP_OUT.z`).

use core::cell::{Cell, RefCell};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::Vec3;

use crate::app::autopilot::{
    Autopilot, CommandRejected, ImuSample, MotorCommand, ParamRejected, PathRejected, PositionFix,
    TelemetrySnapshot, VehicleCommand,
};

/// An [`Autopilot`] behind a critical-section mutex, installed once at start-up.
pub struct SharedAutopilot<A> {
    inner: Mutex<CriticalSectionRawMutex, RefCell<Option<A>>>,
}

impl<A> Default for SharedAutopilot<A> {
    fn default() -> Self {
        Self::new()
    }
}

impl<A> SharedAutopilot<A> {
    /// Empty (every call gets the safe default until [`SharedAutopilot::install`]).
    pub const fn new() -> Self {
        Self { inner: Mutex::new(RefCell::new(None)) }
    }

    /// Installs (or replaces) the autopilot.
    pub fn install(&self, a: A) {
        self.inner.lock(|c| {
            if let Ok(mut slot) = c.try_borrow_mut() {
                *slot = Some(a);
            }
        });
    }

    /// Runs `f` on the autopilot inside a critical section; `None` before installation.
    pub fn with<R>(&self, f: impl FnOnce(&mut A) -> R) -> Option<R> {
        self.inner.lock(|c| c.try_borrow_mut().ok().and_then(|mut slot| slot.as_mut().map(f)))
    }

    /// A handle implementing [`Autopilot`].
    pub fn handle(&self) -> SharedHandle<'_, A> {
        SharedHandle(self)
    }
}

/// [`Autopilot`] view of a [`SharedAutopilot`]: every call locks for its own duration. Before
/// installation: motors off, commands refused, [`TelemetrySnapshot::BOOT`].
pub struct SharedHandle<'a, A>(&'a SharedAutopilot<A>);

impl<A: Autopilot> Autopilot for SharedHandle<'_, A> {
    fn step_inner(&mut self, now_us: u64, imu: &ImuSample) -> MotorCommand {
        self.0.with(|a| a.step_inner(now_us, imu)).unwrap_or(MotorCommand::OFF)
    }
    fn step_outer(&mut self, now_us: u64) {
        self.0.with(|a| a.step_outer(now_us));
    }
    fn update_position(&mut self, fix: &PositionFix) {
        self.0.with(|a| a.update_position(fix));
    }
    fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        self.0.with(|a| a.update_obstacles(now_us, obstacles));
    }
    fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected> {
        self.0.with(|a| a.set_path(waypoints_ned)).unwrap_or(Err(PathRejected::Invalid))
    }
    fn command(&mut self, now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
        self.0.with(|a| a.command(now_us, cmd)).unwrap_or(Err(CommandRejected::NotNow))
    }
    fn telemetry(&self) -> TelemetrySnapshot {
        self.0.with(|a| a.telemetry()).unwrap_or(TelemetrySnapshot::BOOT)
    }
    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        self.0.with(|a| a.set_param(name, value)).unwrap_or(Err(ParamRejected::NotNow))
    }
    fn get_param(&self, name: &str) -> Option<f32> {
        self.0.with(|a| a.get_param(name)).flatten()
    }
}

/// A `Copy` value published by one task and read by others.
pub struct SharedCell<T: Copy> {
    inner: Mutex<CriticalSectionRawMutex, Cell<T>>,
}

impl<T: Copy> SharedCell<T> {
    /// A cell holding `v`.
    pub const fn new(v: T) -> Self {
        Self { inner: Mutex::new(Cell::new(v)) }
    }
    /// Current value.
    pub fn get(&self) -> T {
        self.inner.lock(|c| c.get())
    }
    /// Replaces the value.
    pub fn set(&self, v: T) {
        self.inner.lock(|c| c.set(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;

    #[test]
    fn defaults_before_install_then_forwards() {
        let s: SharedAutopilot<RecordingAutopilot> = SharedAutopilot::new();
        let mut h = s.handle();
        let imu = ImuSample { gyro_frd: Vec3::zeros(), accel_frd: Vec3::zeros() };
        assert_eq!(h.step_inner(1, &imu), MotorCommand::OFF);
        assert_eq!(h.command(1, VehicleCommand::Arm), Err(CommandRejected::NotNow));
        assert_eq!(h.telemetry(), TelemetrySnapshot::BOOT);
        s.install(RecordingAutopilot::new());
        assert_eq!(h.command(1, VehicleCommand::Arm), Ok(()));
        assert!(h.step_inner(2, &imu).armed);
        assert_eq!(s.with(|a| a.inner_steps.clone()), Some(vec![2]));
        let c = SharedCell::new(3u32);
        c.set(4);
        assert_eq!(c.get(), 4);
    }
}
