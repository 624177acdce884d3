//! The setup commands end to end on the host: COMMAND_LONG frames for DO_MOTOR_TEST (209),
//! PREFLIGHT_CALIBRATION (241) and PREFLIGHT_STORAGE (245) through the firmware's link into an
//! autopilot that holds the real cascade plus `setup::Setup` and a `storage::ParamStore` on
//! a RAM NOR flash; the answers are COMMAND_ACKs and STATUSTEXTs (issue 22).

use embassy_futures::block_on;
use mavlink_core::MessageData;
use parapet_core::controller::ControllerParams;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::params::ParamRejected;
use parapet_core::Vec3;
use parapet_firmware::app::autopilot::{
    Autopilot, CommandRejected, FixKind, PathRejected, PositionFix, SourceNoise, TelemetrySnapshot,
    VehicleCommand,
};
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::link::command::command_long;
use parapet_firmware::link::dialect::MavResult;
use parapet_firmware::link::framing::FrameWriter;
use parapet_firmware::link::outbound::Outbound;
use parapet_firmware::link::{FixClock, Link};
use parapet_firmware::setup::{Setup, SetupAck, StorageRequest, Text};
use parapet_firmware::storage::ram::RamFlash;
use parapet_firmware::storage::{Loaded, ParamStore};

type Flash = RamFlash<{ 2 * 4096 }, 4096>;

/// The cascade plus the setup services, as a board's outer task would hold them.
struct Vehicle {
    cascade: Cascade,
    params: ControllerParams,
    setup: Setup,
    store: ParamStore<Flash>,
    armed: bool,
}

impl Vehicle {
    fn new() -> Self {
        let params = ControllerParams::default();
        let mut store = ParamStore::new(Flash::new(), 0..(2 * 4096)).unwrap();
        let mut p = params;
        assert_eq!(block_on(store.load(&mut p)), Loaded::Empty);
        Vehicle { cascade: Cascade::new(params).unwrap(), params, setup: Setup::new(), store, armed: false }
    }

    /// The storage task's turn (the QEMU / host boards run it between steps).
    fn storage_step(&mut self) {
        match self.setup.take_storage() {
            Some(StorageRequest::Write) => {
                block_on(self.store.save(&self.params)).unwrap();
            }
            Some(StorageRequest::Read) => {
                let mut p = self.params;
                if block_on(self.store.load(&mut p)) == Loaded::Stored {
                    for d in parapet_core::params::TABLE.iter() {
                        let _ = self.set_param(d.name, (d.get)(&p));
                    }
                }
            }
            Some(StorageRequest::Reset) => {
                block_on(self.store.reset()).unwrap();
            }
            None => {}
        }
    }
}

impl Autopilot for Vehicle {
    fn update_position(&mut self, fix: &PositionFix) {
        self.cascade.update_position(fix)
    }
    fn navigation_fix(&mut self, fix: &PositionFix, kind: FixKind, noise: SourceNoise) {
        self.cascade.navigation_fix(fix, kind, noise)
    }
    fn navigation_height(&mut self, t_us: u64, down: f32) {
        self.cascade.navigation_height(t_us, down)
    }
    fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        self.cascade.update_obstacles(now_us, obstacles)
    }
    fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected> {
        self.cascade.set_path(waypoints_ned)
    }
    fn clear_path(&mut self) {
        self.cascade.clear_path()
    }
    fn command(&mut self, now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
        self.cascade.command(now_us, cmd)
    }
    fn telemetry(&self) -> TelemetrySnapshot {
        self.cascade.telemetry()
    }
    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        let v = self.cascade.set_param(name, value)?;
        parapet_core::params::set(&mut self.params, name, v)?;
        self.setup.param_changed(0);
        Ok(v)
    }
    fn get_param(&self, name: &str) -> Option<f32> {
        self.cascade.get_param(name)
    }
    fn setup_command(&mut self, now_us: u64, id: u16, p: [f32; 7]) -> Option<SetupAck> {
        self.setup.command(now_us, id, p, self.armed, &self.params)
    }
    fn setup_text(&mut self) -> Option<Text> {
        self.setup.pop_text()
    }
}

