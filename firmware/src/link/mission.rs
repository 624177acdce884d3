//! Mission protocol, vehicle side: upload MISSION_COUNT → MISSION_REQUEST_INT (seq 0..n−1) ↔
//! MISSION_ITEM_INT → MISSION_ACK; download MISSION_REQUEST_LIST → MISSION_COUNT, then
//! MISSION_REQUEST_INT(seq) → MISSION_ITEM_INT (the plan the cascade accepted last); clear
//! MISSION_CLEAR_ALL or MISSION_COUNT 0 → the plan is dropped, MISSION_ACK ACCEPTED.
//!
//! `mission_type`: only `MAV_MISSION_TYPE_MISSION` is stored. A geofence or rally upload or
//! download is answered MISSION_ACK `MAV_MISSION_UNSUPPORTED` (with that `mission_type`) and
//! does not touch the mission; MISSION_CLEAR_ALL with `MAV_MISSION_TYPE_ALL` clears the mission
//! (there is nothing else to clear), with fence/rally it is refused the same way.
//!
//! **Items** ([`Step`]; positions in `MAV_FRAME_LOCAL_NED`: x, y = metres × 10⁴ as int32, per
//! the MAVLink local-frame convention for MISSION_ITEM_INT, z = metres down; or in a global
//! frame as QGroundControl and MAVSDK's `mission` plugin send them: `MAV_FRAME_GLOBAL` /
//! `GLOBAL_INT` (z = m AMSL) and `GLOBAL_RELATIVE_ALT` / `GLOBAL_RELATIVE_ALT_INT` (z = m above
//! home), x, y = lat, lon × 10⁷, converted to local NED around home by [`parapet_core::wire::geo`]: lat
//! outside ±90° or > 10 km from home → INVALID_PARAM5, lon → INVALID_PARAM6, altitude →
//! INVALID_PARAM7):
//! * `NAV_WAYPOINT` (16): a waypoint of the path.
//! * `NAV_TAKEOFF` (22), only as the first navigation item (PX4's rule): climb to z (> 0 m above
//!   home, else INVALID_PARAM7) where the vehicle is; x = y = 0 (QGroundControl's "here") or a
//!   position: then fly there at that altitude as the path's first waypoint. The mission begins
//!   with the cascade's takeoff ramp to that height where the vehicle is, started armed on the
//!   ground or airborne (then up or down to it, as PX4 flies a TAKEOFF item in the air;
//!   [`crate::link::mission_run`]). A height above the takeoff limit `MIS_TKO_ALT_MAX` (the
//!   cascade's `GuidanceParams::takeoff_height_max`) is refused at upload (INVALID_PARAM7, as PX4
//!   checks a plan's feasibility when it arrives); the limit set lower after the upload makes
//!   MISSION_START DENIED.
//! * `NAV_LAND` (21): x = y = 0 → land where the last waypoint was reached; a position → fly there
//!   at the previous navigation item's altitude (refused UNSUPPORTED without one), then land.
//!   The cascade's Land mode lands and disarms on the ground.
//! * `NAV_RETURN_TO_LAUNCH` (20): Return mode, as the low-battery failsafe's return (the
//!   breadcrumbs back to home, then land and disarm).
//! * LAND and RTL end the flight: only ignored items may follow them (a navigation item after
//!   them → UNSUPPORTED).
//! * Non-navigation items (DO_* such as DO_CHANGE_SPEED, gimbal, camera and video commands) are
//!   accepted, stored (a download returns them) and not acted on (reported reached with the
//!   navigation item before them). Other NAV/CONDITION items → MAV_MISSION_UNSUPPORTED.
//!
//! Every item keeps the ground station's seq: MISSION_CURRENT / MISSION_ITEM_REACHED report the
//! uploaded seq ([`MissionUpload::path_seq`], [`crate::link::mission_run`]) and a download returns
//! each item field for field as uploaded: param1–4, x, y, z, command, frame, autocontinue and
//! mission_type (issue 41: param1–4 came back 0 and autocontinue 1, and MAVSDK's
//! `download_mission` failed UNSUPPORTED on the difference); `current` is 1 for item 0. The plan's path (waypoints, a takeoff position, a landing approach)
//! is handed to the cascade only when the last item arrived; the MISSION_ACK then reports
//! whether the cascade took it. The non-path items run in [`crate::link::mission_run`].
//!
//! **Plan id** ([`MissionUpload::plan_id`], issue 38): MISSION_COUNT's `opaque_id` and
//! MISSION_CURRENT's `mission_id` carry an id of the
//! accepted plan (`parapet_core::wire::ids::PLAN_ID_START`, the host's in-process bridge folds
//! its path the same way), which changes whenever the plan does, so a ground station knows to
//! download it again (the MAVLink definition of these fields).
//!
//! **Replanned path** ([`MissionUpload::replanned`], from [`crate::link::mission_run`] when the
//! on-board replanner set a new path): the items of the flight being flown (the waypoints from
//! one item with an action to the next, [`Next::Fly`]) become the path the vehicle now flies,
//! one NAV_WAYPOINT item per waypoint in the flight's frame, so a download returns it and the
//! plan id changes. Everything else stays as uploaded, in place: the items before the flight
//! (a takeoff, earlier flights, holds already flown) keep their seqs, the items after it (a
//! speed change, a hold, a landing, a return, DO_*) move up or down with the new count. The
//! flight's last item stays when it does more than pass (a hold, a loiter, a yaw, a landing
//! approach): the replanned path ends at its position (the replanner keeps the flight's end).
//! A flight with other items inside it (an ignored DO_* between its waypoints, waypoints in
//! two frames) is kept as uploaded (its download is then not the replanned path). The path
//! fits the store unless the other items need the room: both hold 64 points (`PATH_CAPACITY`;
//! a replan that would need more is a `BudgetExceeded` result and is not flown), and a path
//! that would make the plan longer than 64 items leaves the plan as uploaded.
//!
//! The deprecated float MISSION_ITEM / MISSION_REQUEST are converted to and from these messages
//! by [`crate::link::mission_float`].
//!
//! Capacity: [`MAX_WAYPOINTS`] items of any kind (MISSION_COUNT above that →
//! MAV_MISSION_NO_SPACE), 36 bytes each, twice (the upload and the accepted plan). A stalled
//! upload re-requests the expected item every [`RETRY_INTERVAL_US`] and is cancelled
//! (MAV_MISSION_OPERATION_CANCELLED) after [`MAX_RETRIES`] re-requests. Every walk over the
//! items is O([`MAX_WAYPOINTS`]).

use crate::link::command::id;
use crate::link::dialect::{
    MavCmd, MavFrame, MavMissionResult, MavMissionType, MISSION_ACK_DATA, MISSION_COUNT_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
};
use crate::link::mission_items::{self, Action};
use heapless::Vec as HVec;
use parapet_core::wire::geo::{self, AltRef, GeoError};
use parapet_core::Vec3;

/// Most items one upload may carry ([`parapet_core::wire::ids::MISSION_ITEM_CAPACITY`], 128):
/// twice the cascade's path (`PATH_CAPACITY`, 64), whose longer segments the executor streams
/// in (issue 38). Each item costs 72 bytes of RAM (the upload and the accepted plan).
pub const MAX_WAYPOINTS: usize = parapet_core::wire::ids::MISSION_ITEM_CAPACITY;
/// Re-request period of a stalled upload, µs.
pub const RETRY_INTERVAL_US: u64 = 500_000;
/// Re-requests before the upload is cancelled.
pub const MAX_RETRIES: u8 = 4;
/// Scale of MISSION_ITEM_INT x/y in local frames (int32 = metres × 10⁴).
pub use parapet_core::wire::ids::LOCAL_XY_SCALE;
use parapet_core::wire::ids::{
    local_xy_from_wire, local_xy_to_wire, plan_id_finish, plan_id_item, PLAN_ID_START,
};

const RETURN_TO_LAUNCH: u16 = MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH as u16;

/// What the vehicle must send (or do) after an input.
#[derive(Clone, Debug, PartialEq)]
pub enum MissionReply {
    /// Ask for item `seq`.
    Request(MISSION_REQUEST_INT_DATA),
    /// Finish (or refuse) the upload with this result.
    Ack(MISSION_ACK_DATA),
    /// All items arrived: install [`MissionUpload::path`] in the cascade, then send
    /// [`MissionUpload::ack_for`] with the outcome (and [`MissionUpload::accept`] it when taken).
    Complete,
    /// MISSION_COUNT 0: clear the cascade's path and [`MissionUpload::clear`], then ACK ACCEPTED.
    Clear,
}

