//! Processor-in-the-loop firmware for QEMU's `netduinoplus2` (STM32F405 emulation).
//!
//! Same cascade (`parapet-core`) and application code as the board firmware; the board layer is
//! `parapet_firmware::board::qemu` and the application `parapet_firmware::pil` (lockstep over
//! the semihosting console = QEMU's stdin/stdout, see `firmware/README.md`). Build:
//! `cargo build -p parapet-firmware --release --target thumbv7em-none-eabihf
//!  --no-default-features --features board-qemu --bin parapet-firmware-qemu`.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[cfg(target_os = "none")]
mod firmware {
    use embassy_executor::Spawner;
    use parapet_core::controller::ControllerParams;
    use parapet_firmware::app::cascade::Cascade;
    use parapet_firmware::board::qemu::{panic_write, InstructionCounter, Semihost};
    use parapet_firmware::link::dialect::MavSeverity;
    use parapet_firmware::link::framing::{FrameWriter, AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};
    use parapet_firmware::link::outbound::Outbound;
    use parapet_firmware::link::telemetry::status_text;
    use parapet_firmware::log::service::RamLogStore;
    use parapet_firmware::pil::{PilApp, CALIBRATION_ITERATIONS};
    use static_cell::ConstStaticCell;

    /// How long one handshake round reads the bytes already received: 1 ms of virtual time at
    /// the 168 MHz SysTick clock (≈ 10⁶ instructions, far more than one frame needs).
    const HEARTBEAT_PERIOD_TICKS: u32 = 168_000;

    /// The onboard log's RAM store (in .bss; `ConstStaticCell` hands it out without a copy
    /// through the stack).
    static LOG_STORE: ConstStaticCell<RamLogStore> = ConstStaticCell::new(RamLogStore::new());

    fn report_and_halt(text: &str) -> ! {
        let mut w = FrameWriter::new(VEHICLE_SYSTEM_ID, AUTOPILOT_COMPONENT_ID);
        let m = Outbound::StatusText(status_text(MavSeverity::MAV_SEVERITY_EMERGENCY, text, ""));
        panic_write(m.encode(&mut w).raw_bytes());
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let Some(cp) = cortex_m::Peripherals::take() else {
            report_and_halt("core peripherals taken twice");
        };
        let counter = InstructionCounter::new(cp.SYST);
        let calibration = counter.calibrate(CALIBRATION_ITERATIONS);
        let Some(port) = Semihost::open() else {
            report_and_halt("semihosting console refused");
        };
        let params = ControllerParams::default();
        let cascade = match Cascade::new(params) {
            Ok(c) => c,
            Err(_) => report_and_halt("controller parameters rejected"),
        };
        let app = PilApp::new(cascade, calibration).with_log(LOG_STORE.take(), &params);
        match lockstep(app, port, counter) {
            Ok(token) => spawner.spawn(token),
            Err(_) => report_and_halt("lockstep task spawn failed"),
        }
    }

    /// The PIL task: heartbeat handshake (one HEARTBEAT, then one more per batch of host bytes
    /// without a valid frame), then answer every HIL_SENSOR. Between batches the port sends what
    /// was collected and waits (the core halted) for the host.
    #[embassy_executor::task]
    async fn lockstep(mut app: PilApp<Cascade>, mut port: Semihost, counter: InstructionCounter) {
        while !app.handshake_round(&mut port, &counter, HEARTBEAT_PERIOD_TICKS) {
            port.wait_readable();
        }
        loop {
            app.poll(&mut port, &counter);
            port.wait_readable();
        }
    }

    #[panic_handler]
    fn panic(_info: &core::panic::PanicInfo) -> ! {
        cortex_m::interrupt::disable();
        // No motors in QEMU: report and stop answering (the host detects the silence).
        report_and_halt(parapet_core::wire::names::PANIC_TEXT);
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "parapet-firmware-qemu runs on thumbv7em-none-eabihf under qemu-system-arm (see firmware/README.md)"
    );
    std::process::exit(2);
}