struct Gcs {
    link: Link,
    v: Vehicle,
    w: FrameWriter,
}

impl Gcs {
    fn new() -> Self {
        Gcs { link: Link::new(1, FixClock::Message), v: Vehicle::new(), w: FrameWriter::new(255, 190) }
    }

    fn send<D: MessageData>(&mut self, m: &D) -> Vec<Outbound> {
        let bytes = self.w.encode(m).raw_bytes().to_vec();
        self.link.push_bytes(&bytes, 0, &mut self.v);
        self.link.poll(0, &mut self.v);
        core::iter::from_fn(|| self.link.pop_reply()).collect()
    }

    /// COMMAND_LONG `id` with `p`: its ACK result and the STATUSTEXTs that came with it.
    fn command(&mut self, id: u16, p: [f32; 7]) -> (MavResult, Vec<String>) {
        let m = command_long(id, p, (1, 1));
        let mut result = None;
        let mut texts = Vec::new();
        for o in self.send(&m) {
            match o {
                Outbound::CommandAck(a) => {
                    assert_eq!(a.command, id);
                    result = Some(a.result);
                }
                Outbound::StatusText(s) => {
                    let end = s.text.iter().position(|&b| b == 0).unwrap_or(s.text.len());
                    texts.push(String::from_utf8_lossy(&s.text[..end]).into_owned());
                }
                _ => {}
            }
        }
        (result.unwrap_or_else(|| panic!("no COMMAND_ACK for {id}")), texts)
    }
}

#[test]
fn motor_test_over_mavlink_is_acked_and_refused_armed_with_a_reason() {
    let mut g = Gcs::new();
    let (r, t) = g.command(209, [1.0, 0.0, 15.0, 2.0, 0.0, 0.0, 0.0]);
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    assert!(t.is_empty());
    assert_eq!(g.v.setup.motor_output(1, None), Some([0.15, 0.0, 0.0, 0.0]));
    // Any other command stops it (here an unknown one, answered UNSUPPORTED by the router).
    let (r, _) = g.command(31_999, [0.0; 7]);
    assert_eq!(r, MavResult::MAV_RESULT_UNSUPPORTED);
    assert_eq!(g.v.setup.motor_output(2, None), None);
    g.v.armed = true;
    let (r, t) = g.command(209, [1.0, 0.0, 15.0, 2.0, 0.0, 0.0, 0.0]);
    assert_eq!(r, MavResult::MAV_RESULT_DENIED);
    assert_eq!(t, ["Motor test refused: vehicle armed"]);
}

#[test]
fn calibration_over_mavlink_sends_the_px4_texts() {
    let mut g = Gcs::new();
    let (r, t) = g.command(241, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(t, ["[cal] calibration started: 2 accel"]);
    let (r, t) = g.command(241, [0.0; 7]);
    assert_eq!(r, MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(t, ["[cal] calibration cancelled"]);
    // Compass: not on this vehicle.
    assert_eq!(g.command(241, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]).0, MavResult::MAV_RESULT_UNSUPPORTED);
}

#[test]
fn preflight_storage_writes_reads_and_resets_the_parameters() {
    let mut g = Gcs::new();
    g.v.set_param("CBF_MU", 2.0).unwrap();
    assert_eq!(g.command(245, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).0, MavResult::MAV_RESULT_ACCEPTED);
    g.v.storage_step();
    g.v.set_param("CBF_MU", 3.0).unwrap();
    // Read: the stored 2.0 comes back.
    assert_eq!(g.command(245, [0.0; 7]).0, MavResult::MAV_RESULT_ACCEPTED);
    g.v.storage_step();
    assert_eq!(g.v.get_param("CBF_MU"), Some(2.0));
    // Reset: the store is empty afterwards.
    assert_eq!(g.command(245, [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).0, MavResult::MAV_RESULT_ACCEPTED);
    g.v.storage_step();
    let mut p = ControllerParams::default();
    assert_eq!(block_on(g.v.store.load(&mut p)), Loaded::Empty);
    // Armed: denied.
    g.v.armed = true;
    let (r, t) = g.command(245, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(r, MavResult::MAV_RESULT_DENIED);
    assert_eq!(t, ["Params: storage denied while armed"]);
}
