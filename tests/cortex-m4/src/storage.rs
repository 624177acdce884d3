//! Instruction counts of the firmware's parameter store (`firmware/src/storage`, included
//! by path) on a RAM NOR flash (issue 22): what a save costs the CPU in the low-priority
//! storage task. The F405's flash programming and erase times come on top (QEMU does not
//! model the flash controller): ~16 µs per 32-bit word, 1-2 s per 128 KiB sector erase
//! (STM32F405 datasheet), during which the single flash bank stalls every instruction fetch —
//! the reason the store saves only while disarmed.

#[path = "../../../firmware/src/storage/mod.rs"]
#[allow(dead_code)]
mod store;

use core::fmt::Write;
use core::future::Future;
use core::pin::pin;
use core::task::{Context, Poll, Waker};

use parapet_core::config::ControllerParams;
use parapet_core::params;

use super::{Console, Counter, Stats};
use store::ram::RamFlash;
use store::{Loaded, ParamStore};

/// The RAM flash's futures are ready at once: poll once (a second poll would mean a bug).
fn ready<T>(f: impl Future<Output = T>) -> T {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
}

/// Four 1 KiB pages = the store's two slots of 2 KiB, 4 records each: the saves below
/// switch slots (erase, the worst case) every 4th save, in 4 KiB of RAM. (The F405's slots
/// are 128 KiB sectors of 256 records: the boot scan reads 64 times as many positions.)
type Flash = RamFlash<4096, 1024>;

pub(crate) fn bench_storage(c: &Counter) {
    let mut s = match ParamStore::new(Flash::new(), 0..4096) {
        Some(s) => s,
        None => return,
    };
    let mut p = ControllerParams::default();
    let ins = c.measure_once(|| {
        let _ = ready(s.load(&mut p));
    }) / super::REPS as u64;
    let _ = writeln!(Console, "storage: load of an empty store: {ins} instructions");
    let mut changed = p;
    let _ = params::set(&mut changed, "CBF_MU", 2.0);
    let ins = c.measure_once(|| {
        let _ = ready(s.save(&changed));
    }) / super::REPS as u64;
    let _ = writeln!(Console, "storage: first save (one record, the whole table): {ins} instructions");
    // PARAM_SETs one at a time, each followed by its save: slots fill and are switched.
    let mut one = Stats::default();
    for k in 0..400u32 {
        let _ = params::set(&mut changed, "CBF_MU", 1.0 + (k % 50) as f32 * 0.01);
        one.add(c.measure_once(|| {
            let _ = ready(s.save(&changed));
        }));
    }
    one.report("storage: save of one changed parameter (400 saves, a slot switch every 4th)");
    let mut s = match ParamStore::new(s.into_flash(), 0..4096) {
        Some(s) => s,
        None => return,
    };
    let mut q = ControllerParams::default();
    let mut loaded = Loaded::Empty;
    let ins = c.measure_once(|| {
        loaded = ready(s.load(&mut q));
    }) / super::REPS as u64;
    let _ = writeln!(
        Console,
        "storage: boot load of the full set ({loaded:?}, CBF_MU {}): {ins} instructions",
        params::get(&q, "CBF_MU").unwrap_or(f32::NAN)
    );
}
