//! Board layer for QEMU's `netduinoplus2` (STM32F405 emulation without RCC, DMA or GPIO).
//!
//! - **Link**: the lockstep byte stream goes over **ARM semihosting** on the console (`:tt`),
//!   which QEMU 7.2 maps to its own stdin/stdout; the host holds both as pipes (see
//!   `firmware/README.md`, "QEMU lockstep protocol"): one `SYS_WRITE` per batch of frames
//!   (everything the firmware sends before it waits for input) and one `SYS_READ` of what the
//!   host sent so far (up to [`RX_CAPACITY`] bytes). The bytes are exactly the MAVLink frames
//!   the USART carried before and reach the same application code ([`crate::pil::PilApp`]);
//!   only the transport changed. Why not USART1: QEMU's USART model holds one received byte,
//!   so every received byte cost a main-loop round trip and an interrupt, and every sent byte
//!   one socket write; that was ≈ 19 ms of wall time per 1 ms step (measured,
//!   `firmware/README.md`, "PIL speed"). `SYS_READ` blocks in the host's `read(2)` while
//!   nothing was received (the core stands still, no virtual time passes), so waiting costs no
//!   emulation and no wake-ups. A `SYS_READ` that returns nothing means end of input (the host
//!   closed the pipe or is gone; also a non-blocking stdin): the firmware then ends QEMU with
//!   the semihosting exit call, so an emulator whose host died does not spin on.
//!   Written by hand on the crate's raw `syscall` (not `cortex_m_semihosting::hio`): that
//!   `write_all` loops without bound when the host writes nothing.
//! - **Clock**: the control clock is the simulator's (HIL_SENSOR `time_usec`). SysTick runs
//!   free from the core clock (24-bit down-counter, reload 0xFF_FFFF) and, under
//!   `qemu -icount shift=0` (one instruction = 1 ns of virtual time), measures the instruction
//!   count of each control step, calibrated against a loop of known instruction count.
//! - **Masked sections**: this board supplies the `critical-section` implementation itself
//!   ([`MeasuredCriticalSection`]: PRIMASK like cortex-m's single-core one, plus the SysTick
//!   ticks from the outermost acquire to its release), so the PIL application can report the
//!   longest section with interrupts masked of every control step (`ins_masked`).
//! - **Parameter store**: a RAM-backed NOR flash ([`param_flash`], a [`RamFlash`] in SRAM): QEMU 7.2 maps the STM32F405's flash as ROM
//!   (`memory_region_init_rom` in `hw/arm/stm32f405_soc.c`) and does not model the flash
//!   controller, so the firmware cannot program it. The store is erased at every start and
//!   lasts until QEMU exits.
//! - **Stack watermark**: [`paint_stack`] fills the unused stack (from cortex-m-rt's
//!   `_stack_end`, the top of `.bss`, up to the caller's frame) with a pattern at boot;
//!   [`stack_free_bytes`] later finds how much of it was never written: the margin left
//!   between the deepest stack use so far and the statics below it (0: the stack reached them).
//! - No RCC/DMA/GPIO access; no defmt/RTT (nothing reads it in QEMU). Without semihosting
//!   enabled in QEMU the first semihosting call faults (HardFault, no output): the host always
//!   enables it.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_semihosting::{nr, syscall};

use crate::link::framing::FrameWriter;
use crate::link::outbound::Outbound;
use crate::pil::lockstep::{systick_elapsed, InstructionCalibration};
use crate::storage::ram::RamFlash;
use static_cell::ConstStaticCell;

/// Capacity of the receive buffer, bytes: one `SYS_READ` takes at most this much (QEMU's
/// semihosting console FIFO holds 1024 bytes).
pub const RX_CAPACITY: usize = 1024;
/// Capacity of the transmit buffer, bytes: frames are collected here and written with one
/// `SYS_WRITE` when the firmware waits for input or the buffer would overflow (more than one
/// step's answer, ≈ 300–900 bytes).
pub const TX_CAPACITY: usize = 2048;
/// Attempts of one `SYS_WRITE` (each writes all or part of the rest; QEMU writes all at once).
const WRITE_ATTEMPTS: usize = 4;

