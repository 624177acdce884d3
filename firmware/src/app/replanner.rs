//! The on-board replanner (issue 38) beside the outer stage, off the control loops: the
//! driver of `parapet_core::replan::onboard` (the host's in-process controller runs the same)
//! split over two tasks that share one request buffer, [`ReplanMailbox`].
//!
//! - **Outer side** ([`ReplanOuter::step`], in the outer stage's step): takes the served
//!   request back and applies its new path to the outer loop (the same guidance and filter fly
//!   it); when a snapshot is due (`RPL_RATE`, a mission flown) and no request waits, fills the
//!   buffer with the vehicle's state, the remaining mission and the filter's obstacle points,
//!   and signals the planner. It never waits: while the planner holds the buffer, it tries
//!   again at the next outer step.
//! - **Planner side** ([`serve_pending`], [`run`]): the board's replanner task (the lowest
//!   priority, `src/bin/fc/mod.rs`) waits for the signal, locks the buffer and runs the
//!   planner on it; the PIL application serves it between lockstep steps, as that board task
//!   would. The planner (`Replanner`, ≈ 29 KiB: the 2.5-D grid and the search's buffers) is the
//!   task's own and the request buffer (≈ 3 KiB) is installed by the board
//!   ([`ReplanMailbox::install`]), both `static`s in the CPU-only RAM (`board::ccm`).
//! - **Events** (every result but `NotNeeded`): counted in the telemetry snapshot
//!   ([`ReplanReport`]); the link says each as a STATUSTEXT and the onboard log as a logged
//!   string, both with [`event_text`].
//!
//! The buffer is an `embassy_sync::mutex::Mutex`: its lock state changes under the raw mutex,
//! but a held lock masks nothing, so the plan (milliseconds) runs with interrupts enabled and the
//! outer stage, preempting it, finds the buffer locked and moves on.
//!
//! May import: `parapet_core` (the replanner, the outer loop).

use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::mutex::Mutex;
use embassy_sync::signal::Signal;
use parapet_core::outer::OuterLoop;
use parapet_core::replan::onboard::{apply, ReplanClock, ReplanEvent, ReplanRequest};
use parapet_core::replan::{ReplanOutcome, ReplanParams, Replanner};

/// Where the request is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    /// With the outer side (nothing to plan, or the result applied).
    Idle,
    /// Filled, waiting for the planner.
    Pending,
    /// Served, waiting for the outer side.
    Served,
}

/// The request buffer (once the board installed one) and its stage.
pub struct ReplanSlot {
    stage: Stage,
    request: Option<&'static mut ReplanRequest>,
}

/// The buffer shared by the outer stage and the replanner task, and the signal that wakes the
/// task (module docs).
pub struct ReplanMailbox<M: RawMutex> {
    slot: Mutex<M, ReplanSlot>,
    pending: Signal<M, ()>,
}

impl<M: RawMutex> Default for ReplanMailbox<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: RawMutex> ReplanMailbox<M> {
    /// An idle mailbox.
    pub const fn new() -> Self {
        Self { slot: Mutex::new(ReplanSlot { stage: Stage::Idle, request: None }), pending: Signal::new() }
    }

    /// Hands the mailbox its request buffer (≈ 3 KiB: the board's, in `board::ccm`; kept out
    /// of the mailboxes so that no value built on a stack at boot carries it). `false`: the
    /// buffer is busy (never at boot). Without one, replanning does nothing.
    pub fn install(&self, request: &'static mut ReplanRequest) -> bool {
        match self.slot.try_lock() {
            Ok(mut s) => {
                *s = ReplanSlot { stage: Stage::Idle, request: Some(request) };
                true
            }
            Err(_) => false,
        }
    }
}

/// The replanner's record in the telemetry snapshot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReplanReport {
    /// Events so far (wraps).
    pub events: u16,
    /// The latest event.
    pub last: Option<ReplanEvent>,
}

/// The outer stage's side (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplanOuter {
    clock: ReplanClock,
    report: ReplanReport,
}

impl ReplanOuter {
    /// For the `RPL_*` parameters `p` of a vehicle of hull radius `hull` m.
    pub fn new(p: &ReplanParams, hull: f32) -> Self {
        Self { clock: ReplanClock::new(p, hull), report: ReplanReport::default() }
    }

    /// New parameters (a rebuilt outer loop; the planner takes them with the next request);
    /// the record is kept.
    pub fn retune(&mut self, p: &ReplanParams, hull: f32) {
        self.clock = ReplanClock::new(p, hull);
    }

    /// The record so far.
    pub fn report(&self) -> ReplanReport {
        self.report
    }

    /// After the outer step at `now_us` (module docs): the served result applied to `outer`,
    /// the next snapshot handed over. The event applied, if any.
    pub fn step<M: RawMutex>(
        &mut self,
        now_us: u64,
        outer: &mut OuterLoop,
        mb: &ReplanMailbox<M>,
    ) -> Option<ReplanEvent> {
        if !self.clock.enabled() {
            return None;
        }
        // Held by the planner: next step.
        let Ok(mut slot) = mb.slot.try_lock() else { return None };
        let ReplanSlot { stage, request } = &mut *slot;
        let request = request.as_deref_mut()?;
        let mut event = None;
        if *stage == Stage::Served {
            *stage = Stage::Idle;
            event = apply(now_us, outer, request);
        }
        let handed = *stage == Stage::Idle && self.clock.snapshot(now_us, outer, outer.obstacles(), request);
        if handed {
            *stage = Stage::Pending;
        }
        drop(slot);
        if handed {
            mb.pending.signal(());
        }
        if let Some(e) = event {
            self.report = ReplanReport { events: self.report.events.wrapping_add(1), last: Some(e) };
        }
        event
    }
}