/// What the vehicle answers to a download request.
#[derive(Clone, Debug, PartialEq)]
pub enum DownloadReply {
    /// MISSION_COUNT (answer to MISSION_REQUEST_LIST).
    Count(MISSION_COUNT_DATA),
    /// MISSION_ITEM_INT (answer to MISSION_REQUEST_INT).
    Item(MISSION_ITEM_INT_DATA),
    /// Refusal (unsupported `mission_type`, sequence out of range).
    Ack(MISSION_ACK_DATA),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    Receiving { count: u16, next: u16, partner_sys: u8, partner_comp: u8, last_us: u64, retries: u8 },
}

/// One item as the ground station uploaded it (what a download returns, field for field).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Item {
    x: i32,
    y: i32,
    z: f32,
    /// param1..param4 as uploaded (hold time, acceptance radius, yaw, ...).
    params: [f32; 4],
    command: u16,
    frame: MavFrame,
    autocontinue: u8,
}

/// What one navigation item makes the vehicle do (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Climb to `height_m` above home, then fly to `at` (NED) when given.
    Takeoff {
        /// Height above home, m (> 0).
        height_m: f32,
        /// Position to fly to after the climb (NED, at the takeoff altitude).
        at: Option<Vec3>,
    },
    /// Fly to this point (NED, m).
    Waypoint(Vec3),
    /// Fly to `at` (north, east, m) at the previous altitude when given, then land.
    Land {
        /// Landing position, north and east of home, m.
        at: Option<(f32, f32)>,
    },
    /// Return mode (back along the breadcrumbs to home, land).
    Return,
    /// Stay where the vehicle is for the item's action (NAV_DELAY, CONDITION_YAW, a loiter
    /// at (0, 0); [`crate::link::mission_items`]).
    Pause,
}

/// What the executor does next from an item on ([`MissionUpload::next_from`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Next {
    /// Fly the accepted path's points `from..=to`; `last` is the seq of point `to`'s item.
    Fly {
        /// First path index.
        from: u16,
        /// Last path index.
        to: u16,
        /// Seq of the item of point `to`.
        last: u16,
    },
    /// Item `seq`'s action where the vehicle is ([`MissionUpload::action_at`]).
    Act(u16),
    /// Item `seq` ends the flight (LAND here, RTL).
    End(u16),
    /// Nothing left.
    Done,
}

/// How the plan ends after its path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EndAction {
    /// NAV_LAND.
    Land,
    /// NAV_RETURN_TO_LAUNCH.
    Return,
}

/// The accepted plan's non-path items (what [`crate::link::mission_run`] runs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Plan {
    /// Items uploaded (every kind).
    pub count: u16,
    /// The takeoff item: (seq, height above home in m).
    pub takeoff: Option<(u16, f32)>,
    /// Waypoints of the path handed to the cascade.
    pub path_len: u16,
    /// The item after the path: (seq, what it does).
    pub end: Option<(u16, EndAction)>,
    /// The path's last waypoint is the LAND item's approach (reaching it is not reaching the
    /// LAND item).
    pub land_approach: bool,
}

/// `true` for commands a mission may carry that do not move the vehicle along the path
/// (DO_* 176–252, gimbal manager 1000–1001, camera/video 2000–2600): accepted and ignored.
fn is_ignored_command(cmd: u16) -> bool {
    matches!(cmd, 176..=252 | 1000..=1001 | 2000..=2600)
}

/// Vehicle side of the mission upload.
pub struct MissionUpload {
    state: State,
    items: HVec<Item, MAX_WAYPOINTS>,
    /// The plan the cascade accepted last (what a download returns).
    stored: HVec<Item, MAX_WAYPOINTS>,
    /// The plan id of `stored` ([`MissionUpload::plan_id`]).
    id: u32,
    partner: (u8, u8),
}

impl Default for MissionUpload {
    fn default() -> Self {
        Self::new()
    }
}

impl MissionUpload {
    /// Idle, no plan.
    pub const fn new() -> Self {
        Self { state: State::Idle, items: HVec::new(), stored: HVec::new(), id: 0, partner: (0, 0) }
    }

    /// `true` while an upload is in progress.
    pub fn is_receiving(&self) -> bool {
        matches!(self.state, State::Receiving { .. })
    }

    /// The path of the last completed upload (waypoints, takeoff position, landing approach),
    /// NED, m.
    pub fn path(&self) -> HVec<Vec3, MAX_WAYPOINTS> {
        points(&self.items)
    }

    /// The accepted plan's path (what [`MissionUpload::path`] was when it was accepted).
    pub fn accepted_path(&self) -> HVec<Vec3, MAX_WAYPOINTS> {
        points(&self.stored)
    }

    /// The action of the accepted plan's item `seq` ([`crate::link::mission_items`]).
    pub fn action_at(&self, seq: u16) -> Option<Action> {
        let it = self.stored.get(usize::from(seq))?;
        mission_items::check(it.command, it.params).ok().flatten()
    }

    /// `true` when the accepted plan's item `seq` ends the flight (LAND, RTL).
    pub fn ends_at(&self, seq: u16) -> bool {
        let it = self.stored.get(usize::from(seq));
        matches!(it.map(step_of), Some(Ok(Some(Step::Land { .. } | Step::Return))))
    }

    /// What to do from the accepted plan's item `seq` on: skip ignored items (and a TAKEOFF
    /// without a position: its climb is flown before); a point starts a flight through the
    /// following points up to the first item with an action or a LAND approach; a pause or an
    /// item's action where the vehicle is; the end item. O([`MAX_WAYPOINTS`]).
    pub fn next_from(&self, seq: u16) -> Next {
        let mut seqs: HVec<u16, MAX_WAYPOINTS> = HVec::new();
        walk(&self.stored, |q, _| {
            let _ = seqs.push(q); // at most one point per item: never full
        });
        let index = |q: u16| seqs.iter().position(|&s| s == q).map(|k| k as u16);
        let stops = |q: u16| self.action_at(q).is_some() || self.ends_at(q);
        for q in seq..self.stored_len() {
            if let Some(from) = index(q) {
                let (mut to, mut last) = (from, q);
                let mut r = q;
                while !stops(last) && r + 1 < self.stored_len() {
                    r += 1;
                    match index(r) {
                        Some(k) => (to, last) = (k, r),
                        None if stops(r) || self.pauses_at(r) => break,
                        None => {}
                    }
                }
                return Next::Fly { from, to, last };
            }
            if self.ends_at(q) {
                return Next::End(q);
            }
            if self.action_at(q).is_some() {
                return Next::Act(q);
            }
        }
        Next::Done
    }

    fn pauses_at(&self, seq: u16) -> bool {
        let it = self.stored.get(usize::from(seq));
        matches!(it.map(step_of), Some(Ok(Some(Step::Pause))))
    }

    /// The accepted plan's summary.
    pub fn plan(&self) -> Plan {
        walk(&self.stored, |_, _| {})
    }

    /// The uploaded seq of the accepted plan's path waypoint `k`.
    pub fn path_seq(&self, k: u16) -> Option<u16> {
        let mut found = None;
        let mut i = 0u16;
        walk(&self.stored, |seq, _| {
            if i == k {
                found = Some(seq);
            }
            i = i.saturating_add(1);
        });
        found
    }

    /// The last seq done when item `seq` of the accepted plan is: `seq` and the ignored items
    /// right after it (up to the next navigation item, or the plan's end).
    pub fn done_through(&self, seq: u16) -> u16 {
        let after = self.stored.iter().enumerate().skip(usize::from(seq) + 1);
        let next_nav = after.filter(|(_, it)| matches!(step_of(it), Ok(Some(_)))).map(|(k, _)| k).next();
        next_nav.map_or(self.stored_len().saturating_sub(1), |k| (k as u16).saturating_sub(1)).max(seq)
    }

    /// Items of the accepted plan.
    pub fn stored_len(&self) -> u16 {
        self.stored.len() as u16
    }

    /// The cascade took [`MissionUpload::path`]: the upload becomes the accepted plan.
    pub fn accept(&mut self) {
        self.stored.clone_from(&self.items);
        self.id = id_of(&self.stored);
    }

    /// The accepted plan's id (MISSION_CURRENT `mission_id`, MISSION_COUNT `opaque_id`;
    /// `parapet_core::wire::ids::PLAN_ID_START`): changes with every change of the plan, 0
    /// without one.
    pub fn plan_id(&self) -> u32 {
        self.id
    }

