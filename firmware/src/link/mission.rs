//! Mission protocol, vehicle side: upload MISSION_COUNT → MISSION_REQUEST_INT (seq 0..n−1) ↔
//! MISSION_ITEM_INT → MISSION_ACK; download MISSION_REQUEST_LIST → MISSION_COUNT, then
//! MISSION_REQUEST_INT(seq) → MISSION_ITEM_INT (the path the cascade accepted last); clear
//! MISSION_CLEAR_ALL or MISSION_COUNT 0 → the path is dropped, MISSION_ACK ACCEPTED.
//!
//! `mission_type`: only `MAV_MISSION_TYPE_MISSION` is stored. A geofence or rally upload or
//! download is answered MISSION_ACK `MAV_MISSION_UNSUPPORTED` (with that `mission_type`) and
//! does not touch the mission; MISSION_CLEAR_ALL with `MAV_MISSION_TYPE_ALL` clears the mission
//! (there is nothing else to clear), with fence/rally it is refused the same way.
//!
//! Accepted items: `MAV_CMD_NAV_WAYPOINT` in `MAV_FRAME_LOCAL_NED` (x, y = metres × 10⁴ as int32,
//! per the MAVLink local-frame convention for MISSION_ITEM_INT; z = metres, down positive), or in
//! a global frame as QGroundControl and MAVSDK's `mission` plugin send them (PX4 accepts only
//! these): `MAV_FRAME_GLOBAL` / `GLOBAL_INT` (z = m AMSL) and `GLOBAL_RELATIVE_ALT` /
//! `GLOBAL_RELATIVE_ALT_INT` (z = m above home); x, y = lat, lon × 10⁷ (MISSION_ITEM_INT carries
//! them as integers in every frame). They are converted to local NED around home by
//! [`crate::link::geo`] (lat outside ±90° or > 10 km from home → INVALID_PARAM5, lon →
//! INVALID_PARAM6, altitude → INVALID_PARAM7). Non-navigation items (DO_* such as
//! DO_CHANGE_SPEED, gimbal, camera and video commands) are accepted and ignored, as the path has
//! no place for them; NAV_TAKEOFF, NAV_LAND, NAV_RETURN_TO_LAUNCH and other NAV/CONDITION items
//! are refused MAV_MISSION_UNSUPPORTED (the mission model is a waypoint path: takeoff, landing
//! and return are commands). A download returns the waypoints (not the ignored items) in the
//! frame each was uploaded in (one byte per waypoint). The path is handed to the cascade only
//! when the last item arrived; the MISSION_ACK then reports whether the cascade took it.
//!
//! Capacity: [`MAX_WAYPOINTS`] items (MISSION_COUNT above that → MAV_MISSION_NO_SPACE). A stalled
//! upload re-requests the expected item every [`RETRY_INTERVAL_US`] and is cancelled
//! (MAV_MISSION_OPERATION_CANCELLED) after [`MAX_RETRIES`] re-requests.

use crate::link::dialect::{
    MavCmd, MavFrame, MavMissionResult, MavMissionType, MISSION_ACK_DATA, MISSION_COUNT_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
};
use crate::link::geo::{self, AltRef, GeoError};
use heapless::Vec as HVec;
use parapet_core::Vec3;

/// Most waypoints one upload may carry.
pub const MAX_WAYPOINTS: usize = 64;
/// Re-request period of a stalled upload, µs.
pub const RETRY_INTERVAL_US: u64 = 500_000;
/// Re-requests before the upload is cancelled.
pub const MAX_RETRIES: u8 = 4;
/// Scale of MISSION_ITEM_INT x/y in local frames (int32 = metres × 10⁴).
pub use parapet_core::wire::ids::LOCAL_XY_SCALE;
use parapet_core::wire::ids::{local_xy_from_wire, local_xy_to_wire};

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

/// The frame a waypoint was uploaded in (a download returns it in the same frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum ItemFrame {
    LocalNed,
    Global,
    GlobalInt,
    GlobalRelativeAlt,
    GlobalRelativeAltInt,
}