/// The planner side, once: serves the waiting request with `planner`, if any (`true`). Never
/// waits: a buffer held by the outer side is left for the next call.
pub fn serve_pending<M: RawMutex>(planner: &mut Replanner, mb: &ReplanMailbox<M>) -> bool {
    if !mb.pending.signaled() {
        return false;
    }
    let Ok(mut slot) = mb.slot.try_lock() else { return false };
    mb.pending.reset();
    serve(planner, &mut slot)
}

fn serve(planner: &mut Replanner, slot: &mut ReplanSlot) -> bool {
    let ReplanSlot { stage, request: Some(request) } = slot else { return false };
    if *stage != Stage::Pending {
        return false;
    }
    planner.serve(request);
    *stage = Stage::Served;
    true
}

/// The replanner task's body (module docs): waits for a request, serves it, forever.
pub async fn run<M: RawMutex>(planner: &mut Replanner, mb: &ReplanMailbox<M>) -> ! {
    loop {
        mb.pending.wait().await;
        let mut slot = mb.slot.lock().await;
        serve(planner, &mut slot);
    }
}

/// The text of an event (STATUSTEXT and the log; at most 50 bytes), as the host's ground
/// station bridge words it: `Replan: new path, N wp (D detour)`, `Replan: no path, holding`,
/// `Replan: budget, holding`. Returns the bytes written to `buf`.
pub fn event_text(e: &ReplanEvent, buf: &mut [u8; 50]) -> usize {
    let mut w = Writer { buf, n: 0 };
    match e.outcome {
        ReplanOutcome::Replanned { .. } => {
            w.str("Replan: new path, ");
            w.num(e.waypoints);
            w.str(" wp (");
            w.num(e.detour);
            w.str(" detour)");
        }
        ReplanOutcome::NoPath => w.str("Replan: no path, holding"),
        ReplanOutcome::BudgetExceeded | ReplanOutcome::NotNeeded => w.str("Replan: budget, holding"),
    }
    w.n
}

struct Writer<'a> {
    buf: &'a mut [u8; 50],
    n: usize,
}

impl Writer<'_> {
    fn str(&mut self, s: &str) {
        for b in s.bytes() {
            if let Some(d) = self.buf.get_mut(self.n) {
                *d = b;
                self.n += 1;
            }
        }
    }

    fn num(&mut self, v: u8) {
        let digits = [v / 100, v / 10 % 10, v % 10];
        let first = if v >= 100 {
            0
        } else if v >= 10 {
            1
        } else {
            2
        };
        for d in &digits[first..] {
            if let Some(b) = self.buf.get_mut(self.n) {
                *b = b'0' + *d;
                self.n += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;

    #[test]
    fn events_are_worded_as_the_host_bridge_words_them() {
        let mut buf = [0u8; 50];
        let e = ReplanEvent {
            outcome: ReplanOutcome::Replanned { detour: 2, waypoints: 7 },
            waypoints: 7,
            detour: 2,
        };
        let n = event_text(&e, &mut buf);
        assert_eq!(core::str::from_utf8(&buf[..n]), Ok("Replan: new path, 7 wp (2 detour)"));
        let e = ReplanEvent {
            outcome: ReplanOutcome::Replanned { detour: 12, waypoints: 130 },
            waypoints: 130,
            detour: 12,
        };
        let n = event_text(&e, &mut buf);
        assert_eq!(core::str::from_utf8(&buf[..n]), Ok("Replan: new path, 130 wp (12 detour)"));
        let e = ReplanEvent { outcome: ReplanOutcome::NoPath, waypoints: 0, detour: 0 };
        let n = event_text(&e, &mut buf);
        assert_eq!(core::str::from_utf8(&buf[..n]), Ok("Replan: no path, holding"));
    }

    /// A request is served only once it is pending, and the buffer held by one side is left
    /// alone by the other.
    #[test]
    fn the_planner_serves_only_a_pending_request_it_can_lock() {
        let mb: ReplanMailbox<CriticalSectionRawMutex> = ReplanMailbox::new();
        let mut planner = Replanner::new(ReplanParams { enable: true, ..ReplanParams::default() }, 0.25);
        mb.pending.signal(());
        assert!(!serve_pending(&mut planner, &mb), "no buffer installed");
        assert!(mb.install(std::boxed::Box::leak(std::boxed::Box::default())));
        assert!(!serve_pending(&mut planner, &mb), "nothing pending");
        if let Ok(mut s) = mb.slot.try_lock() {
            s.stage = Stage::Pending;
        }
        mb.pending.signal(());
        {
            let held = mb.slot.try_lock();
            assert!(held.is_ok());
            assert!(!serve_pending(&mut planner, &mb), "held by the outer side");
        }
        mb.pending.signal(());
        assert!(serve_pending(&mut planner, &mb));
        assert!(mb.slot.try_lock().is_ok_and(|s| s.stage == Stage::Served));
        assert!(!serve_pending(&mut planner, &mb), "served once");
    }
}