    /// The cascade flies a replanned path (issue 38) in place of the flight through points
    /// `from..` whose last item is `last` ([`Next::Fly`]): the items of that flight become
    /// `path`, one NAV_WAYPOINT per point in their frame (a global one through
    /// [`geo::ned_to_global`] and the frame's altitude reference), and the items after them
    /// move up or down. A last item that does more than pass (a hold, a loiter, a yaw, a landing
    /// approach) stays as uploaded, and the path's last point, its position (where the
    /// replanner's path ends: the flight's end), is not repeated. A download then returns what
    /// the vehicle flies and the plan id changes. `Some((to, last))`, the flight's new last
    /// point and item; `None`, the plan kept: the flight's other items are not plain waypoints
    /// of one frame, the path is empty, does not fit [`MAX_WAYPOINTS`] with the other items or
    /// lies beyond the global frame's reach. O([`MAX_WAYPOINTS`]), no second store.
    pub fn replanned(&mut self, path: &[Vec3], from: u16, last: u16) -> Option<(u16, u16)> {
        let a = usize::from(self.path_seq(from)?);
        let last_i = usize::from(last);
        let s = &self.stored;
        let frame = s.get(a)?.frame;
        let plain = |it: &Item| {
            it.command == id::WAYPOINT
                && it.frame == frame
                && matches!(mission_items::check(it.command, it.params), Ok(None))
        };
        let keep_last = !plain(s.get(last_i)?);
        // Items a..b are replaced by `new`.
        let b = last_i + usize::from(!keep_last);
        let new = path.get(..path.len().saturating_sub(usize::from(keep_last)))?;
        let len = s.len().checked_sub(b.checked_sub(a)?)? + new.len();
        if new.is_empty() || len > MAX_WAYPOINTS || !s.get(a..b)?.iter().all(plain) {
            return None;
        }
        let r = alt_ref(frame).ok()?;
        // The wire x, y, z of point `p` in the plan's frame; `None` beyond a global frame's reach.
        let wire = |p: &Vec3| match r {
            None => Some((local_xy_to_wire(f64::from(p.x)), local_xy_to_wire(f64::from(p.y)), p.z)),
            Some(r) => geo::ned_to_global(*p).map(|(lat, lon, _)| (lat, lon, geo::altitude_m(p.z, r))),
        };
        // Checked before the plan is touched.
        if !new.iter().all(|p| wire(p).is_some()) {
            return None;
        }
        // The items after the flight move to a + new.len() (len ≤ MAX_WAYPOINTS: it fits).
        let old = self.stored.len();
        let filler = *self.stored.get(a)?;
        if len > old {
            self.stored.resize(len, filler).ok()?;
        }
        self.stored.copy_within(b..old, a + new.len());
        self.stored.truncate(len);
        for (slot, (x, y, z)) in self.stored.iter_mut().skip(a).zip(new.iter().filter_map(wire)) {
            *slot = Item { x, y, z, params: [0.0; 4], command: id::WAYPOINT, frame, autocontinue: 1 };
        }
        self.id = id_of(&self.stored);
        let n = new.len() as u16 - u16::from(!keep_last);
        Some((from + n, a as u16 + n))
    }

    /// MISSION_ACK addressed to the last upload partner.
    pub fn ack_for(&self, result: MavMissionResult) -> MISSION_ACK_DATA {
        ack(self.partner.0, self.partner.1, result, MavMissionType::MAV_MISSION_TYPE_MISSION)
    }

    fn request(&self, seq: u16) -> MissionReply {
        MissionReply::Request(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: self.partner.0,
            target_component: self.partner.1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        })
    }

    /// MISSION_REQUEST_LIST of `mission_type` from (`sys`, `comp`): the accepted plan's count,
    /// or UNSUPPORTED for fence/rally.
    pub fn on_request_list(&self, mission_type: MavMissionType, sys: u8, comp: u8) -> DownloadReply {
        if mission_type != MavMissionType::MAV_MISSION_TYPE_MISSION {
            return DownloadReply::Ack(ack(
                sys,
                comp,
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
                mission_type,
            ));
        }
        DownloadReply::Count(MISSION_COUNT_DATA {
            count: self.stored_len(),
            target_system: sys,
            target_component: comp,
            mission_type,
            opaque_id: self.id,
        })
    }

    /// MISSION_REQUEST_INT(`seq`) of `mission_type` from (`sys`, `comp`): the stored item as
    /// uploaded (param1–4, x, y, z, command, frame, autocontinue, mission_type), or a refusal.
    pub fn on_request_item(
        &self,
        seq: u16,
        mission_type: MavMissionType,
        sys: u8,
        comp: u8,
    ) -> DownloadReply {
        if mission_type != MavMissionType::MAV_MISSION_TYPE_MISSION {
            return DownloadReply::Ack(ack(
                sys,
                comp,
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
                mission_type,
            ));
        }
        let Some(it) = self.stored.get(usize::from(seq)) else {
            return DownloadReply::Ack(ack(
                sys,
                comp,
                MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
                mission_type,
            ));
        };
        let [param1, param2, param3, param4] = it.params;
        DownloadReply::Item(MISSION_ITEM_INT_DATA {
            param1,
            param2,
            param3,
            param4,
            x: it.x,
            y: it.y,
            z: it.z,
            seq,
            command: it.command,
            target_system: sys,
            target_component: comp,
            frame: it.frame,
            current: u8::from(seq == 0),
            autocontinue: it.autocontinue,
            mission_type,
        })
    }

    fn fail(&mut self, result: MavMissionResult) -> MissionReply {
        self.state = State::Idle;
        self.items.clear();
        MissionReply::Ack(self.ack_for(result))
    }

    /// MISSION_COUNT from (`sys`, `comp`) at `now_us`. A new count restarts any upload.
    /// Another `mission_type` than MISSION is refused (UNSUPPORTED) and changes nothing.
    pub fn on_count(&mut self, msg: &MISSION_COUNT_DATA, sys: u8, comp: u8, now_us: u64) -> MissionReply {
        if msg.mission_type != MavMissionType::MAV_MISSION_TYPE_MISSION {
            return MissionReply::Ack(ack(
                sys,
                comp,
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
                msg.mission_type,
            ));
        }
        self.partner = (sys, comp);
        self.items.clear();
        if usize::from(msg.count) > MAX_WAYPOINTS {
            return self.fail(MavMissionResult::MAV_MISSION_NO_SPACE);
        }
        if msg.count == 0 {
            self.state = State::Idle;
            return MissionReply::Clear;
        }
        self.state = State::Receiving {
            count: msg.count,
            next: 0,
            partner_sys: sys,
            partner_comp: comp,
            last_us: now_us,
            retries: 0,
        };
        self.request(0)
    }

    /// MISSION_ITEM_INT from (`sys`, `comp`) at `now_us`; `None` when the item is ignored
    /// (no upload in progress, or from another partner). A TAKEOFF higher than
    /// `takeoff_max_m` (m above home, `MIS_TKO_ALT_MAX`) fails the upload with INVALID_PARAM7.
    pub fn on_item(
        &mut self,
        msg: &MISSION_ITEM_INT_DATA,
        sys: u8,
        comp: u8,
        now_us: u64,
        takeoff_max_m: f32,
    ) -> Option<MissionReply> {
        let State::Receiving { count, next, partner_sys, partner_comp, .. } = self.state else {
            return None;
        };
        if (sys, comp) != (partner_sys, partner_comp) {
            return None;
        }
        if msg.seq < next {
            // Duplicate (our request crossed a resend): ask again for what we need.
            return Some(self.request(next));
        }
        if msg.seq > next {
            return Some(self.fail(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE));
        }
        let it = Item {
            x: msg.x,
            y: msg.y,
            z: msg.z,
            params: [msg.param1, msg.param2, msg.param3, msg.param4],
            command: msg.command,
            frame: msg.frame,
            autocontinue: msg.autocontinue,
        };
        let checked = step_of(&it).and_then(|s| match s {
            Some(Step::Takeoff { height_m, .. }) if height_m > takeoff_max_m => {
                Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7)
            }
            s => s.map_or(Ok(()), |s| check_order(&self.items, s)),
        });
        if let Err(e) = checked {
            return Some(self.fail(e));
        }
        if self.items.push(it).is_err() {
            return Some(self.fail(MavMissionResult::MAV_MISSION_NO_SPACE));
        }
        let next = next + 1;
        if next >= count {
            self.state = State::Idle;
            return Some(MissionReply::Complete);
        }
        self.state = State::Receiving { count, next, partner_sys, partner_comp, last_us: now_us, retries: 0 };
        Some(self.request(next))
    }

    /// Periodic check (call at ≥ 10 Hz): re-requests a stalled item or cancels the upload.
    pub fn poll(&mut self, now_us: u64) -> Option<MissionReply> {
        let State::Receiving { count, next, partner_sys, partner_comp, last_us, retries } = self.state else {
            return None;
        };
        if now_us.saturating_sub(last_us) < RETRY_INTERVAL_US {
            return None;
        }
        if retries >= MAX_RETRIES {
            return Some(self.fail(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
        }
        self.state = State::Receiving {
            count,
            next,
            partner_sys,
            partner_comp,
            last_us: now_us,
            retries: retries + 1,
        };
        Some(self.request(next))
    }

    /// MISSION_CLEAR_ALL: drops the accepted plan and any upload.
    pub fn clear(&mut self) {
        self.state = State::Idle;
        self.items.clear();
        self.stored.clear();
        self.id = 0;
    }
}

/// The plan id of `items` (`parapet_core::wire::ids::PLAN_ID_START`; 0 for none).
fn id_of(items: &[Item]) -> u32 {
    if items.is_empty() {
        return 0;
    }
    plan_id_finish(items.iter().fold(PLAN_ID_START, |a, it| plan_id_item(a, it.command, it.x, it.y, it.z)))
}

/// The altitude reference of a supported position frame (`None`: the local frame); `Err` for
/// other frames.
// MISSION_ITEM_INT still carries the *_INT frames (MAVSDK and QGroundControl send them).
#[allow(deprecated)]
pub(crate) fn alt_ref(frame: MavFrame) -> Result<Option<AltRef>, MavMissionResult> {
    match frame {
        MavFrame::MAV_FRAME_LOCAL_NED => Ok(None),
        MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => Ok(Some(AltRef::Amsl)),
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
            Ok(Some(AltRef::Home))
        }
        _ => Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME),
    }
}