/// The semihosting console as the lockstep byte link. Create it once.
pub struct Semihost {
    fd_in: usize,
    fd_out: usize,
    rx: [u8; RX_CAPACITY],
    rx_pos: usize,
    rx_len: usize,
    tx: [u8; TX_CAPACITY],
    tx_len: usize,
}

/// `SYS_OPEN` of the console `:tt` (mode 0 = read → stdin, mode 4 = write → stdout).
fn open_console(mode: usize) -> Option<usize> {
    let name = b":tt\0";
    // SAFETY: SYS_OPEN with a NUL-terminated name, its length without the NUL and a mode.
    let fd = unsafe { syscall!(OPEN, name.as_ptr(), mode, name.len() - 1) };
    (fd as isize >= 0).then_some(fd)
}

/// Writes `bytes` to semihosting file `fd` (bounded retries).
fn write_fd(fd: usize, bytes: &[u8]) {
    let mut rest = bytes;
    for _ in 0..WRITE_ATTEMPTS {
        if rest.is_empty() {
            return;
        }
        // SAFETY: SYS_WRITE of `rest` (valid for its length); returns the bytes NOT written.
        let left = unsafe { syscall!(WRITE, fd, rest.as_ptr(), rest.len()) };
        let done = rest.len().saturating_sub(left);
        rest = rest.get(done..).unwrap_or(&[]);
    }
}

impl Semihost {
    /// Opens the console for reading and writing; `None` if QEMU refuses.
    pub fn open() -> Option<Self> {
        let fd_in = open_console(nr::open::R)?;
        let fd_out = open_console(nr::open::W_TRUNC)?;
        Some(Self {
            fd_in,
            fd_out,
            rx: [0; RX_CAPACITY],
            rx_pos: 0,
            rx_len: 0,
            tx: [0; TX_CAPACITY],
            tx_len: 0,
        })
    }

    /// Writes the collected frames to the host (one `SYS_WRITE`).
    pub fn flush(&mut self) {
        if self.tx_len > 0 {
            write_fd(self.fd_out, self.tx.get(..self.tx_len).unwrap_or(&[]));
            self.tx_len = 0;
        }
    }

    /// Sends what was collected, then waits (the core halted by QEMU) until the host sent
    /// something and reads all of it that fits. Returns at once if bytes are still buffered.
    pub fn wait_readable(&mut self) {
        if self.rx_pos < self.rx_len {
            return;
        }
        self.flush();
        // SAFETY: SYS_READ into `rx` (valid for RX_CAPACITY bytes); returns the bytes NOT read.
        let left = unsafe { syscall!(READ, self.fd_in, self.rx.as_mut_ptr(), RX_CAPACITY) };
        self.rx_pos = 0;
        self.rx_len = RX_CAPACITY.saturating_sub(left);
        if self.rx_len == 0 {
            // End of input (see the module doc): nothing will ever arrive.
            cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_SUCCESS);
        }
    }

    /// One received byte, if buffered (never waits).
    pub fn try_read(&mut self) -> Option<u8> {
        let b = self.rx.get(self.rx_pos..self.rx_len)?.first().copied()?;
        self.rx_pos += 1;
        Some(b)
    }

    /// Collects `bytes` for the next write (writes first when they do not fit).
    pub fn write(&mut self, bytes: &[u8]) {
        if self.tx_len + bytes.len() > TX_CAPACITY {
            self.flush();
        }
        match self.tx.get_mut(self.tx_len..self.tx_len + bytes.len()) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                self.tx_len += bytes.len();
            }
            // Larger than the whole buffer: straight through.
            None => write_fd(self.fd_out, bytes),
        }
    }

    /// Encodes and collects one message.
    pub fn send(&mut self, writer: &mut FrameWriter, msg: &Outbound) {
        let raw = msg.encode(writer);
        self.write(raw.raw_bytes());
    }
}

