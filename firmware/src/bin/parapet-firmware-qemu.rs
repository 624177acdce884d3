//! Processor-in-the-loop firmware for QEMU's `netduinoplus2` (STM32F405 emulation).
//!
//! Same cascade (`parapet-core`) and application code as the board firmware; the board layer is
//! `parapet_firmware::board::qemu` and the application `parapet_firmware::pil` (lockstep over
//! the semihosting console = QEMU's stdin/stdout, see `firmware/README.md`). The cascade runs
//! inside `SetupVehicle` (PREFLIGHT_STORAGE / PREFLIGHT_CALIBRATION / DO_MOTOR_TEST, IMU
//! correction) with its parameter store on a **RAM-backed NOR flash** (`board::qemu::param_flash`,
//! 2 × 2 KiB pages in SRAM): QEMU 7.2's netduinoplus2 maps the STM32F405 flash as ROM and does
//! not model the flash controller, so the store lasts until QEMU exits. The store's work runs
//! between lockstep steps, never inside one (the board's lowest-priority context), and is
//! reported as NAMED_VALUE_INT `ins_store` (instructions of each call that used the flash); the
//! stack margin as `stack_free` (bytes never used since boot, `board::qemu::stack_free_bytes`).
//! The on-board replanner (issue 38) is served there too, as the board's lowest-priority
//! replanner task would serve it: its planner in `board::ccm` (QEMU's stand-in for the F405's
//! CCM), each plan reported as NAMED_VALUE_INT `ins_rpl` (its instructions).
//!
//! Stack: the 128 KiB SRAM holds `.bss` (≈ 70 KiB: the 32 KiB log ring, the application) and
//! the stack above it. Building the cascade at boot is the deepest use (≈ 59 KiB of frames);
//! the application is therefore built straight into a `static` from a small `main` frame and
//! the port and store are opened by the task (moved through `main` by value they overflowed the
//! stack into `.bss` at boot). Build:
//! `cargo build -p parapet-firmware --release --target thumbv7em-none-eabihf
//!  --no-default-features --features board-qemu --bin parapet-firmware-qemu`.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[cfg(target_os = "none")]
mod firmware {
    use embassy_executor::Spawner;
    use parapet_core::controller::ControllerParams;
    use parapet_core::replan::Replanner;
    use parapet_firmware::app::autopilot::ControlSteps;
    use parapet_firmware::app::cascade::Cascade;
    use parapet_firmware::board::ccm;
    use parapet_firmware::board::qemu::{
        paint_stack, panic_write, param_flash, stack_free_bytes, InstructionCounter, ParamFlash, Semihost,
        PARAM_FLASH_SIZE,
    };
    use parapet_firmware::link::dialect::MavSeverity;
    use parapet_firmware::link::framing::{FrameWriter, AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};
    use parapet_firmware::link::outbound::Outbound;
    use parapet_firmware::link::telemetry::status_text;
    use parapet_firmware::log::service::RamLogStore;
    use parapet_firmware::pil::lockstep::InstructionCalibration;
    use parapet_firmware::pil::{PilApp, CALIBRATION_ITERATIONS};
    use parapet_firmware::storage::ParamStore;
    use parapet_firmware::vehicle::SetupVehicle;
    use static_cell::{ConstStaticCell, StaticCell};

    /// NAMED_VALUE_INT of the instructions of one storage call that used the flash.
    const INS_STORE: &str = "ins_store";
    /// NAMED_VALUE_INT of the stack never used so far, bytes (`board::qemu::stack_free_bytes`).
    const STACK_FREE: &str = "stack_free";
    /// NAMED_VALUE_INT of the instructions of one served replanning request.
    const INS_RPL: &str = parapet_core::wire::names::INS_REPLAN;
    type Vehicle = SetupVehicle<Cascade>;

    /// How long one handshake round reads the bytes already received: 1 ms of virtual time at
    /// the 168 MHz SysTick clock (≈ 10⁶ instructions, far more than one frame needs).
    const HEARTBEAT_PERIOD_TICKS: u32 = 168_000;

