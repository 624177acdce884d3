//! The flight stacks the closed loop of [`crate::flight`] flies.
//!
//! * [`control`]: the in-process `parapet-core` `FlightController`.
//! * [`pil`]: processor-in-the-loop: the QEMU firmware flies the scene over MAVLink
//!   lockstep, and its pure-host twin.
//!
//! May import: `parapet-core`, [`crate::input`], [`crate::sim`], [`crate::world`],
//! [`crate::report`], [`crate::flight`].
pub mod control;
pub mod pil;
