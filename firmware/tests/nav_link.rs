//! The navigation filter on the vehicle, end to end on the host (issue 39): GPS_INPUT frames
//! through the firmware's `Link` into the real `Cascade` on the lockstep scheduler, the
//! telemetry scheduler's frames decoded by the `mavlink` crate (what a ground station reads):
//! ESTIMATOR_STATUS reports the filter's flags, test ratios and σ; LOCAL_POSITION_NED is the
//! filter's estimate; a dropout beyond the timeout drops the position flags.

use mavlink::dialects::ardupilotmega::{EstimatorStatusFlags, MavMessage};
use mavlink::{MavlinkReader, MavlinkVersion};
use mavlink_core::MessageData;
use parapet_core::controller::ControllerParams;
use parapet_core::nav::aid::NAV_TIMEOUT_US;
use parapet_core::wire::geo::ned_to_global;
use parapet_firmware::app::autopilot::Autopilot;
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::app::loop_timing::LoopReport;
use parapet_firmware::link::dialect::{GpsFixType, GpsInputIgnoreFlags, GPS_INPUT_DATA, HIL_SENSOR_DATA};
use parapet_firmware::link::framing::FrameWriter;
use parapet_firmware::link::telemetry::{TelemetryInputs, TelemetryScheduler};
use parapet_firmware::link::{FixClock, Link};
use parapet_firmware::pil::lockstep::LockstepScheduler;

/// Where the GPS puts the vehicle (NED, m) and the σ it states.
const AT: [f32; 3] = [5.0, 3.0, -2.0];
const H_ACC: f32 = 0.5;

struct Sim {
    link: Link,
    ap: Cascade,
    sched: LockstepScheduler,
    w: FrameWriter,
    tel: TelemetryScheduler,
    k: u64,
}

impl Sim {
    fn new() -> Self {
        let Ok(ap) = Cascade::new(ControllerParams::default()) else { panic!("default parameters") };
        Sim {
            link: Link::new(1, FixClock::Message),
            ap,
            sched: LockstepScheduler::default(),
            w: FrameWriter::new(255, 190),
            tel: TelemetryScheduler::new(),
            k: 0,
        }
    }

    fn t(&self) -> u64 {
        1_000_000 + self.k * 1000
    }

    fn push<D: MessageData>(&mut self, m: &D) {
        let (f, t) = (self.w.encode(m).raw_bytes().to_vec(), self.t());
        self.link.push_bytes(&f, t, &mut self.ap);
    }

    /// One 1 ms step at rest; with `gps`, a GPS_INPUT 150 ms old every 100 ms, 0.2 m north and
    /// south of [`AT`] in turn (a noisy fix).
    fn step(&mut self, gps: bool) {
        let t = self.t();
        if gps && self.k.is_multiple_of(100) {
            let north = if self.k.is_multiple_of(200) { 0.2 } else { -0.2 };
            let at = parapet_core::Vec3::new(AT[0] + north, AT[1], AT[2]);
            let Some((lat, lon, alt_mm)) = ned_to_global(at) else { panic!("position in range") };
            self.push(&GPS_INPUT_DATA {
                time_usec: t - 150_000,
                fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                lat,
                lon,
                alt: alt_mm as f32 / 1000.0,
                horiz_accuracy: H_ACC,
                speed_accuracy: 0.1,
                ignore_flags: GpsInputIgnoreFlags::empty(),
                ..Default::default()
            });
        }
        self.push(&HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() });
        let Some(sample) = self.link.take_hil_sample() else { panic!("HIL_SENSOR not decoded at {t}") };
        self.sched.step(&sample, &mut self.link, &mut self.ap);
        while self.link.pop_reply().is_some() {}
        self.k += 1;
    }

    /// The telemetry frames of one poll at the current time, decoded by the `mavlink` crate.
    fn telemetry(&mut self) -> Vec<MavMessage> {
        let inp = TelemetryInputs {
            snapshot: self.ap.telemetry(),
            inner: LoopReport::ZERO,
            outer: LoopReport::ZERO,
            parser: self.link.parser_stats(),
            counters: Default::default(),
        };
        let mut bytes = Vec::new();
        let mut w = FrameWriter::new(1, 1);
        self.tel.poll(self.t(), &inp, |m| bytes.extend_from_slice(m.encode(&mut w).raw_bytes()));
        let mut r = MavlinkReader::new(bytes.as_slice());
        let mut out = Vec::new();
        while let Ok((_, m)) = r.read_message::<MavMessage>(MavlinkVersion::V2) {
            out.push(m);
        }
        out
    }
}