/// Panic path: writes `bytes` straight to the console (no driver instance needed).
pub fn panic_write(bytes: &[u8]) {
    if let Some(fd) = open_console(nr::open::W_TRUNC) {
        write_fd(fd, bytes);
    }
}

/// SysTick reload value (full 24 bits).
pub const SYSTICK_RELOAD: u32 = 0x00FF_FFFF;

/// SysTick value at the outermost open critical section's acquire.
static MASKED_START: AtomicU32 = AtomicU32::new(0);
/// Longest critical section since the last [`take_masked_max_ticks`], SysTick ticks.
static MASKED_MAX: AtomicU32 = AtomicU32::new(0);

/// The `critical-section` implementation of this board: masks interrupts with PRIMASK (single
/// core, like cortex-m's `critical-section-single-core`) and measures each outermost section
/// on SysTick (instructions under `-icount shift=0`, see [`InstructionCounter`]).
pub struct MeasuredCriticalSection;
critical_section::set_impl!(MeasuredCriticalSection);

// SAFETY: single-core Cortex-M4: masking interrupts with PRIMASK excludes every other context;
// the restore state says whether this acquire masked them (outermost) so nesting is sound.
unsafe impl critical_section::Impl for MeasuredCriticalSection {
    unsafe fn acquire() -> critical_section::RawRestoreState {
        let was_enabled = cortex_m::register::primask::read().is_active();
        cortex_m::interrupt::disable();
        if was_enabled {
            MASKED_START.store(SYST::get_current(), Ordering::Relaxed);
        }
        was_enabled
    }

    unsafe fn release(was_enabled: critical_section::RawRestoreState) {
        if was_enabled {
            let ticks =
                systick_elapsed(MASKED_START.load(Ordering::Relaxed), SYST::get_current(), SYSTICK_RELOAD);
            if ticks > MASKED_MAX.load(Ordering::Relaxed) {
                MASKED_MAX.store(ticks, Ordering::Relaxed);
            }
            // SAFETY: this acquire masked them; no outer section is open.
            unsafe { cortex_m::interrupt::enable() };
        }
    }
}

/// Longest critical section since the previous call, SysTick ticks (and starts a new window).
pub fn take_masked_max_ticks() -> u32 {
    // Not through `critical_section` (that would measure itself): a plain masked swap.
    cortex_m::interrupt::free(|_| MASKED_MAX.swap(0, Ordering::Relaxed))
}

/// Free-running SysTick used as the instruction counter.
pub struct InstructionCounter {
    _syst: SYST,
}

impl InstructionCounter {
    /// Starts SysTick from the core clock, full reload, no interrupt.
    pub fn new(mut syst: SYST) -> Self {
        syst.disable_interrupt();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(SYSTICK_RELOAD);
        syst.clear_current();
        syst.enable_counter();
        Self { _syst: syst }
    }

    /// Current counter value (counts down).
    #[inline(always)]
    pub fn now(&self) -> u32 {
        SYST::get_current()
    }

    /// Ticks from `start` to now.
    #[inline(always)]
    pub fn since(&self, start: u32) -> u32 {
        systick_elapsed(start, self.now(), SYSTICK_RELOAD)
    }

    /// Runs the calibration loop twice (`n` and `2n` iterations of a 2-instruction loop) and
    /// returns ticks for exactly `2n` instructions (the difference cancels the call and
    /// register-read overhead).
    pub fn calibrate(&self, n: u32) -> InstructionCalibration {
        let t0 = self.now();
        spin(n);
        let short = self.since(t0);
        let t1 = self.now();
        spin(2 * n);
        let long = self.since(t1);
        InstructionCalibration { instructions: 2 * n, ticks: long.saturating_sub(short) }
    }
}

/// `iterations` × (`subs`, `bne`): exactly 2 instructions per iteration.
#[inline(never)]
fn spin(iterations: u32) {
    if iterations == 0 {
        return;
    }
    // SAFETY: a register-only countdown loop; no memory access, no stack use.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {0}, {0}, #1",
            "bne 2b",
            inout(reg) iterations => _,
            options(nomem, nostack),
        );
    }
}

