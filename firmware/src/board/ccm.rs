//! The memory the CPU alone reaches, for large buffers no DMA touches (issue 38: the on-board
//! replanner's planner, ≈ 29 KiB, and its request buffer, ≈ 3 KiB, `crate::app::replanner`): the linker's `.ccmram` section,
//! placed per board by the generated `ccm.x` (`firmware/build.rs`) — the F405's 64 KiB
//! core-coupled RAM at 0x1000_0000 (`memory-f405.x`'s `CCMRAM`); on QEMU's netduinoplus2, which
//! models no CCM but 192 KiB of SRAM, the 64 KiB past the F405's 128 KiB at 0x2002_0000, so that
//! the QEMU image's SRAM use and stack margin stay the F405's; on the H743 its `RAM`. The
//! section is NOLOAD: [`zero`] clears it at boot, before anything in it is used, so its statics
//! start as `.bss` ones do (all bytes zero, which a `ConstStaticCell` of an all-zero value needs).
//!
//! May import: `parapet_core` (the planner's type), `static_cell`.

use parapet_core::replan::onboard::ReplanRequest;
use parapet_core::replan::Replanner;
use static_cell::ConstStaticCell;

/// The replanner task's planner: [`Replanner::ZEROED`], all zero bytes, so the boot's
/// [`zero`] gives it its value (never built on a stack: ≈ 29 KiB); it takes the `RPL_*`
/// parameters with its first request.
#[link_section = ".ccmram"]
pub static PLANNER: ConstStaticCell<Replanner> = ConstStaticCell::new(Replanner::ZEROED);

/// The replanning request buffer (`app::replanner::ReplanMailbox::install`): all zero bytes
/// after [`zero`] too (every field's value is overwritten by each snapshot).
#[link_section = ".ccmram"]
pub static REQUEST: ConstStaticCell<ReplanRequest> = ConstStaticCell::new(ReplanRequest::ZEROED);

extern "C" {
    static mut __sccmram: u32;
    static mut __eccmram: u32;
}

/// Clears the `.ccmram` section (module docs). Call once, first thing at boot.
pub fn zero() {
    let start = core::ptr::addr_of_mut!(__sccmram) as usize;
    let end = core::ptr::addr_of_mut!(__eccmram) as usize;
    let mut a = start;
    while a < end {
        // SAFETY: [start, end) is the `.ccmram` section (linker symbols, word aligned), whose
        // statics nothing has referenced yet at boot; writing zeros gives them their initial
        // (all-zero) value, as cortex-m-rt does for `.bss`.
        unsafe { core::ptr::write_volatile(a as *mut u32, 0) };
        a += 4;
    }
}
