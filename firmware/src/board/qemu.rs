//! Board layer for QEMU's `netduinoplus2` (STM32F405 emulation without RCC, DMA or GPIO).
//!
//! - **Link**: USART1 at `0x4001_1000`, driven at register level (QEMU maps the first `-serial`
//!   to it). QEMU's USART holds one received byte (RXNE) and back-pressures the chardev while it
//!   is full; bytes that arrive *before* the firmware enables the USART are dropped by QEMU, which
//!   is why the link starts with a heartbeat handshake (see `firmware/README.md`). Reception is
//!   interrupt-driven: the USART1 interrupt moves DR into an embassy-sync [`Pipe`] that the
//!   application task awaits. (Polling the status register instead takes QEMU's I/O lock on
//!   every read and slows the lockstep ≈ 10×; QEMU lowers the USART interrupt only when DR is
//!   read.) When the pipe is full the interrupt is masked in the NVIC until the task drained
//!   it, so the USART back-pressures the host and no byte is lost.
//! - **Clock**: the control clock is the simulator's (HIL_SENSOR `time_usec`). SysTick runs
//!   free from the core clock (24-bit down-counter, reload 0xFF_FFFF) and, under
//!   `qemu -icount shift=0` (one instruction = 1 ns of virtual time), measures the instruction
//!   count of each control step, calibrated against a loop of known instruction count.
//! - **Masked sections**: this board supplies the `critical-section` implementation itself
//!   ([`MeasuredCriticalSection`]: PRIMASK like cortex-m's single-core one, plus the SysTick
//!   ticks from the outermost acquire to its release), so the PIL application can report the
//!   longest section with interrupts masked of every control step (`ins_masked`).
//! - No RCC/DMA/GPIO access; no defmt/RTT (nothing reads it in QEMU).

use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;

use crate::link::framing::FrameWriter;
use crate::link::outbound::Outbound;
use crate::pil::lockstep::{systick_elapsed, InstructionCalibration};

const USART1_BASE: usize = 0x4001_1000;
const SR: usize = USART1_BASE;
const DR: usize = USART1_BASE + 0x04;
const CR1: usize = USART1_BASE + 0x0C;
const SR_RXNE: u32 = 1 << 5;
const SR_TXE: u32 = 1 << 7;
const CR1_UE: u32 = 1 << 13;
const CR1_TE: u32 = 1 << 3;
const CR1_RE: u32 = 1 << 2;
const CR1_RXNEIE: u32 = 1 << 5;
/// NVIC interrupt number of USART1 on the STM32F405.
pub const USART1_IRQ: u16 = 37;

/// Received bytes, filled by the USART1 interrupt.
static RX: Pipe<CriticalSectionRawMutex, RX_CAPACITY> = Pipe::new();
/// Capacity of the receive pipe, bytes (more than one lockstep step of host traffic).
pub const RX_CAPACITY: usize = 1024;
/// The interrupt is masked because the pipe was full.
static RX_THROTTLED: AtomicBool = AtomicBool::new(false);

#[derive(Clone, Copy)]
struct Usart1Irq;
// SAFETY: 37 is USART1's position in the STM32F405 vector table (QEMU wires it the same way).
unsafe impl cortex_m::interrupt::InterruptNumber for Usart1Irq {
    fn number(self) -> u16 {
        USART1_IRQ
    }
}

/// USART1 interrupt body (call from the vector for IRQ 37): moves the received byte into the
/// pipe; with the pipe full, masks the interrupt and leaves the byte in DR (back-pressure).
pub fn on_usart1_interrupt() {
    if RX.is_full() {
        RX_THROTTLED.store(true, Ordering::Release);
        cortex_m::peripheral::NVIC::mask(Usart1Irq);
        return;
    }
    // SAFETY: USART1 registers (see `Usart1::new`); reading DR clears RXNE and lowers the line.
    unsafe {
        if read_volatile(SR as *const u32) & SR_RXNE != 0 {
            let b = read_volatile(DR as *const u32) as u8;
            // Cannot fail: the pipe has space (checked above; only this handler writes).
            let _ = RX.try_write(&[b]);
        }
    }
}