// MISSION_ITEM_INT still carries the *_INT frames (MAVSDK and QGroundControl send them).
#[allow(deprecated)]
impl ItemFrame {
    fn from_wire(f: MavFrame) -> Option<Self> {
        Some(match f {
            MavFrame::MAV_FRAME_LOCAL_NED => Self::LocalNed,
            MavFrame::MAV_FRAME_GLOBAL => Self::Global,
            MavFrame::MAV_FRAME_GLOBAL_INT => Self::GlobalInt,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT => Self::GlobalRelativeAlt,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => Self::GlobalRelativeAltInt,
            _ => return None,
        })
    }

    fn to_wire(self) -> MavFrame {
        match self {
            Self::LocalNed => MavFrame::MAV_FRAME_LOCAL_NED,
            Self::Global => MavFrame::MAV_FRAME_GLOBAL,
            Self::GlobalInt => MavFrame::MAV_FRAME_GLOBAL_INT,
            Self::GlobalRelativeAlt => MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            Self::GlobalRelativeAltInt => MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        }
    }

    /// Altitude reference of a global frame; `None` for the local frame.
    fn alt_ref(self) -> Option<AltRef> {
        match self {
            Self::LocalNed => None,
            Self::Global | Self::GlobalInt => Some(AltRef::Amsl),
            Self::GlobalRelativeAlt | Self::GlobalRelativeAltInt => Some(AltRef::Home),
        }
    }
}

/// `true` for commands a mission may carry that do not move the vehicle along the path
/// (DO_* 176–252, gimbal manager 1000–1001, camera/video 2000–2600): accepted and ignored.
fn is_ignored_command(cmd: u16) -> bool {
    matches!(cmd, 176..=252 | 1000..=1001 | 2000..=2600)
}

/// Vehicle side of the mission upload.
pub struct MissionUpload {
    state: State,
    items: HVec<Vec3, MAX_WAYPOINTS>,
    frames: HVec<ItemFrame, MAX_WAYPOINTS>,
    /// The path the cascade accepted last (what a download returns).
    stored: HVec<Vec3, MAX_WAYPOINTS>,
    stored_frames: HVec<ItemFrame, MAX_WAYPOINTS>,
    partner: (u8, u8),
}

impl Default for MissionUpload {
    fn default() -> Self {
        Self::new()
    }
}

impl MissionUpload {
    /// Idle, no path.
    pub const fn new() -> Self {
        Self {
            state: State::Idle,
            items: HVec::new(),
            frames: HVec::new(),
            stored: HVec::new(),
            stored_frames: HVec::new(),
            partner: (0, 0),
        }
    }

    /// `true` while an upload is in progress.
    pub fn is_receiving(&self) -> bool {
        matches!(self.state, State::Receiving { .. })
    }

    /// The waypoints of the last completed upload, NED, m.
    pub fn path(&self) -> &[Vec3] {
        &self.items
    }

    /// The path the cascade accepted last (download), NED, m.
    pub fn stored(&self) -> &[Vec3] {
        &self.stored
    }

