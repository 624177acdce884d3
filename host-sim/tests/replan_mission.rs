//! The replanned path is the mission a ground station downloads (issue 38): `parapet run --gcs`'s
//! in-process bridge flies `two_doors_blocked` with the on-board replanner; a ground station on
//! a local socket (driven from the run's progress callback, every 0.1 s of simulated time)
//! watches MISSION_CURRENT and, whenever its `mission_id` differs from the plan it holds,
//! downloads the mission with the MAVLink mission protocol (MISSION_REQUEST_LIST →
//! MISSION_COUNT → MISSION_REQUEST_INT → MISSION_ITEM_INT, one item at a time).

use std::cell::RefCell;
use std::net::UdpSocket;
use std::rc::Rc;

use mavlink::dialects::ardupilotmega::{
    MavMessage, HEARTBEAT_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA,
};
use mavlink::MavHeader;
use parapet_sim::cli::run_config_from_args;
use parapet_sim::cli::sitl::run_inprocess_bridged;
use parapet_sim::fc::bridge::inprocess::decode_all;
use parapet_sim::fc::bridge::{frame, Bridge, Endpoint};

/// A mission item's x, y (wire) and z.
type Xyz = (i32, i32, f32);
/// A downloaded plan: MISSION_COUNT's `opaque_id` and the items.
type Plan = (u32, Vec<Xyz>);

/// A ground station that downloads the mission whenever MISSION_CURRENT shows a new id.
struct Gcs {
    sock: UdpSocket,
    port: u16,
    seq: u8,
    /// The latest MISSION_CURRENT `mission_id`.
    current_id: Option<u32>,
    /// Download under way: MISSION_COUNT's count, its opaque id, the items so far.
    loading: Option<(u16, u32, Vec<Xyz>)>,
    /// Completed downloads with the simulated time they completed.
    plans: Vec<(f64, Plan)>,
}

impl Gcs {
    fn send(&mut self, m: &MavMessage) {
        let h = MavHeader { system_id: 250, component_id: 190, sequence: self.seq };
        self.seq = self.seq.wrapping_add(1);
        self.sock.send_to(&frame(h, m), ("127.0.0.1", self.port)).expect("send");
    }

    fn request(&mut self, seq: u16) {
        self.send(&MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }));
    }

    /// One step of the ground station at simulated time `t`.
    fn poll(&mut self, t: f64) {
        if self.seq == 0 {
            self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        }
        let mut buf = [0u8; 2048];
        while let Ok((n, _)) = self.sock.recv_from(&mut buf) {
            for (_, m) in decode_all(&buf[..n]) {
                match m {
                    MavMessage::MISSION_CURRENT(c) => {
                        // A plan that changed while it was downloaded: start again.
                        if self.loading.as_ref().is_some_and(|(_, id, _)| *id != c.mission_id) {
                            self.loading = None;
                        }
                        self.current_id = Some(c.mission_id);
                    }
                    MavMessage::MISSION_COUNT(c) if self.loading.is_none() => {
                        self.loading = Some((c.count, c.opaque_id, Vec::new()));
                        self.request(0);
                    }
                    MavMessage::MISSION_ITEM_INT(i) => {
                        let Some((count, id, items)) = self.loading.as_mut() else { continue };
                        if usize::from(i.seq) != items.len() {
                            continue;
                        }
                        items.push((i.x, i.y, i.z));
                        let (next, count, id) = (items.len() as u16, *count, *id);
                        if next < count {
                            self.request(next);
                        } else if let Some((_, _, items)) = self.loading.take() {
                            self.plans.push((t, (id, items)));
                        }
                    }
                    _ => {}
                }
            }
        }
        let held = self.plans.last().map(|(_, (id, _))| *id);
        if self.loading.is_none() && self.current_id.is_some() && self.current_id != held {
            self.send(&MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
                ..Default::default()
            }));
        }
    }
}

/// The ground station behind a bridge: the bridge and the station.
fn station() -> (Rc<RefCell<Bridge>>, Gcs) {
    let sock = UdpSocket::bind("127.0.0.1:0").expect("gcs socket");
    sock.set_nonblocking(true).expect("nonblocking");
    let ep = Endpoint::new("gcs", sock.local_addr().expect("addr")).expect("endpoint");
    let port = ep.local().expect("local").port();
    let bridge = Rc::new(RefCell::new(Bridge::new(vec![ep], false, None)));
    (bridge, Gcs { sock, port, seq: 0, current_id: None, loading: None, plans: Vec::new() })
}

