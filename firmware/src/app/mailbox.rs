//! How the cascade's stages exchange their messages: embassy-sync primitives instead of one
//! shared, locked controller. Each message is a small `Copy` value (`parapet_core::msg`), so a
//! critical section only ever copies one message in or out; no control computation runs with
//! interrupts masked.
//!
//! | mailbox | from → to | primitive | why |
//! |---|---|---|---|
//! | [`Mailboxes::commands`] | outer → inner | `Channel` (depth [`COMMAND_DEPTH`]) | every `AttitudeCommand` in order: taking one with the motors not flying resets the attitude controller, so none may be skipped |
//! | [`Mailboxes::aid`] | outer → inner | `Signal` | the estimator aid of the latest position fix (latest wins) |
//! | [`Mailboxes::inner_params`] | outer → inner | `Signal` | a new parameter set: the inner task rebuilds its loop itself, outside any critical section |
//! | [`Mailboxes::estimate`] | inner → outer | `Signal` | the latest `StateEstimate` (cumulative counters, sticky tilt trip: latest wins) |
//! | [`Mailboxes::nav`] | inner → outer | `Channel` (depth [`NAV_SAMPLE_DEPTH`]) | every IMU sample for the navigation filter's predict, in order ([`crate::app::navigation`]; full: the oldest go) |
//! | [`Mailboxes::snapshot`] | outer → link | `Signal` | the telemetry snapshot ([`TelemetrySnapshot`], `Copy`) |
//! | [`Mailboxes::battery`] | battery measurement → outer | `Signal` | the latest [`BatteryState`] (latest wins: the level only goes down) |
//! | [`Mailboxes::rc`] | RC receiver → outer | `Signal` | the latest receiver frame ([`RcFrame`], mapped by the outer stage with the live `RC_*` parameters; latest wins: the mode machine wants the newest sticks, and the loss timeout runs on the frames' times) |
//! | [`Mailboxes::kill`] | RC receiver → inner | `Signal` | a frame whose kill switch the mode machine will act on (its time): the inner stage stops the motors at the top of its next step |
//! | [`Mailboxes::rc_params`] | outer → RC receiver | `Signal` | the live `RC_*` parameters after a rebuild (the receiver task maps the kill channel with them) |
//! | [`Mailboxes::replan`] | outer ⇄ replanner | async `Mutex` + `Signal` | one request buffer (≈ 3 KiB, the board's, installed at boot) handed back and forth by reference, never copied: a held lock masks nothing ([`crate::app::replanner`]) |
//!
//! **The kill switch** ([`Mailboxes::deliver_rc`]): the receiver task maps each frame's kill
//! channel itself ([`kill_requested`]) and, after publishing the frame, signals
//! [`Mailboxes::kill`]; the inner stage takes it after draining the queued commands and switches
//! its loop to Off before it computes the step, so the inner step after the frame's arrival
//! outputs zero (≤ one inner period). The outer stage takes the same frame at its next wake,
//! before it publishes any command (every path that publishes takes the pending inputs first),
//! disarms for `kill-switch` and queues the Off command: the motors stay off. (Before: the frame
//! went through the outer stage only, so the motors stopped one inner step later, up to two
//! inner periods after the frame.)
//!
//! The board's link plumbing (decoded inbound messages, replies, loop reports) lives next to the
//! tasks that own it (`src/bin/fc/mod.rs`). May import: `parapet_core::msg`, `parapet_core::inner`,
//! `parapet_core::rc`, `parapet_core::battery`, `parapet_core::supervisor::modes` (the kill check),
//! [`crate::app::autopilot`], [`crate::app::replanner`] (its mailbox), [`crate::app::navigation`]
//! (its sample).

use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::channel::{Channel, TrySendError};
use embassy_sync::signal::Signal;
use parapet_core::battery::BatteryState;
use parapet_core::inner::InnerParams;
use parapet_core::msg::{AttitudeCommand, EstimatorAid, StateEstimate};
use parapet_core::rc::map::{RcFrame, RcParams};
use parapet_core::supervisor::modes::kill_requested;

use crate::app::autopilot::TelemetrySnapshot;
use crate::app::navigation::{NavSample, NAV_SAMPLE_DEPTH};
use crate::app::replanner::ReplanMailbox;

/// Attitude commands queued for the inner loop (the outer loop publishes at most two per outer
/// step; the inner loop, at higher priority, drains them every inner step).
pub const COMMAND_DEPTH: usize = 4;

