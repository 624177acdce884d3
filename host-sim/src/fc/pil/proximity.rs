//! `OBSTACLE_DISTANCE` (id 330) from a simulated planar 360° lidar scan (issue 19): what a 2-D
//! lidar driver or a companion computer sends PX4's collision prevention and ArduPilot's
//! proximity library, and what the firmware's obstacle memory takes on the QEMU board
//! (`firmware/src/link/obstacles.rs`). With `parapet pil --perception lidar` the host sends
//! each delivered lidar scan as one `OBSTACLE_DISTANCE` and no obstacle points: the firmware
//! builds its own obstacle set from the sectors ([`FlightStack::proximity_scan`]).
//!
//! **Sectors.** A lidar of `n ≤ 72` beams (`[[sensor]]` columns, beam 0 ahead, azimuth
//! positive right = clockwise from above) gives one sector per beam; a finer one (`lidar360`)
//! is cut into 72 sectors of `g = n / 72` consecutive beams, each sector the **nearest**
//! return of its beams (a sector is as close as its closest obstacle), free only when every
//! beam saw nothing within range, unknown when no beam has information. `angle_offset` is the
//! centre of sector 0 plus the mounting yaw; `increment_f` the sector width.
//!
//! **Values.** A return `r` (m) → `round(100·r)` cm, within `[min_distance, max_distance]`;
//! nothing within range → `max_distance + 1` (the message's "no obstacle within range"); no
//! information (dropout, below the minimum range) → `UINT16_MAX`. `frame` `MAV_FRAME_BODY_FRD`
//! (sectors turn with the vehicle's heading; roll and pitch are not applied, as in PX4),
//! `time_usec` the scan's time on the firmware clock.
//!
//! **Eligible sensors** ([`is_planar_lidar`]): one row, a full circle, no mounting pitch,
//! mounted at the centre of mass (`OBSTACLE_DISTANCE` has no sensor offset), a beam count that
//! 72 sectors divide evenly. Any other sensor set keeps the companion model of the PIL (the host's
//! obstacle memory → `OBSTACLE_DISTANCE_3D` points).
//!
//! May import: `parapet-core` (perception types), mavlink, [`crate::sim::range`].

use mavlink::dialects::ardupilotmega::{MavDistanceSensor, MavFrame, MavMessage, OBSTACLE_DISTANCE_DATA};
use parapet_core::perception::Range;

use crate::sim::range::RangeSensor;

/// Sectors of one `OBSTACLE_DISTANCE`.
pub const SECTORS: usize = 72;

/// `UINT16_MAX`: no information in the sector.
pub const UNKNOWN_CM: u16 = u16::MAX;

/// Beams per sector of `s` when it can be sent as `OBSTACLE_DISTANCE`.
fn beams_per_sector(s: &RangeSensor) -> Option<usize> {
    let n = s.columns as usize;
    if n == 0 {
        return None;
    }
    let g = n.div_ceil(SECTORS);
    (n.is_multiple_of(g) && n / g <= SECTORS).then_some(g)
}

/// Whether sensor `s` is a planar 360° lidar that `OBSTACLE_DISTANCE` describes exactly (see the
/// module documentation).
pub fn is_planar_lidar(s: &RangeSensor) -> bool {
    s.rows == 1
        && s.fov_h >= 360.0
        && s.pitch == 0.0
        && s.offset.iter().all(|c| c.abs() < 1e-9)
        && s.max_range * 100.0 < f64::from(u16::MAX - 1)
        && beams_per_sector(s).is_some()
}