/// `two_doors_blocked` with the 360° lidar and replanning on, as `parapet run` flies it.
fn two_doors() -> (parapet_sim::world::scene::Scene, parapet_sim::flight::runner::RunConfig) {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/two_doors_blocked.toml");
    let args: Vec<String> = [
        "--scene",
        scene,
        "--guidance",
        "trajectory",
        "--perception",
        "lidar360",
        "--assume",
        "no-overhangs,no-low-obstacles",
        "--param",
        "RPL_ENABLE=1",
        "--duration",
        "120",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    run_config_from_args(&args).expect("config")
}

/// The PIL (issue 38): the QEMU firmware (`PARAPET_FIRMWARE_QEMU_ELF`; skipped without it)
/// replans by itself; its mission download after the flight's last replan is that replan's
/// path, ending at the goal, under a plan id other than the uploaded plan's (the firmware says
/// the id in MISSION_CURRENT at 1 Hz, so a download under way at a replan may mix the two; only
/// the last is compared).
#[test]
fn pil_the_replanned_path_is_the_downloaded_mission() {
    let Some(elf) = std::env::var_os("PARAPET_FIRMWARE_QEMU_ELF").map(std::path::PathBuf::from) else {
        eprintln!("\n*** SKIP: PARAPET_FIRMWARE_QEMU_ELF not set ***\n");
        return;
    };
    let (scene, mut cfg) = two_doors();
    cfg.duration = 90.0;
    let (bridge, mut gcs) = station();
    let opts = parapet_sim::fc::pil::PilOptions::new(elf);
    let (out, _) = parapet_sim::cli::sitl::run_pil_bridged(&scene, &cfg, opts, bridge, &mut |t| gcs.poll(t))
        .expect("PIL");
    let s = &out.summary;
    assert_eq!(s.end_reason, "goal", "{:?}", s.end_reason);
    let last_event = s.replan.replan_events.iter().rfind(|e| e.outcome == "replanned").expect("a replan");
    let (_, (first_id, first)) = gcs.plans.first().expect("no download completed");
    assert_eq!(first.len(), cfg.path.len(), "the first download is the uploaded plan");
    let (t_last, (last_id, last)) = gcs.plans.last().expect("download");
    assert!(last_event.t_s < *t_last, "the last download ({t_last} s) follows the last replan");
    assert_ne!(last_id, first_id);
    assert_eq!(last.len(), last_event.waypoints, "downloaded items against the last replan's waypoints");
    let goal = cfg.path.last().expect("goal");
    let (x, y, z) = *last.last().expect("item");
    let end = nalgebra::Vector3::new(f64::from(x) * 1e-4, f64::from(y) * 1e-4, f64::from(z));
    assert!((end - goal).norm() < 1e-3, "the replanned path ends at the goal: {end:?}");
    assert_eq!(gcs.current_id, Some(*last_id));
    eprintln!(
        "PIL: goal {:?} s, replans {}, downloads {}, last at {t_last:.1} s: {} items (last replan at {:.1} s)",
        s.time_to_goal_s,
        s.replan.replans,
        gcs.plans.len(),
        last.len(),
        last_event.t_s
    );
}

/// After each replan the ground station sees a new `mission_id` and downloads the new path:
/// the last download has the last replan's waypoint count (`summary.json`'s `replan_events`),
/// ends at the goal and differs from the uploaded path, which the first download returned.
#[test]
fn the_replanned_path_is_the_downloaded_mission() {
    let (scene, cfg) = two_doors();
    let (bridge, mut gcs) = station();
    let (out, _) = run_inprocess_bridged(&scene, &cfg, bridge, &mut |t| gcs.poll(t)).expect("run");

    let s = &out.summary;
    assert_eq!(s.end_reason, "goal", "{:?}", s.end_reason);
    let replanned: Vec<_> = s.replan.replan_events.iter().filter(|e| e.outcome == "replanned").collect();
    assert!(!replanned.is_empty(), "no replan: the test needs one");
    // As the controller holds the path (f32) and the wire carries it.
    let wire = |w: &nalgebra::Vector3<f64>| {
        let xy = |v: f64| parapet_core::wire::ids::local_xy_to_wire(f64::from(v as f32));
        (xy(w.x), xy(w.y), w.z as f32)
    };
    let uploaded: Vec<_> = cfg.path.iter().map(wire).collect();
    let (_, (first_id, first)) = gcs.plans.first().expect("no download completed");
    assert_eq!(first, &uploaded, "the first download is the uploaded path");
    let (t_last, (last_id, last)) = gcs.plans.last().expect("download");
    assert_ne!(last_id, first_id, "the plan id changed with the replans");
    assert_ne!(last, &uploaded);
    let last_event = replanned.last().expect("event");
    assert!(
        last_event.t_s < *t_last,
        "the last download ({t_last} s) follows the last replan ({} s)",
        last_event.t_s
    );
    assert_eq!(last.len(), last_event.waypoints, "downloaded items against the last replan's waypoints");
    assert_eq!(last.last(), uploaded.last(), "the replanned path ends at the goal");
    assert_eq!(gcs.current_id, Some(*last_id), "the last download is the plan the vehicle flew last");
    // Every download completed between a replan and the next event is that replan's path
    // (its waypoint count), and at least half of the replans were downloaded so.
    let events = &s.replan.replan_events;
    let mut matched = 0;
    for (k, e) in events.iter().enumerate().filter(|(_, e)| e.outcome == "replanned") {
        let until = events.get(k + 1).map_or(f64::INFINITY, |n| n.t_s);
        for (t, (_, items)) in gcs.plans.iter().filter(|(t, _)| *t > e.t_s && *t < until) {
            assert_eq!(items.len(), e.waypoints, "download at {t} s after the replan at {} s", e.t_s);
            matched += 1;
        }
    }
    assert!(2 * matched >= replanned.len(), "{matched} downloads of {} replans", replanned.len());
    // Each plan id is one path.
    for (_, (id, items)) in &gcs.plans {
        let same: Vec<_> = gcs.plans.iter().filter(|(_, (i, _))| i == id).map(|(_, (_, p))| p).collect();
        assert!(same.iter().all(|p| *p == items), "plan id {id} named two paths");
    }
    eprintln!(
        "replans {}, downloads {} ({matched} matched to a replan), last at {t_last:.1} s: {} items (last replan at {:.1} s, {} wp)",
        replanned.len(),
        gcs.plans.len(),
        last.len(),
        last_event.t_s,
        last_event.waypoints
    );
}
