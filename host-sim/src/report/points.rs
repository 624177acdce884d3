//! The obstacle points the controller's safety filter was given, logged for the report
//! (`filter_points.csv`) and the replay page: every [`FILTER_POINTS_PERIOD`]-th outer step
//! (10 Hz at the 250 Hz outer rate), the points reported to the controller at that step —
//! ground truth: each obstacle's closest point within the sensing range; `--perception`: the
//! obstacle memory's selected points —, the [`FILTER_POINTS_MAX`] nearest to the vehicle when
//! more were reported. The controller's obstacle set then keeps the most critical of them
//! (`parapet_core::obstacle_set`) and the filter enforces the smallest barriers.
//!
//! `filter_points.csv`: one row per point, `t,id,x,y,z` (s; the point's obstacle / track id;
//! ENU, m; 4 decimals, as `trajectory.csv`). A logged step with no point has no row.
//!
//! Owns [`FilterPointLog`] and its file. May import: `parapet-core`, nalgebra, [`crate::decimal`].

use nalgebra::Vector3;
use parapet_core::obstacle::ObstaclePoint;

use crate::decimal::push_fixed;

/// File name in a report directory.
pub const FILTER_POINTS_CSV: &str = "filter_points.csv";

/// One logged step every this many outer steps (25: 10 Hz).
pub const FILTER_POINTS_PERIOD: u64 = 25;

/// At most this many points per logged step (the nearest to the vehicle).
pub const FILTER_POINTS_MAX: usize = 64;

/// One logged point: NED position (f32, as reported) and its obstacle / track id.
pub type LoggedPoint = ([f32; 3], u16);

/// The logged steps: per step its time and its points (NED, f32 as reported, with their id).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FilterPointLog {
    /// Per logged step: time, index of its first point in `points`.
    steps: Vec<(f64, usize)>,
    points: Vec<LoggedPoint>,
}

impl FilterPointLog {
    /// Log the points `seen` reported at `t` with the vehicle at `pos` (NED): all of them, or
    /// the [`FILTER_POINTS_MAX`] nearest (in the order reported).
    pub fn record(&mut self, t: f64, seen: &[ObstaclePoint], pos: &Vector3<f64>) {
        self.steps.push((t, self.points.len()));
        let point = |o: &ObstaclePoint| ([o.point.x, o.point.y, o.point.z], o.id);
        if seen.len() <= FILTER_POINTS_MAX {
            self.points.extend(seen.iter().map(point));
            return;
        }
        let d2 = |o: &ObstaclePoint| {
            let d = Vector3::new(f64::from(o.point.x), f64::from(o.point.y), f64::from(o.point.z)) - pos;
            d.norm_squared()
        };
        let mut order: Vec<usize> = (0..seen.len()).collect();
        order.select_nth_unstable_by(FILTER_POINTS_MAX - 1, |&a, &b| d2(&seen[a]).total_cmp(&d2(&seen[b])));
        order.truncate(FILTER_POINTS_MAX);
        order.sort_unstable();
        self.points.extend(order.into_iter().filter_map(|i| seen.get(i)).map(point));
    }

    /// Logged steps.
    pub fn steps(&self) -> usize {
        self.steps.len()
    }

    /// Points logged over every step.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// No point logged.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Step `i`: its time and points (NED, id).
    pub fn step(&self, i: usize) -> Option<(f64, &[LoggedPoint])> {
        let &(t, first) = self.steps.get(i)?;
        let end = self.steps.get(i + 1).map_or(self.points.len(), |s| s.1);
        Some((t, self.points.get(first..end).unwrap_or(&[])))
    }
}

/// Write `filter_points.csv` (module docs) to `w`.
pub fn write_filter_points_csv(w: &mut dyn std::io::Write, log: &FilterPointLog) -> std::io::Result<()> {
    writeln!(w, "t,id,x,y,z")?;
    let mut line = Vec::with_capacity(64);
    for i in 0..log.steps() {
        let Some((t, points)) = log.step(i) else { break };
        for (p, id) in points {
            line.clear();
            push_fixed(&mut line, t, 4);
            std::io::Write::write_fmt(&mut line, format_args!(",{id}"))?;
            // NED → ENU: (y, x, −z).
            for v in [p[1], p[0], -p[2]] {
                line.push(b',');
                push_fixed(&mut line, f64::from(v), 4);
            }
            line.push(b'\n');
            w.write_all(&line)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::Vec3;

    #[test]
    fn a_step_keeps_the_nearest_points_in_reported_order_and_the_file_has_them() {
        let pts: Vec<ObstaclePoint> = (0..100)
            .map(|i| ObstaclePoint::fixed(Vec3::new(100.0 - i as f32, 0.0, -1.0), i as u16))
            .collect();
        let mut log = FilterPointLog::default();
        log.record(0.0, &pts[..3], &Vector3::zeros());
        log.record(0.1, &[], &Vector3::zeros());
        log.record(0.2, &pts, &Vector3::zeros());
        assert_eq!((log.steps(), log.len()), (3, 3 + FILTER_POINTS_MAX));
        let (t, p) = log.step(2).unwrap();
        assert_eq!(t, 0.2);
        // The nearest 64: ids 36..=99 (x = 64 … 1), in the order reported.
        let ids: Vec<u16> = p.iter().map(|x| x.1).collect();
        assert_eq!(ids, (36..100).collect::<Vec<u16>>());
        assert_eq!(log.step(1).unwrap().1.len(), 0);
        assert!(log.step(3).is_none());
        let mut v = Vec::new();
        write_filter_points_csv(&mut v, &log).unwrap();
        let text = String::from_utf8(v).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 1 + 3 + FILTER_POINTS_MAX);
        assert_eq!(lines[0], "t,id,x,y,z");
        // NED (100, 0, −1) → ENU (0, 100, 1).
        assert_eq!(lines[1], "0.0000,0,0.0000,100.0000,1.0000");
        assert!(lines[4].starts_with("0.2000,36,"), "{}", lines[4]);
    }
}
