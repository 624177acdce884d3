//! The replay page's time-linked overlays beyond the samples: the flight-mode changes, the
//! events (a failsafe's guidance entered — brake, no fix, hold, land, return —, a flight-mode change
//! after the first mode, first collision / unavoidable / infeasible / deadlock, the end of the
//! run), the barriers the filter enforced and when (intervention intervals with
//! the most constraints enforced at once and the obstacles acted on), and the range sensors'
//! returns (`ranges.csv`'s scans, decimated for display: [`scan_plan`]).
//!
//! Every list is taken from **every** sample or beam and bounded ([`super::MAX_MARKS`] entries;
//! the page says when a list was cut); times are written as `trajectory.csv` / `ranges.csv`
//! print them (4 decimals).
//!
//! Owns these parts of the page's JSON only. May import: what [`super`] may.

use parapet_core::controller::{FlightMode, GuidanceMode};

use super::{Json, MAX_MARKS};
use crate::perception::RangeLog;
use crate::report::{RunRecord, Sample};

/// At most this many returns are drawn over the whole flight (each shown scan keeps every
/// `stride`-th return, [`scan_plan`]).
pub const MAX_DRAWN_RETURNS: usize = 60_000;

/// At most this many scans per sensor per second of flight are kept for display (a 10 Hz
/// lidar shows every second scan).
pub const MAX_SCANS_PER_S: f64 = 5.0;

/// At most this many of `filter_points.csv`'s logged steps are in the page (every
/// `ceil(steps / MAX_FILTER_STEPS_SHOWN)`-th, each with all its points).
pub const MAX_FILTER_STEPS_SHOWN: usize = 1200;

/// Most obstacle ids listed per intervention interval.
const MAX_IDS: usize = 4;

/// The flight-mode changes of every sample, as `"flight_modes":[names],
/// "flight_mode_changes":[[t, index], …],"flight_mode_changes_cut":bool`.
pub(super) fn flight_modes_json(j: &mut Json, samples: &[Sample]) {
    j.raw(",\"flight_modes\":[");
    for (i, m) in FlightMode::ALL.iter().enumerate() {
        j.sep(i);
        j.string(m.as_str());
    }
    j.raw("],\"flight_mode_changes\":[");
    let (mut n, mut cut, mut last) = (0usize, false, None);
    for s in samples {
        if last == Some(s.flight_mode) {
            continue;
        }
        last = Some(s.flight_mode);
        if n >= MAX_MARKS {
            cut = true;
            break;
        }
        j.sep(n);
        j.raw("[");
        j.num(s.t, 4);
        j.raw(&format!(",{}]", s.flight_mode as usize));
        n += 1;
    }
    j.raw(if cut { "],\"flight_mode_changes_cut\":true" } else { "],\"flight_mode_changes_cut\":false" });
}

/// The guidances a failsafe flies (brake, no fix, hold, land, return; hold and land are also
/// flown on command: the page lists every entry into one as an event).
pub const FAILSAFE_GUIDANCE: [GuidanceMode; 5] =
    [GuidanceMode::Brake, GuidanceMode::NoFix, GuidanceMode::Hold, GuidanceMode::Land, GuidanceMode::Return];

