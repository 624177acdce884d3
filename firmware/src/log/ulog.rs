//! The onboard log's error type. The ULog encoding itself is the core's
//! (`parapet_core::wire::ulog`, the one writer of the onboard log and the host's `flight.ulg`;
//! the topics and records are `parapet_core::wire::log_topics`); a store becomes its sink through
//! [`crate::log::store::Appender`].
//!
//! May import: `parapet_core::wire::ulog`.

use parapet_core::wire::ulog::TooLong;

/// Why a log write failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogError {
    /// A message or record longer than the writer's buffers (a programming error in a topic).
    TooLong,
    /// No log is open (the store's `begin` was not called).
    NotOpen,
    /// The store has no room for this log any more (the log is truncated from here).
    Full,
    /// No log with this id.
    NotFound,
    /// The store is busy (e.g. erase while a log is being written).
    Busy,
    /// The storage device failed.
    Device,
}

impl From<TooLong> for LogError {
    fn from(_: TooLong) -> Self {
        LogError::TooLong
    }
}