/// SysTick reload value (full 24 bits).
pub const SYSTICK_RELOAD: u32 = 0x00FF_FFFF;

/// Register-level USART1 (polling). Owning it means owning USART1; create it once.
pub struct Usart1 {
    peeked: Option<u8>,
}

impl Usart1 {
    /// Enables USART1 (UE, TE, RE). Baud rate registers are irrelevant under QEMU.
    pub fn new() -> Self {
        // SAFETY: fixed, aligned MMIO address of USART1 on the STM32F405; only this driver
        // touches USART1.
        unsafe { write_volatile(CR1 as *mut u32, CR1_UE | CR1_TE | CR1_RE | CR1_RXNEIE) };
        // SAFETY: unmasking USART1 in the NVIC; its handler (`on_usart1_interrupt`) is sound at
        // any time.
        unsafe { cortex_m::peripheral::NVIC::unmask(Usart1Irq) };
        Self { peeked: None }
    }

    /// Waits until at least one byte was received.
    pub async fn wait_readable(&mut self) {
        if self.peeked.is_none() {
            let mut b = [0u8; 1];
            if RX.read(&mut b).await == 1 {
                self.peeked = Some(b[0]);
            }
        }
    }

    /// Sleeps (WFI) until at least one byte was received. Halting the emulated core instead of
    /// spinning leaves the host CPU to QEMU's I/O thread, which delivers the next byte.
    /// Interrupts are masked around the check so the wake-up cannot be lost: a pending
    /// interrupt ends WFI even while masked, and runs when they are unmasked again.
    pub fn sleep_until_readable(&mut self) {
        if self.peeked.is_some() {
            return;
        }
        while RX.is_empty() {
            cortex_m::interrupt::disable();
            if RX.is_empty() {
                cortex_m::asm::wfi();
            }
            // SAFETY: re-enables interrupts after the masked check + WFI; no critical section is
            // open here.
            unsafe { cortex_m::interrupt::enable() };
        }
    }

    /// One received byte, if any.
    pub fn try_read(&mut self) -> Option<u8> {
        if let Some(b) = self.peeked.take() {
            return Some(b);
        }
        let mut b = [0u8; 1];
        let got = matches!(RX.try_read(&mut b), Ok(1));
        if RX_THROTTLED.swap(false, Ordering::AcqRel) {
            // SAFETY: the handler is sound at any time; the pipe has room again.
            unsafe { cortex_m::peripheral::NVIC::unmask(Usart1Irq) };
        }
        got.then_some(b[0])
    }

    /// Writes `bytes`, waiting for TXE before each (QEMU transmits at once).
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            write_byte(b);
        }
    }

    /// Encodes and writes one message.
    pub fn send(&mut self, writer: &mut FrameWriter, msg: &Outbound) {
        let raw = msg.encode(writer);
        self.write(raw.raw_bytes());
    }
}

impl Default for Usart1 {
    fn default() -> Self {
        Self::new()
    }
}

fn write_byte(b: u8) {
    // SAFETY: USART1 registers (see `Usart1::new`). The wait is bounded in practice by the
    // emulated USART, which sets TXE immediately after a write.
    unsafe {
        while read_volatile(SR as *const u32) & SR_TXE == 0 {}
        write_volatile(DR as *mut u32, u32::from(b));
    }
}

/// Panic path: writes `bytes` straight to USART1 (no driver instance needed).
pub fn panic_write(bytes: &[u8]) {
    // SAFETY: see `Usart1::new`; enabling an already enabled USART is harmless.
    unsafe { write_volatile(CR1 as *mut u32, CR1_UE | CR1_TE | CR1_RE) };
    for &b in bytes {
        write_byte(b);
    }
}

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

impl crate::pil::BytePort for Usart1 {
    fn try_read(&mut self) -> Option<u8> {
        Usart1::try_read(self)
    }
    fn write(&mut self, bytes: &[u8]) {
        Usart1::write(self, bytes)
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