/// The events of the flight in time order: `[t, text]`.
pub(super) fn events(rec: &RunRecord) -> (Vec<(f64, String)>, bool) {
    let mut out: Vec<(f64, String)> = Vec::new();
    let mut cut = false;
    let mut push = |out: &mut Vec<(f64, String)>, t: f64, text: String| {
        if out.len() < MAX_MARKS {
            out.push((t, text));
        } else {
            cut = true;
        }
    };
    let (mut unavoidable, mut infeasible, mut deadlock) = (false, false, false);
    let (mut last, mut last_flight) = (None, None);
    for s in rec.samples {
        if last != Some(s.mode) {
            if FAILSAFE_GUIDANCE.contains(&s.mode) {
                push(&mut out, s.t, format!("guidance entered: {}", s.mode.as_str()));
            }
            last = Some(s.mode);
        }
        if last_flight != Some(s.flight_mode) {
            if last_flight.is_some() {
                push(&mut out, s.t, format!("flight mode: {}", s.flight_mode.as_str()));
            }
            last_flight = Some(s.flight_mode);
        }
        for (seen, flag, what) in [
            (
                &mut unavoidable,
                s.filter.unavoidable,
                "first unavoidable step (a barrier needs more than u_max)",
            ),
            (&mut infeasible, s.filter.infeasible, "first infeasible step (no common solution)"),
            (&mut deadlock, s.safety.deadlock, "first deadlock step (stall detected)"),
        ] {
            if flag && !*seen {
                *seen = true;
                push(&mut out, s.t, what.to_string());
            }
        }
    }
    if let Some(t) = rec.summary.first_collision_time_s {
        let with = rec.summary.collision_with.as_deref().unwrap_or("?");
        push(&mut out, t, format!("collision with {with}"));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Last, at the last sample (a collision is found between samples, after the last one).
    if let Some(s) = rec.samples.last() {
        push(
            &mut out,
            s.t,
            format!("end: {} (controller {})", rec.summary.end_reason, rec.summary.final_controller_state),
        );
    }
    (out, cut)
}

pub(super) fn events_json(j: &mut Json, rec: &RunRecord) {
    let (ev, cut) = events(rec);
    j.raw(",\"events\":[");
    for (i, (t, text)) in ev.iter().enumerate() {
        j.sep(i);
        j.raw("[");
        j.num(*t, 4);
        j.raw(",");
        j.string(text);
        j.raw("]");
    }
    j.raw(if cut { "],\"events_cut\":true" } else { "],\"events_cut\":false" });
}

/// One interval of consecutive steps where the filter changed u*: first and last time, the most
/// barriers enforced at once, the obstacles acted on (at most [`MAX_IDS`], in first-seen order).
#[derive(Clone, Debug, PartialEq)]
pub struct Intervention {
    /// First and last step time, s.
    pub t0: f64,
    /// Last step time, s.
    pub t1: f64,
    /// Most constraints enforced in one step.
    pub n_max: u8,
    /// Obstacles (track ids) acted on.
    pub ids: Vec<u16>,
}

/// The intervention intervals over every sample, at most [`MAX_MARKS`] (and whether more were cut).
pub fn interventions(samples: &[Sample]) -> (Vec<Intervention>, bool) {
    let mut out = Vec::new();
    let mut open: Option<Intervention> = None;
    let mut cut = false;
    let mut close = |out: &mut Vec<Intervention>, iv: Intervention| {
        if out.len() < MAX_MARKS {
            out.push(iv);
        } else {
            cut = true;
        }
    };
    for s in samples {
        if !s.filter.intervened {
            if let Some(iv) = open.take() {
                close(&mut out, iv);
            }
            continue;
        }
        let iv = open.get_or_insert(Intervention { t0: s.t, t1: s.t, n_max: 0, ids: Vec::new() });
        iv.t1 = s.t;
        iv.n_max = iv.n_max.max(s.filter.n_constraints);
        if let Some(a) = s.filter.active_id {
            if iv.ids.len() < MAX_IDS && !iv.ids.contains(&a) {
                iv.ids.push(a);
            }
        }
    }
    if let Some(iv) = open {
        close(&mut out, iv);
    }
    (out, cut)
}

pub(super) fn interventions_json(j: &mut Json, samples: &[Sample]) {
    let (ivs, cut) = interventions(samples);
    j.raw(",\"interventions\":[");
    for (i, iv) in ivs.iter().enumerate() {
        j.sep(i);
        j.raw("[");
        j.num(iv.t0, 4);
        j.raw(",");
        j.num(iv.t1, 4);
        j.raw(&format!(",{},[", iv.n_max));
        for (k, id) in iv.ids.iter().enumerate() {
            j.sep(k);
            j.raw(&id.to_string());
        }
        j.raw("]]");
    }
    j.raw(if cut { "],\"interventions_cut\":true" } else { "],\"interventions_cut\":false" });
}

/// One scan of [`RangeLog`]: its time, sensor and number of returns.
struct ScanSummary {
    t: f64,
    sensor: u16,
    hits: usize,
}

/// Which scans the page shows and how densely: per sensor, a scan when at least
/// `1 / MAX_SCANS_PER_S` s passed since the last one kept; of each kept scan every
/// `stride`-th return, `stride` the smallest keeping the total at most [`MAX_DRAWN_RETURNS`].
/// Returns the kept scans' indices (scan order) and the stride.
fn scan_plan(scans: &[ScanSummary]) -> (Vec<usize>, usize) {
    let mut last: Vec<f64> = Vec::new();
    let mut kept = Vec::new();
    let mut hits = 0usize;
    for (i, s) in scans.iter().enumerate() {
        let k = usize::from(s.sensor);
        if last.len() <= k {
            last.resize(k + 1, f64::NEG_INFINITY);
        }
        if s.t - last[k] >= 1.0 / MAX_SCANS_PER_S - 1e-9 {
            last[k] = s.t;
            kept.push(i);
            hits += s.hits;
        }
    }
    (kept, hits.div_ceil(MAX_DRAWN_RETURNS).max(1))
}

/// The scans of `log` in order, each with its records (one pass; a scan is a run of records
/// with the same time and sensor).
fn scans_of(log: &RangeLog) -> Vec<ScanSummary> {
    let mut out: Vec<ScanSummary> = Vec::new();
    for r in log.iter() {
        match out.last_mut() {
            Some(s) if s.t == r.t && s.sensor == r.sensor => s.hits += usize::from(r.point.is_some()),
            _ => out.push(ScanSummary { t: r.t, sensor: r.sensor, hits: usize::from(r.point.is_some()) }),
        }
    }
    out
}

/// `"scans":{"sensors":[names],"stride":k,"n_scans":n,"shown":[[t, sensor, hits, [x,y,z,…]],…]}`:
/// the returns (ENU, 2 decimals, drawn only) of the kept scans ([`scan_plan`]); `hits` is the
/// scan's count of returns in `ranges.csv` (rows with a range), the drawn points are its
/// returns 0, stride, 2·stride, ….
pub(super) fn scans_json(j: &mut Json, rec: &RunRecord) {
    let scans = scans_of(rec.ranges);
    let (kept, stride) = scan_plan(&scans);
    j.raw(",\"scans\":{\"sensors\":[");
    for (i, s) in rec.range_sensors.iter().enumerate() {
        j.sep(i);
        j.string(&s.name);
    }
    j.raw(&format!("],\"stride\":{stride},\"n_scans\":{},\"shown\":[", scans.len()));
    let mut keep = kept.iter().peekable();
    let (mut scan_i, mut hit_i, mut written) = (0usize, 0usize, 0usize);
    let mut current: Option<(f64, u16)> = None;
    let (mut open, mut first_point) = (false, true);
    for r in rec.ranges.iter() {
        if current != Some((r.t, r.sensor)) {
            if current.is_some() {
                scan_i += 1;
            }
            current = Some((r.t, r.sensor));
            hit_i = 0;
            if open {
                j.raw("]]");
                open = false;
            }
            if keep.peek() == Some(&&scan_i) {
                keep.next();
                j.sep(written);
                written += 1;
                j.raw("[");
                j.num(r.t, 4);
                j.raw(&format!(",{},{},[", r.sensor, scans[scan_i].hits));
                open = true;
                first_point = true;
            }
        }
        if let (true, Some(p)) = (open, r.point) {
            if hit_i % stride == 0 {
                // NED → ENU (y, x, −z), as ranges.csv.
                for v in [p[1], p[0], -p[2]] {
                    if !first_point {
                        j.raw(",");
                    }
                    first_point = false;
                    j.num(f64::from(v), 2);
                }
            }
            hit_i += 1;
        }
    }
    if open {
        j.raw("]]");
    }
    j.raw("]}");
}

/// `"filter_points":{"n_steps":n,"every":k,"shown":[[t, [x,y,z,…]],…]}`: every `k`-th logged
/// step of [`crate::report::points::FilterPointLog`] (`t` as `filter_points.csv` prints it, the
/// points ENU with 2 decimals, drawn only), `k` the smallest keeping at most
/// [`MAX_FILTER_STEPS_SHOWN`].
pub(super) fn filter_points_json(j: &mut Json, rec: &RunRecord) {
    let log = rec.filter_points;
    let every = log.steps().div_ceil(MAX_FILTER_STEPS_SHOWN).max(1);
    j.raw(&format!(",\"filter_points\":{{\"n_steps\":{},\"every\":{every},\"shown\":[", log.steps()));
    for (n, i) in (0..log.steps()).step_by(every).enumerate() {
        let Some((t, points)) = log.step(i) else { break };
        j.sep(n);
        j.raw("[");
        j.num(t, 4);
        j.raw(",[");
        for (k, (p, _)) in points.iter().enumerate() {
            j.sep(k);
            // NED → ENU (y, x, −z).
            j.num(f64::from(p[1]), 2);
            j.raw(",");
            j.num(f64::from(p[0]), 2);
            j.raw(",");
            j.num(-f64::from(p[2]), 2);
        }
        j.raw("]]");
    }
    j.raw("]}");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ten_minute_two_lidar_flight_keeps_5_hz_and_at_most_the_drawn_budget() {
        // Two sensors at 10 Hz for 600 s, 1000 returns a scan: 6 M returns.
        let scans: Vec<ScanSummary> = (0..6000)
            .flat_map(|k| (0..2).map(move |s| ScanSummary { t: k as f64 * 0.1, sensor: s, hits: 1000 }))
            .collect();
        let (kept, stride) = scan_plan(&scans);
        assert_eq!(kept.len(), 2 * 3000, "every second scan of each sensor");
        assert!(kept.iter().all(|&i| (i / 2) % 2 == 0));
        let drawn: usize = kept.iter().map(|&i| scans[i].hits.div_ceil(stride)).sum();
        assert!(drawn <= MAX_DRAWN_RETURNS + kept.len(), "{drawn} drawn, stride {stride}");
        assert_eq!(stride, 100);
        // A short flight keeps every return.
        assert_eq!(scan_plan(&scans[..20]).1, 1);
        assert_eq!(scan_plan(&[]), (vec![], 1));
    }

    #[test]
    fn an_intervention_interval_has_its_most_barriers_and_obstacles() {
        let mut samples: Vec<Sample> = Vec::new();
        for k in 0..10u8 {
            let mut s = super::super::tests::sample(usize::from(k));
            s.filter.intervened = (2..6).contains(&k) || k == 8;
            s.filter.n_constraints = if s.filter.intervened { k % 4 } else { 0 };
            s.filter.active_id = s.filter.intervened.then_some(u16::from(k % 2) + 7);
            samples.push(s);
        }
        let (iv, cut) = interventions(&samples);
        assert!(!cut);
        assert_eq!(iv.len(), 2);
        let t = |k: usize| samples[k].t;
        assert_eq!((iv[0].t0, iv[0].t1, iv[0].n_max, iv[0].ids.clone()), (t(2), t(5), 3, vec![7, 8]));
        assert_eq!((iv[1].t0, iv[1].t1, iv[1].ids.clone()), (t(8), t(8), vec![7]));
    }
}
