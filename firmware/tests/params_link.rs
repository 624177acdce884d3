//! The MAVLink parameter protocol end to end on the host: PARAM_SET / PARAM_REQUEST_READ
//! frames through the firmware's link into the real cascade, answered with PARAM_VALUE from
//! the one parameter table (`parapet_core::params::TABLE`): every parameter answers under its
//! table index and name, an out-of-range value is refused and answered with the value in
//! effect, any in-range value is taken whatever the order, and arming waits for a consistent
//! set.

use mavlink_core::MessageData;
use parapet_core::controller::ControllerParams;
use parapet_core::params::{COUNT, TABLE};
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::link::dialect::{
    MavCmd, MavParamType, MavResult, COMMAND_LONG_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA,
    PARAM_VALUE_DATA,
};
use parapet_firmware::link::framing::FrameWriter;
use parapet_firmware::link::outbound::{name, Outbound};
use parapet_firmware::link::{FixClock, Link};

struct Gcs {
    link: Link,
    ap: Cascade,
    w: FrameWriter,
}

impl Gcs {
    fn new() -> Self {
        let ap = Cascade::new(ControllerParams::default()).expect("default parameters");
        Gcs { link: Link::new(1, FixClock::Message), ap, w: FrameWriter::new(255, 190) }
    }

    fn send<D: MessageData>(&mut self, m: &D) -> Vec<Outbound> {
        let bytes = self.w.encode(m).raw_bytes().to_vec();
        self.link.push_bytes(&bytes, 0, &mut self.ap);
        core::iter::from_fn(|| self.link.pop_reply()).collect()
    }

    /// PARAM_SET `id` = `v`; the one PARAM_VALUE answer.
    fn set(&mut self, id: &str, v: f32) -> PARAM_VALUE_DATA {
        let m = PARAM_SET_DATA {
            param_value: v,
            target_system: 1,
            target_component: 1,
            param_id: name(id),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        };
        match &self.send(&m)[..] {
            [Outbound::ParamValue(v)] => v.clone(),
            other => panic!("PARAM_SET {id}: {other:?}"),
        }
    }

    fn read(&mut self, index: i16) -> PARAM_VALUE_DATA {
        let m = PARAM_REQUEST_READ_DATA {
            param_index: index,
            target_system: 1,
            target_component: 1,
            param_id: name(""),
        };
        match &self.send(&m)[..] {
            [Outbound::ParamValue(v)] => v.clone(),
            other => panic!("PARAM_REQUEST_READ {index}: {other:?}"),
        }
    }
}

fn id(v: &PARAM_VALUE_DATA) -> String {
    v.param_id.to_str().unwrap_or("").to_string()
}

#[test]
fn every_table_entry_answers_under_its_index_name_and_default() {
    let mut g = Gcs::new();
    for (i, p) in TABLE.iter().enumerate() {
        let v = g.read(i as i16);
        assert_eq!(
            (id(&v), usize::from(v.param_index), usize::from(v.param_count)),
            (p.name.into(), i, COUNT)
        );
        assert_eq!(v.param_value, p.default_value(), "{}", p.name);
    }
}

#[test]
fn out_of_range_is_refused_with_the_value_in_effect_and_in_range_is_taken() {
    let mut g = Gcs::new();
    for p in &TABLE {
        for bad in [p.min - (1.0 + p.min.abs()), p.max * 2.0 + 1.0, f32::NAN] {
            let v = g.set(p.name, bad);
            assert_eq!(
                (id(&v), v.param_value),
                (p.name.into(), p.default_value()),
                "{} = {bad} taken",
                p.name
            );
        }
        for good in [p.max, p.min, p.default_value()] {
            assert_eq!(g.set(p.name, good).param_value, good, "{} = {good}", p.name);
        }
    }
    assert_eq!(g.ap.flown_params(), &ControllerParams::default());
}

#[test]
fn a_heavier_vehicle_in_table_order_then_arming() {
    let mut g = Gcs::new();
    // Table order: VEH_MASS comes before VEH_ROTOR_TMAX and THR_MAX; each is taken at once.
    for (n, v) in [("VEH_MASS", 1.5f32), ("VEH_ROTOR_TMAX", 9.0), ("THR_MAX", 30.0)] {
        assert_eq!(g.set(n, v).param_value, v, "{n}");
        let consistent = n == "THR_MAX";
        assert_eq!(g.ap.params_consistent(), consistent, "after {n}");
    }
    assert_eq!(g.ap.flown_params().airframe.mass, 1.5);
    // δ1 below δ: stored, arming refused until it is lifted again.
    assert_eq!(g.set("CBF_DELTA1", 0.01).param_value, 0.01);
    let arm = COMMAND_LONG_DATA {
        param1: 1.0,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let acks: Vec<MavResult> = g
        .send(&arm)
        .into_iter()
        .filter_map(|r| match r {
            Outbound::CommandAck(a) => Some(a.result),
            _ => None,
        })
        .collect();
    assert_eq!(acks, vec![MavResult::MAV_RESULT_TEMPORARILY_REJECTED]);
    assert_eq!(g.ap.flown_params().cbf.delta1, 0.1);
    assert_eq!(g.set("CBF_DELTA1", 0.2).param_value, 0.2);
    assert!(g.ap.params_consistent());
    assert_eq!(g.ap.flown_params().cbf.delta1, 0.2);
}