fn geo_refusal(e: GeoError) -> MavMissionResult {
    match e {
        GeoError::Latitude => MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
        GeoError::Longitude => MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y,
        GeoError::Altitude => MavMissionResult::MAV_MISSION_INVALID_PARAM7,
    }
}

/// The NED point of an item's x, y, z, or the refusal.
fn position(it: &Item) -> Result<Vec3, MavMissionResult> {
    let Some(r) = alt_ref(it.frame)? else {
        if !it.z.is_finite() {
            return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
        }
        return Ok(Vec3::new(local_xy_from_wire(it.x), local_xy_from_wire(it.y), it.z));
    };
    geo::global_to_ned(it.x, it.y, it.z, r).map_err(geo_refusal)
}

/// The NED down coordinate of an item's altitude alone, m.
fn down_of(it: &Item) -> Result<f32, MavMissionResult> {
    match alt_ref(it.frame)? {
        None if it.z.is_finite() => Ok(it.z),
        None => Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7),
        Some(r) => {
            geo::global_to_ned(geo::ORIGIN.0, geo::ORIGIN.1, it.z, r).map(|p| p.z).map_err(geo_refusal)
        }
    }
}

/// The horizontal position of a TAKEOFF/LAND item: `None` for x = y = 0 ("here").
fn horizontal(it: &Item) -> Result<Option<(f32, f32)>, MavMissionResult> {
    if it.x == 0 && it.y == 0 {
        return Ok(None);
    }
    position(&Item { z: 0.0, ..*it }).map(|p| Some((p.x, p.y)))
}

/// The path points of `items` (NED, m).
fn points(items: &[Item]) -> HVec<Vec3, MAX_WAYPOINTS> {
    let mut out = HVec::new();
    walk(items, |_, p| {
        let _ = out.push(p); // at most one point per item: never full
    });
    out
}

/// What item `it` makes the vehicle do (`None`: accepted and ignored), or the refusal.
fn step_of(it: &Item) -> Result<Option<Step>, MavMissionResult> {
    mission_items::check(it.command, it.params)?;
    if is_ignored_command(it.command) {
        return Ok(None);
    }
    match it.command {
        id::WAYPOINT => position(it).map(|p| Some(Step::Waypoint(p))),
        c if mission_items::is_pause(c) && horizontal(it)?.is_some() && c != mission_items::DELAY => {
            position(it).map(|p| Some(Step::Waypoint(p)))
        }
        c if mission_items::is_pause(c) => Ok(Some(Step::Pause)),
        id::TAKEOFF => {
            let down = down_of(it)?;
            if down.is_nan() || down >= 0.0 {
                return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
            }
            let at = horizontal(it)?.map(|(n, e)| Vec3::new(n, e, down));
            Ok(Some(Step::Takeoff { height_m: -down, at }))
        }
        id::LAND => Ok(Some(Step::Land { at: horizontal(it)? })),
        RETURN_TO_LAUNCH => Ok(Some(Step::Return)),
        _ => Err(MavMissionResult::MAV_MISSION_UNSUPPORTED),
    }
}

/// Refuses `step` after the items `before` (see the module docs: TAKEOFF first, nothing that
/// moves after LAND/RTL, a LAND position needs an altitude before it).
fn check_order(before: &[Item], step: Step) -> Result<(), MavMissionResult> {
    let mut nav = false;
    let mut ended = false;
    for s in before.iter().filter_map(|it| step_of(it).ok().flatten()) {
        nav = true;
        ended |= matches!(s, Step::Land { .. } | Step::Return);
    }
    let bad = ended
        || (nav && matches!(step, Step::Takeoff { .. }))
        || (!nav && matches!(step, Step::Land { at: Some(_) }));
    if bad {
        Err(MavMissionResult::MAV_MISSION_UNSUPPORTED)
    } else {
        Ok(())
    }
}

/// Walks accepted items: calls `point(seq, p)` for every path point, in order, and returns the
/// plan's summary. Items that do not decode (never stored) are skipped.
fn walk(items: &[Item], mut point: impl FnMut(u16, Vec3)) -> Plan {
    let mut plan = Plan { count: items.len() as u16, ..Plan::default() };
    let mut last_z: Option<f32> = None;
    for (k, it) in items.iter().enumerate() {
        let seq = k as u16;
        let Ok(Some(step)) = step_of(it) else { continue };
        let p = match step {
            Step::Takeoff { height_m, at } => {
                plan.takeoff = Some((seq, height_m));
                last_z = Some(-height_m);
                at
            }
            Step::Waypoint(p) => {
                last_z = Some(p.z);
                Some(p)
            }
            Step::Land { at } => {
                plan.end = Some((seq, EndAction::Land));
                let approach = at.zip(last_z).map(|((n, e), z)| Vec3::new(n, e, z));
                plan.land_approach = approach.is_some();
                approach
            }
            Step::Return => {
                plan.end = Some((seq, EndAction::Return));
                None
            }
            Step::Pause => None,
        };
        if let Some(p) = p {
            plan.path_len = plan.path_len.saturating_add(1);
            point(seq, p);
        }
    }
    plan
}

/// MISSION_ACK to (`sys`, `comp`).
pub fn ack(sys: u8, comp: u8, result: MavMissionResult, mission_type: MavMissionType) -> MISSION_ACK_DATA {
    MISSION_ACK_DATA {
        target_system: sys,
        target_component: comp,
        mavtype: result,
        mission_type,
        opaque_id: 0,
    }
}

#[cfg(test)]
#[allow(deprecated)] // the *_INT frames, as ground stations send them
mod tests {
    use super::*;

    /// The default takeoff limit, m (`MIS_TKO_ALT_MAX`).
    const TKO: f32 = parapet_core::outer::guidance::TAKEOFF_HEIGHT_MAX_DEFAULT;

    fn item(seq: u16, x: f32, y: f32, z: f32) -> MISSION_ITEM_INT_DATA {
        MISSION_ITEM_INT_DATA {
            x: parapet_core::wire::ids::local_xy_to_wire(f64::from(x)),
            y: parapet_core::wire::ids::local_xy_to_wire(f64::from(y)),
            z,
            seq,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT as u16,
            frame: MavFrame::MAV_FRAME_LOCAL_NED,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }
    }

    fn count(n: u16) -> MISSION_COUNT_DATA {
        MISSION_COUNT_DATA { count: n, target_system: 1, target_component: 1, ..Default::default() }
    }

    fn req_seq(r: Option<MissionReply>) -> Option<u16> {
        match r {
            Some(MissionReply::Request(q)) => Some(q.seq),
            _ => None,
        }
    }

    #[test]
    fn full_upload_in_order() {
        let mut m = MissionUpload::new();
        assert_eq!(req_seq(Some(m.on_count(&count(3), 255, 190, 0))), Some(0));
        assert_eq!(req_seq(m.on_item(&item(0, 1.0, 0.0, -1.0), 255, 190, 10, TKO)), Some(1));
        assert_eq!(req_seq(m.on_item(&item(1, 2.5, -1.25, -1.5), 255, 190, 20, TKO)), Some(2));
        assert_eq!(m.on_item(&item(2, 3.0, 1.0, -2.0), 255, 190, 30, TKO), Some(MissionReply::Complete));
        assert_eq!(m.path().len(), 3);
        assert!((m.path()[1] - Vec3::new(2.5, -1.25, -1.5)).norm() < 1e-4);
        let ack = m.ack_for(MavMissionResult::MAV_MISSION_ACCEPTED);
        assert_eq!((ack.target_system, ack.target_component), (255, 190));
        assert!(!m.is_receiving());
    }

    /// Uploads `items` (seq set in order) and accepts the plan.
    fn accepted(items: &[MISSION_ITEM_INT_DATA]) -> MissionUpload {
        let mut m = MissionUpload::new();
        m.on_count(&count(items.len() as u16), 255, 190, 0);
        for (k, it) in items.iter().enumerate() {
            m.on_item(&MISSION_ITEM_INT_DATA { seq: k as u16, ..*it }, 255, 190, 0, TKO);
        }
        m.accept();
        m
    }