    /// The onboard log's RAM store (`ConstStaticCell` hands it out without a copy through the
    /// stack). In `.ccmram` (`board::ccm`, zeroed at boot; here the SRAM past the F405's 128 KiB;
    /// its value is all zero bytes, as it was in `.bss`), since it stands for the board's SD
    /// card, not for its SRAM, as the parameter flash does: in `.bss` its 33 KB and the
    /// navigation filter's 4.5 KB in the cascade (issue 39) left the boot stack no room.
    #[link_section = ".ccmram"]
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
        ccm::zero();
        paint_stack();
        let Some(cp) = cortex_m::Peripherals::take() else {
            report_and_halt("core peripherals taken twice");
        };
        let counter = InstructionCounter::new(cp.SYST);
        let calibration = counter.calibrate(CALIBRATION_ITERATIONS);
        // The deepest stack use of the whole run (building the cascade): with as little as
        // possible in this frame (the port and the store are opened by the task).
        let app = build_app(calibration);
        let Some(planner) = ccm::PLANNER.try_take() else { report_and_halt("replanner taken twice") };
        let Some(request) = ccm::REQUEST.try_take() else { report_and_halt("replan request taken twice") };
        app.autopilot_mut().install_replan(request);
        match lockstep(app, counter, planner) {
            Ok(token) => spawner.spawn(token),
            Err(_) => report_and_halt("lockstep task spawn failed"),
        }
    }

    /// The application, in a `static` (module docs: the boot stack).
    static APP: StaticCell<PilApp<Vehicle>> = StaticCell::new();

    /// The cascade in its setup wrapper with the onboard log, in [`APP`] (halts when the
    /// default parameters are refused).
    #[inline(never)]
    fn build_app(calibration: InstructionCalibration) -> &'static mut PilApp<Vehicle> {
        let params = ControllerParams::default();
        let cascade = match Cascade::new(params) {
            Ok(c) => c,
            Err(_) => report_and_halt("controller parameters rejected"),
        };
        let Some(slot) = APP.try_uninit() else { report_and_halt("application built twice") };
        let app = slot.write(PilApp::new(SetupVehicle::new(cascade, params), calibration));
        app.set_log(LOG_STORE.take(), &params);
        app
    }

    /// The PIL task: heartbeat handshake (one HEARTBEAT, then one more per batch of host bytes
    /// without a valid frame), then answer every HIL_SENSOR. Between batches the port sends what
    /// was collected and waits (the core halted) for the host. The stored parameters are loaded
    /// before the handshake (a RAM store: empty at every QEMU start); after each batch the
    /// store's due work runs (outside the control steps) and reports `ins_store`.
    #[embassy_executor::task]
    async fn lockstep(
        app: &'static mut PilApp<Vehicle>,
        counter: InstructionCounter,
        planner: &'static mut Replanner,
    ) {
        let Some(mut port) = Semihost::open() else {
            report_and_halt("semihosting console refused");
        };
        let Some(flash) = param_flash() else { report_and_halt("parameter flash taken twice") };
        let Some(mut store) = ParamStore::new(flash, 0..PARAM_FLASH_SIZE as u32) else {
            report_and_halt("parameter store layout refused");
        };
        boot_load(app, &mut store);
        while !app.handshake_round(&mut port, &counter, HEARTBEAT_PERIOD_TICKS) {
            port.wait_readable();
        }
        let mut free = u32::MAX;
        loop {
            // The stack margin after the boot and each step batch, when it shrank.
            let now_free = stack_free_bytes();
            if now_free < free {
                free = now_free;
                app.report(&mut port, STACK_FREE, free);
            }
            app.poll(&mut port, &counter);
            let t0 = counter.now();
            let used = storage_step(app, &mut store);
            let ticks = counter.since(t0);
            if used {
                let ins = app.calibration().instructions_for(ticks);
                app.report(&mut port, INS_STORE, ins);
            }
            let t0 = counter.now();
            if serve_replan(app, planner) {
                let ins = app.calibration().instructions_for(counter.since(t0));
                app.report(&mut port, INS_RPL, ins);
            }
            port.wait_readable();
        }
    }

    // The store's futures on the RAM flash never wait: run them to completion here, outside
    // the task's future (an `.await` in the task keeps their state, and LLVM's copies of it, in
    // the task: its poll frame grew to 58 KiB of stack and overflowed at boot).
    #[inline(never)]
    fn boot_load(app: &mut PilApp<Vehicle>, store: &mut ParamStore<&'static mut ParamFlash>) {
        embassy_futures::block_on(app.autopilot_mut().boot_load(store));
    }

    /// The replanner's plan, outside the task's poll (its frames, ≈ 1 KiB, only while it runs).
    #[inline(never)]
    fn serve_replan(app: &mut PilApp<Vehicle>, planner: &mut Replanner) -> bool {
        app.autopilot_mut().serve_replan(planner)
    }

    #[inline(never)]
    fn storage_step(app: &mut PilApp<Vehicle>, store: &mut ParamStore<&'static mut ParamFlash>) -> bool {
        let now = app.now_us();
        embassy_futures::block_on(app.autopilot_mut().storage_step(now, store))
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