/// The `OBSTACLE_DISTANCE` of one scan of planar lidar `s` (`ranges`: one per beam, beam 0
/// first) taken at `t_us` (firmware clock). `None` when `s` is not [`is_planar_lidar`] or the
/// scan has the wrong number of beams.
pub fn obstacle_distance(t_us: u64, s: &RangeSensor, ranges: &[Range]) -> Option<MavMessage> {
    if !is_planar_lidar(s) || ranges.len() != s.columns as usize {
        return None;
    }
    let g = beams_per_sector(s)?;
    let step = 360.0 / s.columns as f64; // degrees per beam
    let min_cm = (s.min_range * 100.0).ceil().clamp(0.0, f64::from(u16::MAX - 2)) as u16;
    let max_cm = ((s.max_range * 100.0).floor() as u16).max(min_cm.saturating_add(1));
    let mut distances = [UNKNOWN_CM; SECTORS];
    for (d, beams) in distances.iter_mut().zip(ranges.chunks(g)) {
        let nearest = beams
            .iter()
            .filter_map(|r| match r {
                Range::Hit(x) if x.is_finite() => Some(*x),
                _ => None,
            })
            .min_by(f32::total_cmp);
        *d = match nearest {
            Some(r) => ((f64::from(r) * 100.0).round().clamp(f64::from(min_cm), f64::from(max_cm))) as u16,
            None if beams.iter().all(|r| matches!(r, Range::Clear)) => max_cm + 1,
            None => UNKNOWN_CM,
        };
    }
    let increment = step * g as f64;
    Some(MavMessage::OBSTACLE_DISTANCE(OBSTACLE_DISTANCE_DATA {
        time_usec: t_us,
        distances,
        min_distance: min_cm,
        max_distance: max_cm,
        sensor_type: MavDistanceSensor::MAV_DISTANCE_SENSOR_LASER,
        increment: increment.round().clamp(1.0, 255.0) as u8,
        increment_f: increment as f32,
        angle_offset: (s.yaw + 0.5 * (g as f64 - 1.0) * step) as f32,
        frame: MavFrame::MAV_FRAME_BODY_FRD,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::range::preset;

    fn lidar(name: &str) -> RangeSensor {
        preset(name).and_then(|v| v.into_iter().next()).expect("preset")
    }

    fn data(m: MavMessage) -> OBSTACLE_DISTANCE_DATA {
        match m {
            MavMessage::OBSTACLE_DISTANCE(d) => d,
            other => panic!("not OBSTACLE_DISTANCE: {other:?}"),
        }
    }

    #[test]
    fn a_72_beam_lidar_is_one_sector_per_beam() {
        let s = lidar("lidar");
        assert!(is_planar_lidar(&s));
        let mut r = vec![Range::Clear; 72];
        r[0] = Range::Hit(2.345);
        r[18] = Range::Unknown;
        r[36] = Range::Hit(0.05); // below the minimum range: clamped to it
        let d = data(obstacle_distance(7, &s, &r).expect("message"));
        assert_eq!((d.time_usec, d.increment, d.increment_f, d.angle_offset), (7, 5, 5.0, 0.0));
        assert_eq!((d.min_distance, d.max_distance), (15, 1200));
        assert_eq!(d.frame, MavFrame::MAV_FRAME_BODY_FRD);
        assert_eq!(d.distances[0], 235);
        assert_eq!(d.distances[1], 1201, "nothing within range: max + 1");
        assert_eq!(d.distances[18], UNKNOWN_CM);
        assert_eq!(d.distances[36], 15);
    }

    #[test]
    fn a_360_beam_lidar_keeps_the_nearest_return_of_each_five_beams() {
        let s = lidar("lidar360");
        let mut r = vec![Range::Clear; 360];
        r[7] = Range::Hit(3.0);
        r[8] = Range::Hit(2.0);
        r[10] = Range::Unknown; // sector 2: one unknown among clear beams → unknown
        let d = data(obstacle_distance(0, &s, &r).expect("message"));
        assert_eq!((d.increment_f, d.angle_offset), (5.0, 2.0)); // centre of beams 0..5
        assert_eq!(d.distances[1], 200);
        assert_eq!(d.distances[2], UNKNOWN_CM);
        assert_eq!(d.distances[0], d.max_distance + 1);
    }

    #[test]
    fn other_sensors_and_wrong_scans_are_not_sent() {
        for name in ["camera", "tof"] {
            let s = lidar(name);
            assert!(!is_planar_lidar(&s), "{name}");
            assert!(
                obstacle_distance(0, &s, &vec![Range::Clear; s.columns as usize * s.rows as usize]).is_none()
            );
        }
        let mut s = lidar("lidar");
        assert!(obstacle_distance(0, &s, &[Range::Clear; 71]).is_none());
        s.offset = [0.1, 0.0, 0.0];
        assert!(!is_planar_lidar(&s), "an offset OBSTACLE_DISTANCE cannot carry");
    }
}
