//! The deprecated float mission messages, for ground stations that still speak them: MISSION_ITEM
//! (39) and MISSION_REQUEST (40), converted to and from the MISSION_ITEM_INT the mission protocol
//! of [`crate::link::mission`] works on.
//!
//! * **Upload**: a MISSION_ITEM answering the vehicle's MISSION_REQUEST_INT is taken like the
//!   MISSION_ITEM_INT it converts to ([`int_item`]; PX4 accepts both too). The vehicle's later
//!   requests stay MISSION_REQUEST_INT (PX4 switches to MISSION_REQUEST; the mission protocol
//!   says MISSION_REQUEST should no longer be sent, and the ground station has just answered one).
//! * **Download**: MISSION_REQUEST(seq) is answered with MISSION_ITEM ([`float_item`]), as PX4
//!   and the message's own definition do (the current mission-protocol page suggests
//!   MISSION_ITEM_INT instead, which a ground station that only speaks the float messages cannot
//!   read); MISSION_REQUEST_INT keeps getting MISSION_ITEM_INT.
//!
//! | frame | MISSION_ITEM x, y | MISSION_ITEM_INT x, y |
//! |---|---|---|
//! | GLOBAL, GLOBAL_RELATIVE_ALT (and the `_INT` ones) | latitude, longitude, degrees | 10⁻⁷ °; a download in MISSION_ITEM reports the `_INT` frames as GLOBAL / GLOBAL_RELATIVE_ALT (PX4 does) |
//! | LOCAL_NED | north, east, m | m × 10⁴ |
//! | any other (DO_* items: param5/6) | as sent | the whole number nearest (a download returns that) |
//!
//! A NaN latitude/longitude (MAVLink's "use the current value") becomes 0, the integer
//! message's "here" for TAKEOFF and LAND (a NaN waypoint is refused as too far from home). z and
//! param1–4 are the same floats in both. **Precision**: an f32 latitude near home (47.4°) has a
//! resolution of 3.8·10⁻⁶ ° ≈ 0.4 m (why the message was deprecated); the f32 conversions add
//! at most 16 10⁻⁷ ° units (≈ 0.2 m) upward and two f32 roundings downward.
//!
//! May import: the dialect, [`crate::link::mission`] (the frame rule), `parapet_core::wire`, `libm`.
//! No allocation, no panics.
#![allow(deprecated)] // MISSION_ITEM, MISSION_REQUEST and the *_INT frames: what this module serves

use crate::link::dialect::{MavFrame, MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA};
use crate::link::mission::alt_ref;
use parapet_core::wire::ids::{local_xy_from_wire, LOCAL_XY_SCALE};

/// How a frame carries x and y.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Xy {
    /// Latitude, longitude.
    Global,
    /// North, east, m.
    Local,
    /// Free parameters.
    Params,
}

fn xy_of(frame: MavFrame) -> Xy {
    match alt_ref(frame) {
        Ok(Some(_)) => Xy::Global,
        Ok(None) => Xy::Local,
        Err(_) => Xy::Params,
    }
}

/// `deg` degrees in 10⁻⁷ ° (NaN → 0; saturating beyond ±214°, which the mission refuses). In
/// f32: up to 16 units (≈ 0.2 m) from the nearest, below the f32 degrees' own resolution.
pub fn e7_of_degrees(deg: f32) -> i32 {
    libm::roundf(deg * 1e7) as i32
}

/// `v` 10⁻⁷ ° in degrees (within two f32 roundings of the nearest).
fn degrees_of_e7(v: i32) -> f32 {
    v as f32 * 1e-7
}

/// The MISSION_ITEM_INT of a MISSION_ITEM (see the module docs).
pub fn int_item(m: &MISSION_ITEM_DATA) -> MISSION_ITEM_INT_DATA {
    let conv = |v: f32| match xy_of(m.frame) {
        Xy::Global => e7_of_degrees(v),
        Xy::Local => libm::roundf(v * LOCAL_XY_SCALE) as i32,
        Xy::Params => libm::roundf(v) as i32,
    };
    with_int_xy(m, conv(m.x), conv(m.y))
}

/// The MISSION_ITEM of a MISSION_ITEM_INT (a download answering MISSION_REQUEST; see the module
/// docs).
pub fn float_item(i: &MISSION_ITEM_INT_DATA) -> MISSION_ITEM_DATA {
    let xy = xy_of(i.frame);
    let conv = |v: i32| match xy {
        Xy::Global => degrees_of_e7(v),
        Xy::Local => local_xy_from_wire(v),
        Xy::Params => v as f32,
    };
    let frame = match i.frame {
        MavFrame::MAV_FRAME_GLOBAL_INT => MavFrame::MAV_FRAME_GLOBAL,
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        f => f,
    };
    with_float_xy(i, conv(i.x), conv(i.y), frame)
}

