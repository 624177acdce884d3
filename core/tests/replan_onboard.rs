//! The replanner's shared driver (`parapet_core::replan::onboard`): snapshot → serve → apply,
//! as the host's in-process controller and the firmware's replanner task run it.

use parapet_core::controller::{ControllerParams, FlightController};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::outer::guidance::{GuidanceMode, PATH_CAPACITY};
use parapet_core::outer::inputs::OBSTACLE_CAPACITY;
use parapet_core::outer::{CommandError, OuterTelemetry};
use parapet_core::replan::onboard::{apply, MissionControl, ReplanClock, ReplanEvent, ReplanRequest};
use parapet_core::replan::{ReplanOutcome, ReplanParams, Replanner};
use parapet_core::Vec3;

/// A loop flying `path` (from segment 0) at `position`.
struct Fake {
    tel: OuterTelemetry,
    path: heapless::Vec<Vec3, PATH_CAPACITY>,
    restarts: u32,
}

impl MissionControl for Fake {
    fn outer_telemetry(&self) -> &OuterTelemetry {
        &self.tel
    }
    fn mission_path(&self) -> &[Vec3] {
        &self.path
    }
    fn replace_path(&mut self, w: &[Vec3]) -> Result<(), CommandError> {
        self.path.clear();
        let _ = self.path.extend_from_slice(w);
        Ok(())
    }
    fn restart_mission(&mut self, _now_us: u64) -> Result<(), CommandError> {
        self.restarts += 1;
        Ok(())
    }
}

fn fake() -> Fake {
    let Ok(fc) = FlightController::new(ControllerParams::default()) else { panic!("defaults") };
    let mut tel = *fc.outer().telemetry();
    tel.mode = GuidanceMode::Mission;
    tel.position = Vec3::new(0.0, 0.0, -1.0);
    // The guidance's reference (where the check of the remaining path starts): on the vehicle.
    tel.reference.position = tel.position;
    let mut path = heapless::Vec::new();
    let _ = path.extend_from_slice(&[Vec3::new(4.0, 0.0, -1.0), Vec3::new(8.0, 0.0, -1.0)]);
    Fake { tel, path, restarts: 0 }
}

/// A wall across the path at x = 2 m, y in [-1.2, 1.2] (points every 0.1 m).
fn wall() -> heapless::Vec<ObstaclePoint, OBSTACLE_CAPACITY> {
    (0..25)
        .map(|k| ObstaclePoint {
            point: Vec3::new(2.0, -1.2 + 0.1 * k as f32, -1.0),
            velocity: None,
            id: k,
            normal: None,
        })
        .collect()
}

/// Snapshot → serve → apply: a blocked path is replaced by a detour that ends with the
/// mission's goal; snapshots come at the rate only, never while a mission is not flown.
#[test]
fn a_blocked_mission_gets_a_detour_through_the_three_parts() {
    let p = ReplanParams { enable: true, ..ReplanParams::default() };
    let mut clock = ReplanClock::new(&p, 0.25);
    let mut planner = Replanner::new(p, 0.25);
    let mut m = fake();
    let mut req = ReplanRequest::new();
    assert!(clock.snapshot(1_000_000, &m, &wall(), &mut req));
    assert!(!clock.snapshot(1_100_000, &m, &wall(), &mut req), "before 1 / RPL_RATE");
    planner.serve(&mut req);
    assert!(matches!(req.outcome, Some(ReplanOutcome::Replanned { .. })), "{:?}", req.outcome);
    let before = m.path.len();
    let ev = apply(1_000_000, &mut m, &req);
    assert!(matches!(ev, Some(ReplanEvent { outcome: ReplanOutcome::Replanned { .. }, .. })), "{ev:?}");
    assert!(m.path.len() > before, "{:?}", m.path);
    assert_eq!(m.path.last(), Some(&Vec3::new(8.0, 0.0, -1.0)));
    assert_eq!(m.restarts, 0, "no stall, no restart");
    // A mission changed while the plan ran: the plan is dropped.
    let mut m2 = fake();
    m2.path[1] = Vec3::new(9.0, 0.0, -1.0);
    assert_eq!(apply(1_000_000, &mut m2, &req), None);
    // Not flying a mission: no snapshot.
    m.tel.mode = GuidanceMode::Hold;
    assert!(!clock.snapshot(2_000_000, &m, &wall(), &mut req));
    // Off: never.
    let mut off = ReplanClock::new(&ReplanParams { enable: false, ..p }, 0.25);
    assert!(!off.snapshot(3_000_000, &fake(), &wall(), &mut req));
}