    /// Replans the plan's first flight ([`Next::Fly`] from item 0) with `path`.
    fn replan_first(m: &mut MissionUpload, path: &[Vec3]) -> Option<(u16, u16)> {
        let Next::Fly { from, last, .. } = m.next_from(0) else { return None };
        m.replanned(path, from, last)
    }

    /// Issue 38: a replanned path becomes the accepted plan of a plan of waypoints — a download
    /// returns its items and the plan id (MISSION_COUNT `opaque_id`) changes; an empty path or
    /// one beyond the store's capacity leaves the plan and its id alone; a landing position
    /// stays the plan's last item.
    #[test]
    fn a_replanned_path_becomes_the_downloaded_plan_of_a_waypoint_plan() {
        let mut m = accepted(&[item(0, 1.0, 0.0, -1.0), item(0, 2.0, 0.0, -1.0), item(0, 3.0, 1.0, -1.0)]);
        let id0 = m.plan_id();
        assert_ne!(id0, 0);
        let path = [
            Vec3::new(1.2, -0.4, -1.0),
            Vec3::new(1.6, 0.6, -1.0),
            Vec3::new(2.0, 0.0, -1.0),
            Vec3::new(3.0, 1.0, -1.0),
        ];
        assert_eq!(replan_first(&mut m, &[]), None);
        assert_eq!(replan_first(&mut m, &[path[0]; MAX_WAYPOINTS + 1]), None);
        assert_eq!(m.plan_id(), id0);
        assert_eq!(replan_first(&mut m, &path), Some((3, 3)));
        let id1 = m.plan_id();
        assert!(id1 != id0 && id1 != 0);
        match m.on_request_list(MavMissionType::MAV_MISSION_TYPE_MISSION, 255, 190) {
            DownloadReply::Count(c) => assert_eq!((c.count, c.opaque_id), (4, id1)),
            other => panic!("{other:?}"),
        }
        for (k, p) in path.iter().enumerate() {
            let DownloadReply::Item(it) =
                m.on_request_item(k as u16, MavMissionType::MAV_MISSION_TYPE_MISSION, 255, 190)
            else {
                panic!("item {k}")
            };
            let want = item(k as u16, p.x, p.y, p.z);
            assert_eq!(
                (it.x, it.y, it.z, it.command, it.frame),
                (want.x, want.y, want.z, want.command, want.frame)
            );
        }
        assert_eq!(m.accepted_path().len(), 4);
        assert!((m.accepted_path()[1] - path[1]).norm() < 1e-4);
        // The same path again is the same plan: the same id.
        assert_eq!(replan_first(&mut m, &path), Some((3, 3)));
        assert_eq!(m.plan_id(), id1);
        // A plan that lands where the last waypoint was: the path, then its LAND item.
        let land = MISSION_ITEM_INT_DATA { command: id::LAND, x: 0, y: 0, ..item(0, 0.0, 0.0, 0.0) };
        let mut l = accepted(&[item(0, 1.0, 0.0, -1.0), land.clone()]);
        assert_eq!(replan_first(&mut l, &path), Some((3, 3)));
        assert_eq!((l.stored_len(), l.plan().path_len, l.plan().end), (5, 4, Some((4, EndAction::Land))));
        // One that lands at a position: its approach is the path's last point, the LAND item
        // stays after the new waypoints.
        let land_at =
            MISSION_ITEM_INT_DATA { x: item(0, 3.0, 0.0, 0.0).x, y: item(0, 0.0, 1.0, 0.0).y, ..land };
        let mut l = accepted(&[item(0, 1.0, 0.0, -1.0), land_at.clone()]);
        let id_l = l.plan_id();
        assert_eq!(replan_first(&mut l, &path), Some((3, 3)));
        assert_ne!(l.plan_id(), id_l);
        assert_eq!((l.stored_len(), l.plan().path_len, l.plan().end), (4, 4, Some((3, EndAction::Land))));
        assert!((l.accepted_path()[3] - path[3]).norm() < 1e-4, "the approach is the path's end");
        assert_eq!(l.stored.last().map(|it| (it.command, it.x)), Some((id::LAND, land_at.x)));
        l.clear();
        assert_eq!(l.plan_id(), 0);
    }

    /// A plan as QGroundControl sends it — a takeoff where the vehicle is, waypoints in
    /// `GLOBAL_RELATIVE_ALT_INT`, a return — gets the replanned waypoints in its frame between
    /// the takeoff and the return; a flight in mixed frames is kept as uploaded.
    #[test]
    fn a_global_frame_plan_gets_the_replanned_waypoints_in_its_frame() {
        let global = |p: Vec3| {
            let (lat, lon, _) = geo::ned_to_global(p).unwrap();
            MISSION_ITEM_INT_DATA {
                x: lat,
                y: lon,
                z: -p.z,
                frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                ..item(0, 0.0, 0.0, 0.0)
            }
        };
        let takeoff =
            MISSION_ITEM_INT_DATA { command: id::TAKEOFF, x: 0, y: 0, z: 2.0, ..global(Vec3::zeros()) };
        let rtl =
            MISSION_ITEM_INT_DATA { command: RETURN_TO_LAUNCH, x: 0, y: 0, z: 0.0, ..global(Vec3::zeros()) };
        let (a, b) = (Vec3::new(5.0, 0.0, -2.0), Vec3::new(9.0, 3.0, -2.0));
        let mut m = accepted(&[takeoff.clone(), global(a), global(b), rtl.clone()]);
        let id0 = m.plan_id();
        assert_eq!((m.plan().takeoff.map(|t| t.0), m.plan().end.map(|e| e.0)), (Some(0), Some(3)));
        let detour = [Vec3::new(4.0, 2.0, -2.5), Vec3::new(7.0, 4.0, -2.0), b];
        assert_eq!(replan_first(&mut m, &detour), Some((2, 3)));
        assert!(m.plan_id() != id0 && m.plan_id() != 0);
        let n = m.stored_len();
        assert_eq!(n, 5);
        let plan = m.plan();
        assert_eq!(
            (plan.takeoff.map(|t| t.0), plan.path_len, plan.end),
            (Some(0), 3, Some((4, EndAction::Return)))
        );
        for (k, p) in detour.iter().enumerate() {
            let DownloadReply::Item(it) =
                m.on_request_item(k as u16 + 1, MavMissionType::MAV_MISSION_TYPE_MISSION, 255, 190)
            else {
                panic!("item {k}")
            };
            assert_eq!((it.command, it.frame), (id::WAYPOINT, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT));
            let (lat, lon, _) = geo::ned_to_global(*p).unwrap();
            assert_eq!((it.x, it.y), (lat, lon));
            assert!((it.z + p.z).abs() < 1e-5, "height above home {}", it.z);
            assert!((m.accepted_path()[k] - p).norm() < 0.02, "{k}");
        }
        let DownloadReply::Item(end) =
            m.on_request_item(4, MavMissionType::MAV_MISSION_TYPE_MISSION, 255, 190)
        else {
            panic!("end item")
        };
        assert_eq!(end.command, RETURN_TO_LAUNCH);
        // Mixed frames within the flight: kept (a last item in another frame stays as it is).
        let mut x = accepted(&[global(a), item(0, 7.0, 3.0, -2.0), global(b)]);
        assert_eq!(replan_first(&mut x, &detour), None);
        let mut y = accepted(&[global(a), item(0, 9.0, 3.0, -2.0)]);
        assert_eq!(replan_first(&mut y, &detour), Some((2, 2)));
        assert_eq!(y.stored.last().map(|it| it.frame), Some(MavFrame::MAV_FRAME_LOCAL_NED));
        // No room for the kept items with a full path: kept.
        assert_eq!(replan_first(&mut m, &[b; MAX_WAYPOINTS - 1]), None);
        let full = (MAX_WAYPOINTS as u16 - 3, MAX_WAYPOINTS as u16 - 2);
        assert_eq!(replan_first(&mut m, &[b; MAX_WAYPOINTS - 2]), Some(full));
        assert_eq!(m.stored_len() as usize, MAX_WAYPOINTS);
    }

