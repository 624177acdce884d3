//! The flight stacks the closed loop of [`crate::flight`] flies.
//!
//! * [`control`]: the in-process `parapet-core` `FlightController`.
//! * [`nav`]: the navigation filter between a filtered position source and [`control`].
//! * [`pil`]: processor-in-the-loop: the QEMU firmware flies the scene over MAVLink
//!   lockstep, and its pure-host twin.
//! * [`replan`]: the on-board replanner beside the in-process controller (issue 38).
//! * [`bridge`]: the SITL side of the PIL: UDP ground-station endpoints, wall-clock pacing,
//!   `.tlog` (imports none of the others; [`pil`] calls it through `bridge::LinkTap`).
//!
//! May import: `parapet-core`, [`crate::input`], [`crate::sim`], [`crate::world`],
//! [`crate::report`], [`crate::flight`].
pub mod bridge;
pub mod control;
pub mod nav;
pub mod pil;
pub mod replan;
