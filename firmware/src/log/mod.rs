//! The onboard flight log: ULog encoding ([`ulog`], `no_std`, fixed buffers), where logs are
//! kept ([`store`]: the [`store::LogStore`] trait and its RAM ring) and the logger that turns
//! telemetry samples into records from arming to disarming at a bounded rate ([`logger`]), and
//! the MAVLink log download that serves a store ([`transfer`]); [`service`] holds the three
//! together as a log task owns them.
//!
//! Log writes never run in a control task: the control tasks hand a [`logger::LogSample`] to a
//! low-priority task through a bounded channel (dropped and counted when full) and that task
//! owns the logger, the store and the log download.
//!
//! May import: [`crate::app`] (the telemetry snapshot), [`crate::link`]'s dialect, framing,
//! frame parser and addressing (for [`transfer`]), `mavlink_core`, `parapet_core`. Not the PIL
//! application, drivers or boards.

pub mod logger;
pub mod service;
pub mod store;
pub mod transfer;
pub mod ulog;