/// The mailboxes between the stages (see the module docs). `M`: the raw mutex of every
/// primitive (`CriticalSectionRawMutex` between tasks of different priorities).
pub struct Mailboxes<M: RawMutex> {
    /// Outer → inner: attitude commands, in order.
    pub commands: Channel<M, AttitudeCommand, COMMAND_DEPTH>,
    /// Outer → inner: estimator aid of the latest fix.
    pub aid: Signal<M, EstimatorAid>,
    /// Outer → inner: parameters of a rebuilt inner loop.
    pub inner_params: Signal<M, InnerParams>,
    /// Inner → outer: latest state estimate.
    pub estimate: Signal<M, StateEstimate>,
    /// Inner → outer: the IMU samples for the navigation filter, in order.
    pub nav: Channel<M, NavSample, NAV_SAMPLE_DEPTH>,
    /// Outer → link: latest telemetry snapshot.
    pub snapshot: Signal<M, TelemetrySnapshot>,
    /// RC receiver → outer: latest receiver frame.
    pub rc: Signal<M, RcFrame>,
    /// Battery measurement → outer: latest battery state.
    pub battery: Signal<M, BatteryState>,
    /// RC receiver → inner: time of the latest frame with the kill switch on.
    pub kill: Signal<M, u64>,
    /// Outer → RC receiver: the live `RC_*` parameters after a rebuild.
    pub rc_params: Signal<M, RcParams>,
    /// Outer ⇄ replanner task: the replanning request.
    pub replan: ReplanMailbox<M>,
}

impl<M: RawMutex> Default for Mailboxes<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: RawMutex> Mailboxes<M> {
    /// Empty mailboxes.
    pub const fn new() -> Self {
        Self {
            commands: Channel::new(),
            aid: Signal::new(),
            inner_params: Signal::new(),
            estimate: Signal::new(),
            nav: Channel::new(),
            snapshot: Signal::new(),
            rc: Signal::new(),
            battery: Signal::new(),
            kill: Signal::new(),
            rc_params: Signal::new(),
            replan: ReplanMailbox::new(),
        }
    }

    /// A receiver frame, mapped with `p` (the receiver task's copy of the live `RC_*`
    /// parameters): published to the outer stage, then, when its kill switch is one the mode
    /// machine acts on, signalled straight to the inner stage (module docs). In this order, so
    /// the outer stage never publishes a command without having seen the frame the inner stage
    /// stopped on.
    pub fn deliver_rc(&self, frame: RcFrame, p: &RcParams) {
        self.rc.signal(frame);
        if kill_requested(&frame.input(p)) {
            self.kill.signal(frame.t_us);
        }
    }

    /// Queues an IMU sample for the navigation filter; a full queue (the outer task stalled)
    /// drops its oldest sample.
    pub fn send_nav_sample(&self, sample: NavSample) {
        if let Err(TrySendError::Full(s)) = self.nav.try_send(sample) {
            let _ = self.nav.try_receive();
            let _ = self.nav.try_send(s);
        }
    }

    /// Queues `command` for the inner loop. Should the queue be full (the inner loop stalled),
    /// the oldest commands are dropped: the latest always gets through.
    pub fn send_command(&self, command: AttitudeCommand) {
        let mut c = command;
        for _ in 0..=COMMAND_DEPTH {
            match self.commands.try_send(c) {
                Ok(()) => return,
                Err(TrySendError::Full(back)) => {
                    c = back;
                    let _ = self.commands.try_receive();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use parapet_core::msg::MotorStage;

    #[test]
    fn commands_keep_their_order_and_the_latest_survives_a_full_queue() {
        let mb: Mailboxes<CriticalSectionRawMutex> = Mailboxes::new();
        let cmd = |stage| AttitudeCommand { stage, ..Default::default() };
        mb.send_command(cmd(MotorStage::Idle));
        mb.send_command(cmd(MotorStage::Fly));
        assert_eq!(mb.commands.try_receive().map(|c| c.stage), Ok(MotorStage::Idle));
        assert_eq!(mb.commands.try_receive().map(|c| c.stage), Ok(MotorStage::Fly));
        assert!(mb.commands.try_receive().is_err());
        for _ in 0..COMMAND_DEPTH {
            mb.send_command(cmd(MotorStage::Idle));
        }
        mb.send_command(cmd(MotorStage::Off));
        let mut last = None;
        while let Ok(c) = mb.commands.try_receive() {
            last = Some(c.stage);
        }
        assert_eq!(last, Some(MotorStage::Off));
    }
}

#[cfg(test)]
mod sizes {
    use super::*;

    /// The masked-section bound of the PIL test (`firmware/tests/qemu_pil.rs`, `MASKED_BOUND`)
    /// assumes every mailbox message is a small copy. The largest is the telemetry snapshot:
    /// 280 B on the host since it carries the RC channels for RC_CHANNELS (224 B before), ≈ 70
    /// word copies; the PIL test measures the real masked sections on the target.
    #[test]
    fn every_message_is_small() {
        let sizes = [
            core::mem::size_of::<AttitudeCommand>(),
            core::mem::size_of::<EstimatorAid>(),
            core::mem::size_of::<InnerParams>(),
            core::mem::size_of::<StateEstimate>(),
            core::mem::size_of::<TelemetrySnapshot>(),
            core::mem::size_of::<RcFrame>(),
            core::mem::size_of::<BatteryState>(),
            core::mem::size_of::<NavSample>(),
            core::mem::size_of::<RcParams>(),
        ];
        std::println!("mailbox message sizes (host): {sizes:?}");
        assert!(sizes.iter().all(|&s| s <= 320), "{sizes:?}");
    }
}