    /// A plan with a hold and a speed change: the replanned flight's items are replaced in
    /// place, the hold (the flight's end) and everything after it stay as uploaded and move
    /// with the new item count; a replan of the next flight replaces its items only.
    #[test]
    fn a_replan_splices_the_flight_being_flown_into_a_plan_with_a_hold_and_a_speed_change() {
        let hold = MISSION_ITEM_INT_DATA {
            command: MavCmd::MAV_CMD_NAV_LOITER_TIME as u16,
            param1: 3.0,
            ..item(0, 4.0, 0.0, -1.0)
        };
        let speed = MISSION_ITEM_INT_DATA {
            command: MavCmd::MAV_CMD_DO_CHANGE_SPEED as u16,
            param2: 2.0,
            ..item(0, 0.0, 0.0, 0.0)
        };
        let rtl = MISSION_ITEM_INT_DATA { command: RETURN_TO_LAUNCH, ..item(0, 0.0, 0.0, 0.0) };
        let mut m = accepted(&[
            item(0, 2.0, 0.0, -1.0),
            hold.clone(),
            speed.clone(),
            item(0, 6.0, 2.0, -1.0),
            item(0, 8.0, 2.0, -1.0),
            rtl.clone(),
        ]);
        let id0 = m.plan_id();
        let h = Vec3::new(4.0, 0.0, -1.0);
        let (d1, d2) = (Vec3::new(2.0, 1.0, -1.0), Vec3::new(3.0, 1.5, -1.0));
        // The first flight (waypoint, hold): two detour points, then the hold as uploaded.
        assert_eq!(m.next_from(0), Next::Fly { from: 0, to: 1, last: 1 });
        assert_eq!(m.replanned(&[d1, d2, h], 0, 1), Some((2, 2)));
        assert_ne!(m.plan_id(), id0);
        let seqs = |m: &MissionUpload| m.stored.iter().map(|it| it.command).collect::<std::vec::Vec<_>>();
        let (wp, loiter, spd) = (id::WAYPOINT, hold.command, speed.command);
        assert_eq!(seqs(&m), [wp, wp, loiter, spd, wp, wp, RETURN_TO_LAUNCH]);
        assert_eq!(m.stored[2].params[0], 3.0, "the hold keeps its time");
        assert_eq!(
            m.accepted_path().as_slice(),
            &[d1, d2, h, Vec3::new(6.0, 2.0, -1.0), Vec3::new(8.0, 2.0, -1.0)][..]
        );
        assert_eq!(m.next_from(3), Next::Act(3));
        // The next flight (after the speed change): its two waypoints become three.
        assert_eq!(m.next_from(4), Next::Fly { from: 3, to: 4, last: 5 });
        let e = Vec3::new(7.0, 3.0, -1.0);
        let c = Vec3::new(8.0, 2.0, -1.0);
        assert_eq!(m.replanned(&[d2, e, c], 3, 5), Some((5, 6)));
        assert_eq!(seqs(&m), [wp, wp, loiter, spd, wp, wp, wp, RETURN_TO_LAUNCH]);
        assert_eq!(m.accepted_path().get(3..).unwrap_or(&[]), &[d2, e, c][..]);
        assert_eq!(m.plan().end.map(|e| e.0), Some(7));
        // A flight that is only the hold: the detour goes before it.
        let mut only = accepted(&[hold.clone(), rtl]);
        assert_eq!(only.replanned(&[d1, h], 0, 0), Some((1, 1)));
        assert_eq!(seqs(&only), [wp, loiter, RETURN_TO_LAUNCH]);
        // An ignored item inside the flight: kept as uploaded.
        let cam = MISSION_ITEM_INT_DATA {
            command: MavCmd::MAV_CMD_DO_SET_CAM_TRIGG_DIST as u16,
            ..item(0, 0.0, 0.0, 0.0)
        };
        let mut k = accepted(&[item(0, 2.0, 0.0, -1.0), cam, item(0, 3.0, 0.0, -1.0), hold]);
        let Next::Fly { from, last, .. } = k.next_from(0) else { panic!("a flight") };
        assert_eq!(k.replanned(&[d1, h], from, last), None);
    }