impl crate::pil::BytePort for Semihost {
    fn try_read(&mut self) -> Option<u8> {
        Semihost::try_read(self)
    }
    fn write(&mut self, bytes: &[u8]) {
        Semihost::write(self, bytes)
    }
}

impl crate::pil::TickCounter for InstructionCounter {
    fn now(&self) -> u32 {
        InstructionCounter::now(self)
    }
    fn since(&self, start: u32) -> u32 {
        InstructionCounter::since(self, start)
    }
    fn take_masked_max(&self) -> u32 {
        take_masked_max_ticks()
    }
}

/// Erase page of the QEMU board's parameter flash, bytes.
pub const PARAM_FLASH_PAGE: usize = 2048;
/// Size of the QEMU board's parameter flash: two pages, the store's two slots (4 records of
/// the whole table each: an erase every 4th save).
pub const PARAM_FLASH_SIZE: usize = 2 * PARAM_FLASH_PAGE;
/// The QEMU board's parameter flash (module docs).
pub type ParamFlash = RamFlash<PARAM_FLASH_SIZE, PARAM_FLASH_PAGE>;

/// The flash in zeroed memory (not an 0xFF image in `.data`: that would cost the same again in
/// flash and did not leave the stack enough room at boot): the `.ccmram` section
/// (`board::ccm`, zeroed at boot; here the SRAM past the F405's 128 KiB), since it stands for
/// the F405's flash, not for its SRAM (in `.bss` it left the stack 1.7 KiB, and nothing with the
/// replanner's 130 B).
#[link_section = ".ccmram"]
static PARAM_FLASH: ConstStaticCell<ParamFlash> = ConstStaticCell::new(ParamFlash::zeroed());

/// The parameter store's RAM flash, erased (module docs); `None` after the first call.
/// QEMU's netduinoplus2 has no core-coupled memory (a write to 0x1000_0000 is a bus fault),
/// so it lives in SRAM (`board::ccm`'s stand-in).
pub fn param_flash() -> Option<&'static mut ParamFlash> {
    let flash = PARAM_FLASH.try_take()?;
    // Erased: every byte 0xFF (what `NorFlash::erase` does, without a future to run).
    flash.bytes_mut().fill(0xFF);
    Some(flash)
}

/// The pattern [`paint_stack`] writes.
const STACK_PAINT: u32 = 0x5AFE_57AC;
/// Bytes below the caller's stack pointer that [`paint_stack`] leaves alone (its own frame).
const PAINT_SKIP: usize = 256;

extern "C" {
    /// cortex-m-rt's lowest stack address (the end of `.bss`, 4-byte aligned).
    static mut _stack_end: u32;
}

/// Fills the stack below the caller (module docs). Call first thing at boot.
#[inline(never)]
pub fn paint_stack() {
    let bottom = core::ptr::addr_of_mut!(_stack_end) as usize;
    let top = (cortex_m::register::msp::read() as usize).saturating_sub(PAINT_SKIP) & !3;
    let mut a = bottom;
    while a < top {
        // SAFETY: [bottom, top) is the part of the stack below the current frame (minus a
        // margin for this function's own frame): memory no Rust object occupies; word aligned.
        unsafe { core::ptr::write_volatile(a as *mut u32, STACK_PAINT) };
        a += 4;
    }
}

/// Bytes of the painted stack never written since [`paint_stack`] (module docs).
pub fn stack_free_bytes() -> u32 {
    let bottom = core::ptr::addr_of_mut!(_stack_end) as usize;
    let top = cortex_m::register::msp::read() as usize;
    let mut a = bottom;
    // SAFETY: reads of the stack region below the current stack pointer, word aligned.
    while a < top && unsafe { core::ptr::read_volatile(a as *const u32) } == STACK_PAINT {
        a += 4;
    }
    (a - bottom) as u32
}