#[test]
fn estimator_status_and_local_position_come_from_the_filter() {
    let mut g = Sim::new();
    // Before any GPS_INPUT: no ESTIMATOR_STATUS.
    assert!(!g.telemetry().iter().any(|m| matches!(m, MavMessage::ESTIMATOR_STATUS(_))));
    for _ in 0..3_000 {
        g.step(true);
    }
    let out = g.telemetry();
    let est = out.iter().find_map(|m| match m {
        MavMessage::ESTIMATOR_STATUS(e) => Some(e.clone()),
        _ => None,
    });
    let Some(est) = est else { panic!("no ESTIMATOR_STATUS: {out:?}") };
    let good = EstimatorStatusFlags::ESTIMATOR_ATTITUDE
        | EstimatorStatusFlags::ESTIMATOR_VELOCITY_HORIZ
        | EstimatorStatusFlags::ESTIMATOR_VELOCITY_VERT
        | EstimatorStatusFlags::ESTIMATOR_POS_HORIZ_REL
        | EstimatorStatusFlags::ESTIMATOR_POS_HORIZ_ABS
        | EstimatorStatusFlags::ESTIMATOR_POS_VERT_ABS;
    assert_eq!(est.flags, good);
    let nav = g.ap.outer().navigation().aid();
    let s = nav.status().sigma_p;
    assert_eq!((est.pos_horiz_accuracy, est.pos_vert_accuracy), (s.x.max(s.y), s.z));
    // The σ has come down from the fixes' 0.5 m; the test ratios of fixes at rest are small.
    assert!(est.pos_horiz_accuracy > 0.0 && est.pos_horiz_accuracy < H_ACC, "{est:?}");
    assert!((0.0..1.0).contains(&est.pos_horiz_ratio) && est.pos_horiz_ratio > 0.0, "{est:?}");
    assert!((0.0..1.0).contains(&est.vel_ratio), "{est:?}");
    let pos = out.iter().find_map(|m| match m {
        MavMessage::LOCAL_POSITION_NED(p) => Some(p.clone()),
        _ => None,
    });
    let Some(pos) = pos else { panic!("no LOCAL_POSITION_NED: {out:?}") };
    // The outer loop's position: the filter's estimate at the last outer step.
    let tel = g.ap.outer().outer().telemetry();
    let Some((p, _)) = nav.estimate(tel.t_us) else { panic!("filter not initialised") };
    assert_eq!([pos.x, pos.y, pos.z], [p.x, p.y, p.z]);
    for (got, want) in [pos.x, pos.y, pos.z].iter().zip(AT) {
        assert!((got - want).abs() < 0.15, "{pos:?}");
    }
    // The fixes stop: after NAV_TIMEOUT_US the position flags go, the attitude stays.
    for _ in 0..(NAV_TIMEOUT_US / 1000 + 600) {
        g.step(false);
    }
    let flags = g.telemetry().iter().find_map(|m| match m {
        MavMessage::ESTIMATOR_STATUS(e) => Some(e.flags),
        _ => None,
    });
    assert_eq!(flags, Some(EstimatorStatusFlags::ESTIMATOR_ATTITUDE));
    assert!(!g.ap.telemetry().position_fresh);
}