    #[test]
    fn duplicates_are_re_requested_and_gaps_abort() {
        let mut m = MissionUpload::new();
        m.on_count(&count(3), 255, 190, 0);
        m.on_item(&item(0, 1.0, 0.0, -1.0), 255, 190, 0, TKO);
        assert_eq!(req_seq(m.on_item(&item(0, 1.0, 0.0, -1.0), 255, 190, 0, TKO)), Some(1));
        match m.on_item(&item(2, 1.0, 0.0, -1.0), 255, 190, 0, TKO) {
            Some(MissionReply::Ack(a)) => {
                assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE)
            }
            other => panic!("{other:?}"),
        }
        assert!(!m.is_receiving());
    }

    #[test]
    fn refuses_wrong_frame_command_size_and_other_partners() {
        let mut m = MissionUpload::new();
        match m.on_count(&count(MAX_WAYPOINTS as u16 + 1), 255, 190, 0) {
            MissionReply::Ack(a) => assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_NO_SPACE),
            other => panic!("{other:?}"),
        }
        m.on_count(&count(2), 255, 190, 0);
        assert_eq!(m.on_item(&item(0, 1.0, 0.0, -1.0), 7, 1, 0, TKO), None);
        let mut bad = item(0, 1.0, 0.0, -1.0);
        bad.frame = MavFrame::MAV_FRAME_BODY_FRD;
        match m.on_item(&bad, 255, 190, 0, TKO) {
            Some(MissionReply::Ack(a)) => {
                assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)
            }
            other => panic!("{other:?}"),
        }
        m.on_count(&count(1), 255, 190, 0);
        let mut bad = item(0, 1.0, 0.0, f32::NAN);
        bad.z = f32::NAN;
        match m.on_item(&bad, 255, 190, 0, TKO) {
            Some(MissionReply::Ack(a)) => assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_INVALID_PARAM7),
            other => panic!("{other:?}"),
        }
        m.on_count(&count(1), 255, 190, 0);
        let mut bad = item(0, 1.0, 0.0, -1.0);
        bad.command = MavCmd::MAV_CMD_NAV_LAND as u16;
        match m.on_item(&bad, 255, 190, 0, TKO) {
            Some(MissionReply::Ack(a)) => assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_UNSUPPORTED),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn stalled_upload_is_retried_then_cancelled() {
        let mut m = MissionUpload::new();
        m.on_count(&count(2), 255, 190, 0);
        assert_eq!(m.poll(RETRY_INTERVAL_US - 1), None);
        let mut t = 0;
        for _ in 0..MAX_RETRIES {
            t += RETRY_INTERVAL_US;
            assert_eq!(req_seq(m.poll(t)), Some(0));
        }
        t += RETRY_INTERVAL_US;
        match m.poll(t) {
            Some(MissionReply::Ack(a)) => {
                assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_OPERATION_CANCELLED)
            }
            other => panic!("{other:?}"),
        }
        assert!(!m.is_receiving());
    }

    #[test]
    fn empty_mission_is_a_clear() {
        let mut m = MissionUpload::new();
        assert_eq!(m.on_count(&count(0), 255, 190, 0), MissionReply::Clear);
        assert!(m.path().is_empty());
    }

    #[test]
    fn download_serves_the_accepted_path_only() {
        let mut m = MissionUpload::new();
        m.on_count(&count(1), 255, 190, 0);
        assert_eq!(m.on_item(&item(0, 1.5, -2.0, -1.0), 255, 190, 0, TKO), Some(MissionReply::Complete));
        // Not accepted by the cascade yet: nothing to download.
        assert!(matches!(m.on_request_list(MavMissionType::MAV_MISSION_TYPE_MISSION, 9, 8),
            DownloadReply::Count(c) if c.count == 0 && (c.target_system, c.target_component) == (9, 8)));
        m.accept();
        match m.on_request_item(0, MavMissionType::MAV_MISSION_TYPE_MISSION, 9, 8) {
            DownloadReply::Item(i) => assert_eq!((i.x, i.y, i.z, i.current), (15_000, -20_000, -1.0, 1)),
            other => panic!("{other:?}"),
        }
        // A failed later upload keeps the accepted path downloadable.
        m.on_count(&count(2), 255, 190, 0);
        m.on_item(&item(1, 1.0, 0.0, -1.0), 255, 190, 0, TKO);
        assert!(matches!(m.on_request_list(MavMissionType::MAV_MISSION_TYPE_MISSION, 9, 8),
            DownloadReply::Count(c) if c.count == 1));
        m.clear();
        assert_eq!(m.stored_len(), 0);
    }

    /// A download returns every item field for field as uploaded: param1–4 (hold time,
    /// acceptance radius, pass radius, yaw; a DO_CHANGE_SPEED's speed type and speed), x, y, z,
    /// command, frame, autocontinue and mission_type. Before: param1–4 came back 0 and
    /// autocontinue 1, and MAVSDK's `download_mission` failed UNSUPPORTED on the difference.
    #[test]
    fn download_returns_every_field_as_uploaded() {
        let wp = MISSION_ITEM_INT_DATA {
            param1: 2.5,
            param2: 0.3,
            param3: 0.0,
            param4: f32::NAN,
            autocontinue: 1,
            ..item(0, 1.5, -2.0, -1.0)
        };
        let speed = MISSION_ITEM_INT_DATA {
            command: MavCmd::MAV_CMD_DO_CHANGE_SPEED as u16,
            param1: 1.0,
            param2: 0.7,
            param3: -1.0,
            autocontinue: 0,
            frame: MavFrame::MAV_FRAME_MISSION,
            ..item(1, 0.0, 0.0, 0.0)
        };
        let mut m = MissionUpload::new();
        m.on_count(&count(2), 255, 190, 0);
        m.on_item(&wp, 255, 190, 0, TKO);
        assert_eq!(m.on_item(&speed, 255, 190, 0, TKO), Some(MissionReply::Complete));
        m.accept();
        for up in [wp, speed] {
            let DownloadReply::Item(down) =
                m.on_request_item(up.seq, MavMissionType::MAV_MISSION_TYPE_MISSION, 9, 8)
            else {
                panic!("item {}", up.seq)
            };
            let key = |i: &MISSION_ITEM_INT_DATA| {
                let p = [i.param1, i.param2, i.param3, i.param4].map(f32::to_bits);
                (p, i.x, i.y, i.z.to_bits(), i.command, i.frame, i.autocontinue, i.mission_type, i.seq)
            };
            assert_eq!(key(&down), key(&up), "item {}", up.seq);
            assert_eq!(
                (down.target_system, down.target_component, down.current),
                (9, 8, u8::from(up.seq == 0))
            );
        }
    }

    fn global(seq: u16, frame: MavFrame, lat: i32, lon: i32, z: f32) -> MISSION_ITEM_INT_DATA {
        MISSION_ITEM_INT_DATA { x: lat, y: lon, frame, ..item(seq, 0.0, 0.0, z) }
    }

    fn refusal(r: Option<MissionReply>) -> MavMissionResult {
        match r {
            Some(MissionReply::Ack(a)) => a.mavtype,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn global_frames_become_local_ned_and_download_in_their_frame() {
        use parapet_core::wire::geo::ORIGIN;
        let mut m = MissionUpload::new();
        let mut speed = item(1, 0.0, 0.0, 0.0);
        speed.command = MavCmd::MAV_CMD_DO_CHANGE_SPEED as u16;
        speed.frame = MavFrame::MAV_FRAME_MISSION;
        let items = [
            global(0, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, ORIGIN.0 + 8983, ORIGIN.1 + 6635, 10.0),
            speed,
            global(2, MavFrame::MAV_FRAME_GLOBAL_INT, ORIGIN.0 - 898, ORIGIN.1, 493.0),
            global(3, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT, ORIGIN.0, ORIGIN.1 - 1327, 2.0),
            global(4, MavFrame::MAV_FRAME_GLOBAL, ORIGIN.0 + 1, ORIGIN.1 + 1, 488.5),
            item(5, 1.5, -2.0, -1.0),
        ];
        m.on_count(&count(items.len() as u16), 255, 190, 0);
        for (k, it) in items.iter().enumerate() {
            let r = m.on_item(it, 255, 190, 0, TKO);
            if k + 1 < items.len() {
                assert_eq!(req_seq(r), Some(k as u16 + 1));
            } else {
                assert_eq!(r, Some(MissionReply::Complete));
            }
        }
        let expect = [
            Vec3::new(100.0, 50.0, -10.0),
            Vec3::new(-10.0, 0.0, -5.0),
            Vec3::new(0.0, -10.0, -2.0),
            Vec3::new(1.0 / 89.831_53, 1.0 / 132.709_22, -0.5),
            Vec3::new(1.5, -2.0, -1.0),
        ];
        assert_eq!(m.path().len(), expect.len(), "DO_CHANGE_SPEED is not a waypoint");
        for (got, want) in m.path().iter().zip(expect) {
            assert!((got - want).norm() < 0.01, "{got:?} vs {want:?}");
        }
        m.accept();
        // Every item comes back with its seq, command and frame (before: the DO_CHANGE_SPEED
        // was dropped and the waypoints renumbered 0..4).
        for (seq, sent) in items.iter().enumerate() {
            match m.on_request_item(seq as u16, MavMissionType::MAV_MISSION_TYPE_MISSION, 9, 8) {
                DownloadReply::Item(i) => {
                    assert_eq!(
                        (i.seq, i.command, i.frame, i.x, i.y),
                        (seq as u16, sent.command, sent.frame, sent.x, sent.y),
                        "item {seq}"
                    );
                    assert!((i.z - sent.z).abs() < 1e-3, "item {seq}: {} vs {}", i.z, sent.z);
                }
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn bad_global_items_are_refused_with_the_parameter() {
        use parapet_core::wire::geo::ORIGIN;
        let rel = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
        for (it, want) in [
            (global(0, rel, 900_000_001, ORIGIN.1, 5.0), MavMissionResult::MAV_MISSION_INVALID_PARAM5_X),
            (
                global(0, rel, ORIGIN.0 + 1_000_000, ORIGIN.1, 5.0),
                MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
            ),
            (global(0, rel, ORIGIN.0, -1_800_000_001, 5.0), MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y),
            (global(0, rel, ORIGIN.0, ORIGIN.1, f32::NAN), MavMissionResult::MAV_MISSION_INVALID_PARAM7),
            (
                global(0, MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT, ORIGIN.0, ORIGIN.1, 5.0),
                MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
            ),
            (
                MISSION_ITEM_INT_DATA {
                    command: MavCmd::MAV_CMD_NAV_LOITER_TURNS as u16,
                    ..global(0, rel, ORIGIN.0, ORIGIN.1, 5.0)
                },
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
            ),
            (
                MISSION_ITEM_INT_DATA {
                    command: MavCmd::MAV_CMD_NAV_LOITER_TIME as u16,
                    param1: -2.0,
                    ..global(0, rel, ORIGIN.0, ORIGIN.1, 5.0)
                },
                MavMissionResult::MAV_MISSION_INVALID_PARAM1,
            ),
            (
                MISSION_ITEM_INT_DATA {
                    command: MavCmd::MAV_CMD_NAV_TAKEOFF as u16,
                    ..global(0, rel, 0, 0, 0.0)
                },
                MavMissionResult::MAV_MISSION_INVALID_PARAM7,
            ),
        ] {
            let mut m = MissionUpload::new();
            m.on_count(&count(1), 255, 190, 0);
            assert_eq!(refusal(m.on_item(&it, 255, 190, 0, TKO)), want, "{it:?}");
            assert!(m.path().is_empty() && !m.is_receiving());
        }
    }

    /// A TAKEOFF above `MIS_TKO_ALT_MAX` fails the upload with INVALID_PARAM7 (before: accepted,
    /// and only the mission start was DENIED); at the limit it is accepted.
    #[test]
    fn a_takeoff_above_the_limit_is_refused_at_upload() {
        use parapet_core::wire::geo::ORIGIN;
        let rel = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
        let takeoff = |z| MISSION_ITEM_INT_DATA {
            command: MavCmd::MAV_CMD_NAV_TAKEOFF as u16,
            ..global(0, rel, ORIGIN.0, ORIGIN.1, z)
        };
        for (z, limit, want) in [
            (50.0, TKO, None),
            (120.0, TKO, None),
            (120.5, TKO, Some(MavMissionResult::MAV_MISSION_INVALID_PARAM7)),
            (12.0, 10.0, Some(MavMissionResult::MAV_MISSION_INVALID_PARAM7)),
            (10.0, 10.0, None),
        ] {
            let mut m = MissionUpload::new();
            m.on_count(&count(1), 255, 190, 0);
            let r = m.on_item(&takeoff(z), 255, 190, 0, limit);
            match want {
                None => assert_eq!(r, Some(MissionReply::Complete), "{z} m under {limit} m"),
                Some(e) => {
                    assert_eq!(refusal(r), e, "{z} m over {limit} m");
                    assert!(m.path().is_empty() && !m.is_receiving());
                }
            }
        }
    }

    fn cmd(seq: u16, command: MavCmd, lat: i32, lon: i32, z: f32) -> MISSION_ITEM_INT_DATA {
        MISSION_ITEM_INT_DATA {
            command: command as u16,
            ..global(seq, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, lat, lon, z)
        }
    }

    fn upload(m: &mut MissionUpload, items: &[MISSION_ITEM_INT_DATA]) -> Option<MissionReply> {
        m.on_count(&count(items.len() as u16), 255, 190, 0);
        let mut last = None;
        for it in items {
            last = m.on_item(it, 255, 190, 0, TKO);
            if matches!(last, Some(MissionReply::Ack(_))) {
                break;
            }
        }
        last
    }

    /// QGroundControl's default plan shape: TAKEOFF (here), waypoints, a DO_CHANGE_SPEED, RTL.
    /// Before: the TAKEOFF was refused MAV_MISSION_UNSUPPORTED.
    #[test]
    fn takeoff_waypoints_and_return_keep_their_seqs() {
        use parapet_core::wire::geo::ORIGIN;
        use MavCmd::*;
        let items = [
            cmd(0, MAV_CMD_NAV_TAKEOFF, 0, 0, 2.5),
            cmd(1, MAV_CMD_NAV_WAYPOINT, ORIGIN.0 + 180, ORIGIN.1, 2.0),
            cmd(2, MAV_CMD_DO_CHANGE_SPEED, 0, 0, 0.0),
            cmd(3, MAV_CMD_NAV_WAYPOINT, ORIGIN.0 + 180, ORIGIN.1 + 265, 2.0),
            cmd(4, MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0),
            cmd(5, MAV_CMD_DO_SET_CAM_TRIGG_DIST, 0, 0, 0.0),
        ];
        assert_eq!(upload(&mut m_new(), &items), Some(MissionReply::Complete));
        let mut m = m_new();
        upload(&mut m, &items);
        let path = m.path();
        assert_eq!(path.len(), 2, "the takeoff climbs where the vehicle is: no path point");
        assert!((path[0] - Vec3::new(2.0, 0.0, -2.0)).norm() < 0.01, "{:?}", path[0]);
        assert!((path[1] - Vec3::new(2.0, 2.0, -2.0)).norm() < 0.01, "{:?}", path[1]);
        m.accept();
        let plan = m.plan();
        assert_eq!(plan.count, 6);
        assert_eq!(plan.takeoff, Some((0, 2.5)));
        assert_eq!(plan.end, Some((4, EndAction::Return)));
        assert_eq!((plan.path_len, plan.land_approach), (2, false));
        assert_eq!((m.path_seq(0), m.path_seq(1), m.path_seq(2)), (Some(1), Some(3), None));
        // Done through: the DO items after a navigation item go with it.
        assert_eq!(
            (m.done_through(0), m.done_through(1), m.done_through(3), m.done_through(4)),
            (0, 2, 3, 5)
        );
    }

    /// The executor's walk over a QGroundControl-style plan: flights run up to the first item
    /// with an action; pauses, speed changes and the end come one by one.
    #[test]
    fn next_from_splits_the_plan_at_the_items_with_actions() {
        use crate::link::mission_items::Action;
        use parapet_core::wire::geo::ORIGIN;
        use MavCmd::*;
        let with = |mut it: MISSION_ITEM_INT_DATA, p: [f32; 4]| {
            [it.param1, it.param2, it.param3, it.param4] = p;
            it
        };
        let items = [
            cmd(0, MAV_CMD_NAV_TAKEOFF, 0, 0, 1.0),
            cmd(1, MAV_CMD_NAV_WAYPOINT, ORIGIN.0 + 90, ORIGIN.1, 1.0),
            with(cmd(2, MAV_CMD_NAV_WAYPOINT, ORIGIN.0 + 180, ORIGIN.1, 1.0), [2.0, 0.3, 0.0, f32::NAN]),
            with(cmd(3, MAV_CMD_NAV_LOITER_TIME, ORIGIN.0 + 180, ORIGIN.1 + 133, 1.0), [1.5, 0.0, 0.0, 0.0]),
            with(cmd(4, MAV_CMD_NAV_DELAY, 0, 0, 0.0), [1.0, -1.0, -1.0, -1.0]),
            with(cmd(5, MAV_CMD_DO_CHANGE_SPEED, 0, 0, 0.0), [1.0, 0.5, -1.0, 0.0]),
            with(cmd(6, MAV_CMD_CONDITION_YAW, 0, 0, 0.0), [90.0, 20.0, 1.0, 0.0]),
            cmd(7, MAV_CMD_NAV_WAYPOINT, ORIGIN.0, ORIGIN.1 + 133, 1.0),
            cmd(8, MAV_CMD_DO_SET_CAM_TRIGG_DIST, 0, 0, 0.0),
            cmd(9, MAV_CMD_NAV_WAYPOINT, ORIGIN.0, ORIGIN.1, 1.0),
            cmd(10, MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0),
        ];
        let mut m = m_new();
        assert_eq!(upload(&mut m, &items), Some(MissionReply::Complete));
        m.accept();
        assert_eq!(m.plan().path_len, 5);
        assert_eq!(m.next_from(0), Next::Fly { from: 0, to: 1, last: 2 }, "takeoff here, 1, held 2");
        assert_eq!(m.action_at(2), Some(Action::Hold { secs: Some(2.0), radius_m: 0.3 }));
        assert_eq!(m.next_from(3), Next::Fly { from: 2, to: 2, last: 3 }, "the loiter's point");
        assert_eq!(m.action_at(3), Some(Action::Hold { secs: Some(1.5), radius_m: 0.0 }));
        assert_eq!(m.next_from(4), Next::Act(4));
        assert_eq!(m.next_from(5), Next::Act(5));
        assert_eq!(m.action_at(5), Some(Action::Speed(Some(0.5))));
        assert_eq!(m.next_from(6), Next::Act(6));
        assert_eq!(m.next_from(7), Next::Fly { from: 3, to: 4, last: 9 }, "through the ignored DO item");
        assert_eq!(m.next_from(10), Next::End(10));
        assert!(m.ends_at(10) && !m.ends_at(9));
        assert_eq!(m.next_from(11), Next::Done);
        // A delay after RTL is refused like any navigation item.
        let mut bad = m_new();
        let late = [cmd(0, MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0), cmd(1, MAV_CMD_NAV_DELAY, 0, 0, 0.0)];
        assert_eq!(upload(&mut bad, &late).map(|r| matches!(r, MissionReply::Ack(_))), Some(true));
    }

    fn m_new() -> MissionUpload {
        MissionUpload::new()
    }

    /// LAND with a position gets an approach waypoint at the previous altitude; LAND "here"
    /// none; TAKEOFF with a position flies there at its altitude.
    #[test]
    fn land_and_takeoff_positions() {
        use parapet_core::wire::geo::ORIGIN;
        use MavCmd::*;
        let mut m = m_new();
        let items = [
            cmd(0, MAV_CMD_NAV_TAKEOFF, ORIGIN.0 + 90, ORIGIN.1, 3.0),
            cmd(1, MAV_CMD_NAV_WAYPOINT, ORIGIN.0 + 180, ORIGIN.1, 2.0),
            cmd(2, MAV_CMD_NAV_LAND, ORIGIN.0, ORIGIN.1 + 133, 0.0),
        ];
        assert_eq!(upload(&mut m, &items), Some(MissionReply::Complete));
        let path = m.path();
        assert_eq!(path.len(), 3);
        assert!((path[0] - Vec3::new(1.0, 0.0, -3.0)).norm() < 0.01, "{:?}", path[0]);
        assert!(
            (path[2] - Vec3::new(0.0, 1.0, -2.0)).norm() < 0.01,
            "approach at the last altitude: {:?}",
            path[2]
        );
        m.accept();
        let plan = m.plan();
        assert_eq!((plan.end, plan.land_approach), (Some((2, EndAction::Land)), true));
        assert_eq!(m.path_seq(2), Some(2));
        let here = [cmd(0, MAV_CMD_NAV_TAKEOFF, 0, 0, 3.0), cmd(1, MAV_CMD_NAV_LAND, 0, 0, 0.0)];
        assert_eq!(upload(&mut m, &here), Some(MissionReply::Complete));
        assert!(m.path().is_empty());
        m.accept();
        assert_eq!((m.plan().end, m.plan().land_approach), (Some((1, EndAction::Land)), false));
    }

    /// PX4's ordering rules: TAKEOFF only first, nothing that moves after LAND/RTL, a LAND
    /// position needs an altitude before it.
    #[test]
    fn item_order_is_checked() {
        use parapet_core::wire::geo::ORIGIN;
        use MavCmd::*;
        let wp = cmd(0, MAV_CMD_NAV_WAYPOINT, ORIGIN.0 + 180, ORIGIN.1, 2.0);
        for items in [
            vec![wp.clone(), cmd(1, MAV_CMD_NAV_TAKEOFF, 0, 0, 2.0)],
            vec![
                cmd(0, MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0),
                MISSION_ITEM_INT_DATA { seq: 1, ..wp.clone() },
            ],
            vec![cmd(0, MAV_CMD_NAV_LAND, 0, 0, 0.0), cmd(1, MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0)],
            vec![cmd(0, MAV_CMD_NAV_LAND, ORIGIN.0 + 90, ORIGIN.1, 0.0)],
        ] {
            let mut m = m_new();
            assert_eq!(
                refusal(upload(&mut m, &items)),
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
                "{items:?}"
            );
        }
        let mut m = m_new();
        let ok = [cmd(0, MAV_CMD_DO_CHANGE_SPEED, 0, 0, 0.0), cmd(1, MAV_CMD_NAV_TAKEOFF, 0, 0, 2.0)];
        assert_eq!(upload(&mut m, &ok), Some(MissionReply::Complete), "DO items may come first");
    }
}
