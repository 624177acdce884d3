//! The onboard flight log: the log error ([`ulog`]; the ULog encoding and the topics are the
//! core's, `parapet_core::wire::ulog` and `log_topics`, shared with the host), where logs are
//! kept ([`store`]: the [`store::LogStore`] trait and its RAM ring for the QEMU board; [`card`]: a
//! raw-block store on a microSD card, the F405's) and the logger that turns
//! telemetry samples into records from arming to disarming at a bounded rate ([`logger`]), and
//! the MAVLink log download that serves a store ([`transfer`]); [`service`] holds the three
//! together as a log task owns them.
//!
//! Log writes never run in a control task: the control tasks hand a [`logger::LogSample`] to a
//! low-priority task through a bounded channel (dropped and counted when full) and that task
//! owns the logger, the store and the log download.
//!
//! Measured in the QEMU build (`qemu-system-arm -icount shift=0`, one instruction per ns;
//! `parapet pil --straight --duration 20 --gcs udp:127.0.0.1:14599 --firmware ELF --out DIR`, then
//! the firmware's NAMED_VALUE_INT `ins_log`/`ins_logq`/`ins_logm` from `DIR/flight.tlog`;
//! 2026-12-02, 217 record sets):
//!
//! | what | instructions |
//! |---|---|
//! | handing one sample to the log queue (the control task's whole cost, `ins_logq`) | 232 – 238 |
//! | longest section with interrupts masked in it (the worst-case blocking of any other task, `ins_logm`) | 214 – 220 |
//! | writing one record set, 6 topics ≈ 280 bytes (log task, `ins_log`) | median 19 209, p99 19 382 |
//! | the first record set of a log (header, 6 formats, 3 infos, 71 parameters, 6 subscriptions) | 178 302 |
//!
//! With the 26 KiB RAM store of the QEMU board a log holds ≈ 3.7 s at 25 Hz; it is cut there.
//! On the F405 (cargo feature `onboard-log`, on by default) a log task alone in thread mode (with
//! the parameter storage) owns the logger, the card store and the download (`src/bin/fc/`);
//! the H743 has no card driver yet (its log store is always off).
//!
//! May import: [`crate::app`] (the telemetry snapshot), [`crate::link`]'s dialect, framing,
//! frame parser and addressing (for [`transfer`]), `mavlink_core`, `parapet_core`. Not the PIL
//! application, drivers or boards.

pub mod card;
pub mod logger;
pub mod service;
pub mod store;
pub mod transfer;
pub mod ulog;