/// `m` as a MISSION_ITEM_INT with `x`, `y`.
fn with_int_xy(m: &MISSION_ITEM_DATA, x: i32, y: i32) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        param1: m.param1,
        param2: m.param2,
        param3: m.param3,
        param4: m.param4,
        x,
        y,
        z: m.z,
        seq: m.seq,
        command: m.command,
        target_system: m.target_system,
        target_component: m.target_component,
        frame: m.frame,
        current: m.current,
        autocontinue: m.autocontinue,
        mission_type: m.mission_type,
    }
}

/// `i` as a MISSION_ITEM with `x`, `y` and `frame`.
fn with_float_xy(i: &MISSION_ITEM_INT_DATA, x: f32, y: f32, frame: MavFrame) -> MISSION_ITEM_DATA {
    MISSION_ITEM_DATA {
        param1: i.param1,
        param2: i.param2,
        param3: i.param3,
        param4: i.param4,
        x,
        y,
        z: i.z,
        seq: i.seq,
        command: i.command,
        target_system: i.target_system,
        target_component: i.target_component,
        frame,
        current: i.current,
        autocontinue: i.autocontinue,
        mission_type: i.mission_type,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::wire::geo::ORIGIN;

    #[test]
    fn degrees_convert_within_the_stated_bounds() {
        for v in
            [ORIGIN.0, ORIGIN.1, -ORIGIN.0, 0, 1, -1, 899_999_999, -1_799_999_999, 9_999_999, -10_000_001]
        {
            let deg = degrees_of_e7(v);
            // Within two f32 roundings of v·1e-7 (f64 reference).
            let want = (f64::from(v) * 1e-7) as f32;
            assert!((deg - want).abs() <= 2.0 * f32::EPSILON * want.abs().max(1.0), "{v}: {deg} vs {want}");
            // Back: within 16 units (f32 of 1.8e9 has a resolution of 128) of that f32's nearest unit.
            let exact = (f64::from(deg) * 1e7).round() as i64;
            let bound = if exact.abs() > 1 << 30 { 64 } else { 16 };
            assert!(
                (i64::from(e7_of_degrees(deg)) - exact).abs() <= bound,
                "{v}: {} vs {exact}",
                e7_of_degrees(deg)
            );
        }
        assert_eq!(e7_of_degrees(f32::NAN), 0);
        assert_eq!(e7_of_degrees(1e9), i32::MAX, "saturates (then refused by the mission)");
        assert_eq!(e7_of_degrees(-f32::INFINITY), i32::MIN);
    }

    fn float(frame: MavFrame, x: f32, y: f32) -> MISSION_ITEM_DATA {
        MISSION_ITEM_DATA { x, y, z: 12.5, seq: 3, command: 16, frame, param1: 0.5, ..Default::default() }
    }

    #[test]
    fn items_convert_per_frame_and_back() {
        let lat = degrees_of_e7(ORIGIN.0 + 8983);
        let g = int_item(&float(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT, lat, 8.545_594));
        assert!((g.x - (ORIGIN.0 + 8983)).abs() <= 20, "{} (f32 resolution 38 units)", g.x);
        assert!((g.y - ORIGIN.1).abs() <= 5, "{}", g.y);
        assert_eq!((g.z, g.seq, g.command, g.param1), (12.5, 3, 16, 0.5));
        let l = int_item(&float(MavFrame::MAV_FRAME_LOCAL_NED, 1.5, -2.25));
        assert_eq!((l.x, l.y), (15_000, -22_500));
        let d = int_item(&float(MavFrame::MAV_FRAME_MISSION, 7.4, f32::NAN));
        assert_eq!((d.x, d.y), (7, 0));
        let here = int_item(&float(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT, f32::NAN, f32::NAN));
        assert_eq!((here.x, here.y), (0, 0), "NaN: here");
        // Back: the *_INT frames become the float ones, the values their nearest f32.
        let i = MISSION_ITEM_INT_DATA {
            x: ORIGIN.0,
            y: ORIGIN.1,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            ..Default::default()
        };
        let f = float_item(&i);
        assert_eq!(f.frame, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
        assert!((f.x - 47.397_742).abs() <= 4e-6 && (f.y - 8.545_594).abs() <= 1e-6, "{} {}", f.x, f.y);
        let f = float_item(&MISSION_ITEM_INT_DATA { frame: MavFrame::MAV_FRAME_GLOBAL_INT, ..i });
        assert_eq!(f.frame, MavFrame::MAV_FRAME_GLOBAL);
        let f = float_item(&MISSION_ITEM_INT_DATA { frame: MavFrame::MAV_FRAME_LOCAL_NED, x: 15_000, ..i });
        assert_eq!((f.frame, f.x), (MavFrame::MAV_FRAME_LOCAL_NED, 1.5));
    }
}
