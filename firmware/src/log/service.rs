//! The log task's state in one place: a store, the [`FlightLogger`] writing into it and the
//! [`LogTransfer`] serving it, plus a frame tap that picks the LOG_* requests out of the received
//! byte stream. What a board's low-priority log task owns (the PIL application holds one and
//! runs it between control steps).
//!
//! The tap is a second [`FrameParser`] on the same bytes the link dispatcher parses: it keeps
//! the log download independent of the dispatcher (which counts LOG_* frames as ignored) at
//! the cost of framing each byte twice (≈ 20 instructions per byte, outside the control step).
//!
//! May import: [`crate::log`], [`crate::link`]'s frame parser and CRC table.

use crate::link::frame_parser::{FrameParser, RawFrame};
use crate::link::messages::frame_extra_crc;
use crate::log::logger::{FlightLogger, LogSample, LoggerStats};
use crate::log::store::{LogStore, RamRing};
use crate::log::transfer::{LogReply, LogTransfer, TransferStats};

/// Bytes of the RAM log store of the QEMU board (and host tests): ≈ 3.7 s of armed flight at
/// the default 25 Hz (`crate::log::logger`); a longer log is cut there (the start is kept),
/// older logs are overwritten. 26 KiB since the 2.5-D replanner (issue 38): its planner grew
/// by 8 KiB and shares the QEMU image's 64 KiB stand-in for the F405's CCM (`board::ccm`) with
/// this store, the parameter flash and the request (32 KiB overflowed it by 5,068 B). Before, 32 KiB (was 60, then 58): the QEMU image's stack needs the
/// room (`tests/tests/setup_pil.rs` guards ≥ 1 KiB never used; 7,452 B are left). The last
/// 26 KiB went to the mission trajectory in the guidance (`parapet_core::outer::trajectory`,
/// 3.0 KB on the Cortex-M4): the boot (`build_app`) builds the application by value, and its
/// frame (37.4 KB without the trajectory, 49.7 KB with it) plus `FlightController::new`'s
/// (5.4 → 9.5 KB) hold about six copies of it. Building the cascade in place would give the
/// room back.
pub const RAM_LOG_BYTES: usize = 26 * 1024;
/// Logs the RAM store lists at most.
pub const RAM_LOG_COUNT: usize = 8;
/// The RAM store of the QEMU board.
pub type RamLogStore = RamRing<RAM_LOG_BYTES, RAM_LOG_COUNT>;

/// Logger + download + tap over one store.
pub struct LogService<S: LogStore + 'static> {
    store: &'static mut S,
    logger: FlightLogger,
    transfer: LogTransfer,
    tap: FrameParser,
}

impl<S: LogStore + 'static> LogService<S> {
    /// The service on `store` (a `static`, e.g. a `static_cell::ConstStaticCell`: a store is
    /// large and must not be moved through the stack) for vehicle `own_system`.
    pub fn new(store: &'static mut S, logger: FlightLogger, own_system: u8) -> Self {
        Self { store, logger, transfer: LogTransfer::new(own_system), tap: FrameParser::new() }
    }

    /// One received byte (the same bytes the link dispatcher gets).
    pub fn on_byte(&mut self, b: u8) {
        let (transfer, store) = (&mut self.transfer, &mut *self.store);
        self.tap.push(b, &frame_extra_crc, &mut |f: &RawFrame<'_>| {
            transfer.on_frame(f, store);
        });
    }

    /// A CRC-checked frame parsed elsewhere (a board's link task): `true` if it was a log
    /// request (handled here).
    pub fn on_frame(&mut self, f: &RawFrame<'_>) -> bool {
        self.transfer.on_frame(f, &mut *self.store)
    }

    /// One telemetry sample (see [`FlightLogger::on_sample`]). Returns `true` when a record
    /// set was written.
    pub fn on_sample(&mut self, s: &LogSample, param: impl FnMut(&str) -> Option<f32>) -> bool {
        let before = self.logger.stats().records;
        self.logger.on_sample(s, &mut *self.store, param);
        self.logger.stats().records != before
    }

    /// Pending log-protocol replies (bounded, see [`LogTransfer::poll`]).
    pub fn poll(&mut self, emit: &mut impl FnMut(LogReply)) {
        self.transfer.poll(&mut *self.store, emit);
    }

    /// Logger counters.
    pub fn logger_stats(&self) -> LoggerStats {
        self.logger.stats()
    }

    /// Log-protocol counters.
    pub fn transfer_stats(&self) -> TransferStats {
        self.transfer.stats()
    }

    /// The store (read access, e.g. for tests).
    pub fn store(&mut self) -> &mut S {
        self.store
    }
}