    /// The cascade took [`MissionUpload::path`]: it becomes the stored (downloadable) path.
    pub fn accept(&mut self) {
        self.stored.clone_from(&self.items);
        self.stored_frames.clone_from(&self.frames);
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

    /// MISSION_REQUEST_LIST of `mission_type` from (`sys`, `comp`): the stored path's count,
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
            count: self.stored.len() as u16,
            target_system: sys,
            target_component: comp,
            mission_type,
            opaque_id: 0,
        })
    }

    /// MISSION_REQUEST_INT(`seq`) of `mission_type` from (`sys`, `comp`): the stored item as
    /// MISSION_ITEM_INT (NAV_WAYPOINT in the frame it was uploaded in: LOCAL_NED x/y = m × 10⁴,
    /// global x/y = lat/lon × 10⁷), or a refusal.
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
        let Some(w) = self.stored.get(usize::from(seq)) else {
            return DownloadReply::Ack(ack(
                sys,
                comp,
                MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
                mission_type,
            ));
        };
        let frame = self.stored_frames.get(usize::from(seq)).copied().unwrap_or(ItemFrame::LocalNed);
        let (x, y, z) = match frame.alt_ref() {
            None => (local_xy_to_wire(f64::from(w.x)), local_xy_to_wire(f64::from(w.y)), w.z),
            Some(alt_ref) => {
                // Stored waypoints came from global_to_ned, so they are in range.
                let (lat, lon, _) = geo::ned_to_global(*w).unwrap_or((geo::HOME.0, geo::HOME.1, 0));
                (lat, lon, geo::altitude_m(w.z, alt_ref))
            }
        };
        DownloadReply::Item(MISSION_ITEM_INT_DATA {
            x,
            y,
            z,
            seq,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT as u16,
            target_system: sys,
            target_component: comp,
            frame: frame.to_wire(),
            current: u8::from(seq == 0),
            autocontinue: 1,
            mission_type,
            ..Default::default()
        })
    }

    fn fail(&mut self, result: MavMissionResult) -> MissionReply {
        self.state = State::Idle;
        self.items.clear();
        self.frames.clear();
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
        self.frames.clear();
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
    /// (no upload in progress, or from another partner).
    pub fn on_item(
        &mut self,
        msg: &MISSION_ITEM_INT_DATA,
        sys: u8,
        comp: u8,
        now_us: u64,
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
        if is_ignored_command(msg.command) {
            // Accepted, not stored (the path has no place for it).
        } else if msg.command != crate::link::command::id::WAYPOINT {
            return Some(self.fail(MavMissionResult::MAV_MISSION_UNSUPPORTED));
        } else {
            let wp = match waypoint(msg) {
                Ok(wp) => wp,
                Err(e) => return Some(self.fail(e)),
            };
            if self.items.push(wp.0).is_err() || self.frames.push(wp.1).is_err() {
                return Some(self.fail(MavMissionResult::MAV_MISSION_NO_SPACE));
            }
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

    /// MISSION_CLEAR_ALL: drops the stored path and any upload.
    pub fn clear(&mut self) {
        self.state = State::Idle;
        self.items.clear();
        self.frames.clear();
        self.stored.clear();
        self.stored_frames.clear();
    }
}

/// The NED waypoint of a NAV_WAYPOINT item and its frame, or the refusal.
fn waypoint(msg: &MISSION_ITEM_INT_DATA) -> Result<(Vec3, ItemFrame), MavMissionResult> {
    let frame = ItemFrame::from_wire(msg.frame).ok_or(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)?;
    let Some(alt_ref) = frame.alt_ref() else {
        if !msg.z.is_finite() {
            return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
        }
        return Ok((Vec3::new(local_xy_from_wire(msg.x), local_xy_from_wire(msg.y), msg.z), frame));
    };
    geo::global_to_ned(msg.x, msg.y, msg.z, alt_ref).map(|p| (p, frame)).map_err(|e| match e {
        GeoError::Latitude => MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
        GeoError::Longitude => MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y,
        GeoError::Altitude => MavMissionResult::MAV_MISSION_INVALID_PARAM7,
    })
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
        assert_eq!(req_seq(m.on_item(&item(0, 1.0, 0.0, -1.0), 255, 190, 10)), Some(1));
        assert_eq!(req_seq(m.on_item(&item(1, 2.5, -1.25, -1.5), 255, 190, 20)), Some(2));
        assert_eq!(m.on_item(&item(2, 3.0, 1.0, -2.0), 255, 190, 30), Some(MissionReply::Complete));
        assert_eq!(m.path().len(), 3);
        assert!((m.path()[1] - Vec3::new(2.5, -1.25, -1.5)).norm() < 1e-4);
        let ack = m.ack_for(MavMissionResult::MAV_MISSION_ACCEPTED);
        assert_eq!((ack.target_system, ack.target_component), (255, 190));
        assert!(!m.is_receiving());
    }

    #[test]
    fn duplicates_are_re_requested_and_gaps_abort() {
        let mut m = MissionUpload::new();
        m.on_count(&count(3), 255, 190, 0);
        m.on_item(&item(0, 1.0, 0.0, -1.0), 255, 190, 0);
        assert_eq!(req_seq(m.on_item(&item(0, 1.0, 0.0, -1.0), 255, 190, 0)), Some(1));
        match m.on_item(&item(2, 1.0, 0.0, -1.0), 255, 190, 0) {
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
        assert_eq!(m.on_item(&item(0, 1.0, 0.0, -1.0), 7, 1, 0), None);
        let mut bad = item(0, 1.0, 0.0, -1.0);
        bad.frame = MavFrame::MAV_FRAME_BODY_FRD;
        match m.on_item(&bad, 255, 190, 0) {
            Some(MissionReply::Ack(a)) => {
                assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)
            }
            other => panic!("{other:?}"),
        }
        m.on_count(&count(1), 255, 190, 0);
        let mut bad = item(0, 1.0, 0.0, f32::NAN);
        bad.z = f32::NAN;
        match m.on_item(&bad, 255, 190, 0) {
            Some(MissionReply::Ack(a)) => assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_INVALID_PARAM7),
            other => panic!("{other:?}"),
        }
        m.on_count(&count(1), 255, 190, 0);
        let mut bad = item(0, 1.0, 0.0, -1.0);
        bad.command = MavCmd::MAV_CMD_NAV_LAND as u16;
        match m.on_item(&bad, 255, 190, 0) {
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
        assert_eq!(m.on_item(&item(0, 1.5, -2.0, -1.0), 255, 190, 0), Some(MissionReply::Complete));
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
        m.on_item(&item(1, 1.0, 0.0, -1.0), 255, 190, 0);
        assert!(matches!(m.on_request_list(MavMissionType::MAV_MISSION_TYPE_MISSION, 9, 8),
            DownloadReply::Count(c) if c.count == 1));
        m.clear();
        assert!(m.stored().is_empty());
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
        use crate::link::geo::HOME;
        let mut m = MissionUpload::new();
        let mut speed = item(1, 0.0, 0.0, 0.0);
        speed.command = MavCmd::MAV_CMD_DO_CHANGE_SPEED as u16;
        speed.frame = MavFrame::MAV_FRAME_MISSION;
        let items = [
            global(0, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, HOME.0 + 8983, HOME.1 + 6635, 10.0),
            speed,
            global(2, MavFrame::MAV_FRAME_GLOBAL_INT, HOME.0 - 898, HOME.1, 493.0),
            global(3, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT, HOME.0, HOME.1 - 1327, 2.0),
            global(4, MavFrame::MAV_FRAME_GLOBAL, HOME.0 + 1, HOME.1 + 1, 488.5),
            item(5, 1.5, -2.0, -1.0),
        ];
        m.on_count(&count(items.len() as u16), 255, 190, 0);
        for (k, it) in items.iter().enumerate() {
            let r = m.on_item(it, 255, 190, 0);
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
        let waypoints = [&items[0], &items[2], &items[3], &items[4], &items[5]];
        for (seq, sent) in waypoints.iter().enumerate() {
            match m.on_request_item(seq as u16, MavMissionType::MAV_MISSION_TYPE_MISSION, 9, 8) {
                DownloadReply::Item(i) => {
                    assert_eq!((i.frame, i.x, i.y), (sent.frame, sent.x, sent.y), "item {seq}");
                    assert!((i.z - sent.z).abs() < 1e-3, "item {seq}: {} vs {}", i.z, sent.z);
                }
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn bad_global_items_are_refused_with_the_parameter() {
        use crate::link::geo::HOME;
        let rel = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
        for (it, want) in [
            (global(0, rel, 900_000_001, HOME.1, 5.0), MavMissionResult::MAV_MISSION_INVALID_PARAM5_X),
            (global(0, rel, HOME.0 + 1_000_000, HOME.1, 5.0), MavMissionResult::MAV_MISSION_INVALID_PARAM5_X),
            (global(0, rel, HOME.0, -1_800_000_001, 5.0), MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y),
            (global(0, rel, HOME.0, HOME.1, f32::NAN), MavMissionResult::MAV_MISSION_INVALID_PARAM7),
            (
                global(0, MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT, HOME.0, HOME.1, 5.0),
                MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
            ),
            (
                MISSION_ITEM_INT_DATA {
                    command: MavCmd::MAV_CMD_NAV_TAKEOFF as u16,
                    ..global(0, rel, HOME.0, HOME.1, 5.0)
                },
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
            ),
            (
                MISSION_ITEM_INT_DATA {
                    command: MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH as u16,
                    ..global(0, rel, HOME.0, HOME.1, 5.0)
                },
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
            ),
        ] {
            let mut m = MissionUpload::new();
            m.on_count(&count(1), 255, 190, 0);
            assert_eq!(refusal(m.on_item(&it, 255, 190, 0)), want, "{it:?}");
            assert!(m.path().is_empty() && !m.is_receiving());
        }
    }
}
