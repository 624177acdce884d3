//! Instruction counts of Parapet's control code on a Cortex-M4F, measured in
//! QEMU (`netduinoplus2`, STM32F405) with `-icount shift=0` (issue 9).
//!
//! Under `-icount shift=0` QEMU advances virtual time by 1 ns per guest
//! instruction and SysTick (core clock, 168 MHz) counts virtual time, so
//! SysTick ticks measure executed instructions. The ratio is calibrated at
//! start-up with a loop of known length (`subs`/`bne`, 2 instructions per
//! turn) and the cost of an empty measurement is subtracted. Each call is
//! repeated [`REPS`] times on the same input so one tick (≈ 6 instructions)
//! becomes a fraction of an instruction.
//!
//! What is measured (same code, parameters and release settings as the
//! firmware: `parapet-core` at opt-level 3, fat LTO):
//! * `SafetyFilter::apply` for the `multi`, `multi-relative` and `paper`
//!   variants with K = 1, 4, 16, 32 obstacles, on 64 seeded random problems per
//!   K drawn exactly as the host benchmark's (`parapet_tests::bench_states`);
//! * the cascade of `FlightController` flying a mission with 16 obstacles:
//!   `update_obstacles` (16 points), `step_outer`, `step_inner`, over 256 steps;
//! * the firmware's parameter store (`storage.rs`): load, first save, one-parameter saves.
//! * one on-board replan (`replan.rs`, issue 38): a typical detour and the worst case (every
//!   target unreachable: four full searches).
//!
//! Results go to the host console by semihosting; the program then exits QEMU.
//! Run: `cd tests/cortex-m4 && cargo run --release` (README.md).

#![no_std]
#![no_main]

use core::fmt::Write;
use core::hint::black_box;

mod check;
mod replan;
mod storage;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::entry;
use parapet_core::attitude::{AttitudeController, Euler};
use parapet_core::cbf::{FilterVariant, SafetyFilter};
use parapet_core::controller::{ControllerParams, FlightController, GuidanceMode, PositionFix};
use parapet_core::estimator::AttitudeEstimator;
use parapet_core::estimator::ImuSample;
use parapet_core::failsafe::FailsafeState;
use parapet_core::fmath;
use parapet_core::frame::wrap_pi;
use parapet_core::mixer::Mixer;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::outer::trajectory::{Trajectory, TrajectoryParams};
use parapet_core::plant_aware::{lag_time_constant, PlantAware, PlantAwareParams, StepInput};
use parapet_core::thrust::map_acceleration;
use parapet_core::tracking::{PdTracker, Reference};
use parapet_core::Vec3;

/// Repetitions of each measured call.
const REPS: u32 = 16;
/// Problems per obstacle count.
const PROBLEMS: usize = 64;
/// Seed of the problems (the host benchmark's timed set uses the same).
const SEED: u64 = 2024;

// ---------------------------------------------------------------- semihosting

fn semihosting(op: u32, arg: usize) -> u32 {
    let r: u32;
    // SAFETY: the ARM semihosting call (BKPT 0xAB); QEMU handles it with
    // `-semihosting-config enable=on`. r0 = operation, r1 = argument block.
    unsafe { core::arch::asm!("bkpt 0xAB", inout("r0") op => r, in("r1") arg, options(nostack)) };
    r
}

/// SYS_WRITE0 of `s` (copied into a NUL-terminated buffer, in chunks).
fn print(s: &str) {
    let mut buf = [0u8; 129];
    for chunk in s.as_bytes().chunks(128) {
        buf[..chunk.len()].copy_from_slice(chunk);
        buf[chunk.len()] = 0;
        semihosting(0x04, buf.as_ptr() as usize);
    }
}

struct Console;
impl Write for Console {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        print(s);
        Ok(())
    }
}

fn exit(ok: bool) -> ! {
    // SYS_EXIT with ADP_Stopped_ApplicationExit (0x20026) or ADP_Stopped_InternalError (0x20024).
    let reason = if ok { 0x20026 } else { 0x20024 };
    semihosting(0x18, reason);
    loop {
        cortex_m::asm::nop();
    }
}

#[cortex_m_rt::exception]
unsafe fn HardFault(_ef: &cortex_m_rt::ExceptionFrame) -> ! {
    print("HARD FAULT\n");
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let _ = writeln!(Console, "PANIC: {info}");
    exit(false)
}

// ---------------------------------------------------------------- counting

/// Instruction counter: SysTick ticks converted with the start-up calibration.
struct Counter {
    /// Owned so nothing else reprograms SysTick.
    _syst: SYST,
    /// Instructions per tick × 2^16 (fixed point).
    ins_per_tick_q16: u64,
    /// Instructions of an empty measurement of REPS turns (subtracted).
    overhead: u64,
    /// Instructions of an empty single measurement (subtracted).
    overhead_once: u64,
}

#[inline(always)]
fn now() -> u32 {
    SYST::get_current()
}

#[inline(always)]
fn ticks_since(start: u32) -> u32 {
    start.wrapping_sub(now()) & 0x00FF_FFFF
}

/// `n` turns of a 2-instruction loop.
#[inline(never)]
fn spin(n: u32) {
    // SAFETY: a register-only countdown loop.
    unsafe {
        core::arch::asm!("1:", "subs {0}, {0}, #1", "bne 1b", inout(reg) n => _, options(nomem, nostack));
    }
}

impl Counter {
    fn new(mut syst: SYST) -> Counter {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(0x00FF_FFFF);
        syst.clear_current();
        syst.enable_counter();
        // Calibration: 2 × 500 000 instructions (the call overhead is a few instructions).
        let n = 500_000u32;
        let t0 = now();
        spin(n);
        let ticks = ticks_since(t0).max(1) as u64;
        let ins_per_tick_q16 = ((2 * n as u64) << 16) / ticks;
        let _ = writeln!(Console, "calibration: {} instructions = {} SysTick ticks", 2 * n, ticks);
        let mut c = Counter { _syst: syst, ins_per_tick_q16, overhead: 0, overhead_once: 0 };
        c.overhead = c.measure(|| {});
        c.overhead_once = c.measure_once(|| {}) / REPS as u64;
        c
    }

    /// Instructions of `REPS` calls of `f` (minus the measuring overhead), × 1/REPS later.
    #[inline(always)]
    fn measure(&self, mut f: impl FnMut()) -> u64 {
        let t0 = now();
        for _ in 0..black_box(REPS) {
            f();
        }
        let ticks = ticks_since(t0) as u64;
        ((ticks * self.ins_per_tick_q16) >> 16).saturating_sub(self.overhead)
    }

    /// Instructions of one call of `f`, scaled by REPS (for stateful calls that must
    /// not be repeated; resolution one SysTick tick ≈ 6 instructions).
    #[inline(always)]
    fn measure_once(&self, mut f: impl FnMut()) -> u64 {
        let t0 = now();
        f();
        let ticks = ticks_since(t0) as u64;
        (((ticks * self.ins_per_tick_q16) >> 16).saturating_sub(self.overhead_once)) * REPS as u64
    }
}

/// Running statistics of per-call instruction counts (in 1/REPS units).
#[derive(Default)]
struct Stats {
    n: u64,
    sum: u64,
    min: u64,
    max: u64,
}

impl Stats {
    fn add(&mut self, total_over_reps: u64) {
        if self.n == 0 || total_over_reps < self.min {
            self.min = total_over_reps;
        }
        self.max = self.max.max(total_over_reps);
        self.sum += total_over_reps;
        self.n += 1;
    }
    fn report(&self, what: &str) {
        let r = REPS as u64;
        let _ = writeln!(
            Console,
            "{what}: mean {} min {} max {} instructions (n = {})",
            self.sum / (self.n.max(1) * r),
            self.min / r,
            self.max / r,
            self.n
        );
    }
}

// ---------------------------------------------------------------- problems

/// SplitMix64, as in `parapet_tests::bench_states`.
struct SplitMix64(u64);
impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
    fn direction(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.uniform(-1.0, 1.0), self.uniform(-1.0, 1.0), self.uniform(-1.0, 1.0));
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
    /// Unit vector within 75° of `axis` (`bench_states::FORWARD_HALF_ANGLE_DEG`).
    fn direction_forward(&mut self, axis: &Vec3) -> Vec3 {
        let cos_max = libm::cosf(75f32.to_radians());
        loop {
            let d = self.direction();
            if d.dot(axis) >= cos_max {
                return d;
            }
        }
    }
}

struct Problem {
    p: Vec3,
    v: Vec3,
    u_nom: Vec3,
    obstacles: [ObstaclePoint; 32],
    k: usize,
}

/// The next problem with `k` obstacles (the distribution of `bench_states::problems` with the
/// forward sector; same generator and seed, so the same problems up to the f32 round-off of
/// `cos 75°`).
fn next_problem(rng: &mut SplitMix64, k: usize) -> Problem {
    let p = Vec3::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0), rng.uniform(-3.0, -0.5));
    let heading = rng.direction();
    let v = heading * rng.uniform(0.0, 1.5);
    let mut obstacles = [ObstaclePoint::fixed(Vec3::zeros(), 0); 32];
    for (i, o) in obstacles.iter_mut().enumerate().take(k) {
        let r = if i == 0 {
            rng.uniform(0.24, 0.40)
        } else {
            let x = rng.unit();
            0.24 + 2.76 * x * x
        };
        *o = ObstaclePoint::fixed(p + rng.direction_forward(&heading) * r, i as u16);
    }
    let mut u_nom = rng.direction() * rng.uniform(0.0, 4.0);
    if rng.unit() < 0.5 {
        let towards = (obstacles[0].point - p).normalize();
        u_nom = (towards * 2.0 + rng.direction() * 0.5) * rng.uniform(0.5, 2.0);
    }
    Problem { p, v, u_nom, obstacles, k }
}

/// The filter with the controller's rule for the sample time (`ControllerParams::outer_params`).
fn filter(variant: FilterVariant) -> SafetyFilter {
    let params = ControllerParams { filter_variant: variant, ..ControllerParams::default() }.outer_params();
    match SafetyFilter::new(params.cbf, variant) {
        Ok(f) => f,
        Err(_) => exit(false),
    }
}

fn bench_filter(c: &Counter) {
    for variant in
        [FilterVariant::Multi, FilterVariant::MultiRelative, FilterVariant::Paper, FilterVariant::Braking]
    {
        let f = filter(variant);
        for k in [1usize, 4, 16, 32] {
            let mut rng = SplitMix64(SEED ^ (k as u64).wrapping_mul(0x1000_0000_01B3));
            let (mut all, mut hit) = (Stats::default(), Stats::default());
            for _ in 0..PROBLEMS {
                let pr = next_problem(&mut rng, k);
                let obs = &pr.obstacles[..pr.k];
                let ins = c.measure(|| {
                    black_box(f.apply(
                        black_box(&pr.p),
                        black_box(&pr.v),
                        black_box(&pr.u_nom),
                        black_box(obs),
                    ));
                });
                all.add(ins);
                if f.apply(&pr.p, &pr.v, &pr.u_nom, obs).1.intervened {
                    hit.add(ins);
                }
            }
            let mut name: heapless::String<64> = heapless::String::new();
            let _ = write!(name, "filter {} K={k}", variant.as_str());
            all.report(&name);
            name.clear();
            let _ = write!(name, "filter {} K={k} (intervened only)", variant.as_str());
            hit.report(&name);
        }
    }
    bench_plant_aware(c);
    bench_governor(c);
}

/// The speed governor (issue 36, `safety::governor::govern`) on the filter's problems: one
/// call per outer step before the filter, K = 1, 4, 16, 32 obstacle points, on, with the
/// F405 build's braking values (3 m/s², 0.1 s) and a 0.05 s data age.
fn bench_governor(c: &Counter) {
    use parapet_core::safety::governor::{govern, GovernorParams, Vehicle};
    let params = GovernorParams { enable: true, ..GovernorParams::default() };
    let veh = Vehicle { accel: 3.0, delay: 0.1, hull_radius: 0.22 };
    for k in [1usize, 4, 16, 32] {
        let mut rng = SplitMix64(SEED ^ (k as u64).wrapping_mul(0x1000_0000_01B3));
        let mut all = Stats::default();
        for _ in 0..PROBLEMS {
            let pr = next_problem(&mut rng, k);
            let obs = &pr.obstacles[..pr.k];
            let ins = c.measure(|| {
                black_box(govern(
                    black_box(&params),
                    black_box(&veh),
                    black_box(&pr.p),
                    black_box(&pr.v),
                    black_box(&pr.u_nom),
                    black_box(obs),
                    black_box(0.05),
                ));
            });
            all.add(ins);
        }
        let mut name: heapless::String<64> = heapless::String::new();
        let _ = write!(name, "governor K={k}");
        all.report(&name);
    }
}

/// The default filter as flown (issue 17): [`PlantAware::apply`] around multi-relative —
/// observer update, lag prediction, tangent planes, the ground plane, the filter, the
/// actual-state h̄. The wrapper has state; each call starts from the same primed copy.
fn bench_plant_aware(c: &Counter) {
    let f = filter(FilterVariant::MultiRelative);
    let rp = PlantAwareParams::default();
    let tau = lag_time_constant(&parapet_core::attitude::AttitudeParams::default().att_p, rp.motor_tau);
    // The limits the outer loop gives it (the default vehicle): the lag model is fed the
    // realisable command, as flown.
    let cp = parapet_core::config::ControllerParams::default();
    let limits = parapet_core::thrust::accel_limits(&cp.thrust, cp.airframe.mass);
    for k in [1usize, 4, 16, 32] {
        let mut rng = SplitMix64(SEED ^ (k as u64).wrapping_mul(0x1000_0000_01B3));
        let (mut all, mut hit) = (Stats::default(), Stats::default());
        for _ in 0..PROBLEMS {
            let pr = next_problem(&mut rng, k);
            let obs = &pr.obstacles[..pr.k];
            let input = StepInput {
                now_us: 1_000_000,
                dt: 1.0 / 250.0,
                p: pr.p,
                v: pr.v,
                u_pd: pr.u_nom,
                obstacles: obs,
                seen_from: Some(pr.p),
                boundaries: true,
                mission_running: true,
            };
            let mut primed = PlantAware::new(rp, tau).with_limits(limits);
            let _ = primed.apply(&f, &input);
            let ins = c.measure(|| {
                let mut pa = black_box(primed);
                black_box(pa.apply(black_box(&f), black_box(&input)));
            });
            all.add(ins);
            let mut pa = primed;
            if pa.apply(&f, &input).2.intervened {
                hit.add(ins);
            }
        }
        let mut name: heapless::String<64> = heapless::String::new();
        let _ = write!(name, "plant-aware multi-relative K={k}");
        all.report(&name);
        name.clear();
        let _ = write!(name, "plant-aware multi-relative K={k} (intervened only)");
        hit.report(&name);
    }
}

// ---------------------------------------------------------------- building blocks

fn bench_blocks(c: &Counter) {
    let mut rng = SplitMix64(1);
    let (mut sq, mut mx, mut bar) = (Stats::default(), Stats::default(), Stats::default());
    let (mut hsq, mut hmx) = (Stats::default(), Stats::default());
    let f = filter(FilterVariant::Multi);
    for _ in 0..64 {
        let x = rng.uniform(0.01, 10.0);
        let y = rng.uniform(0.01, 10.0);
        sq.add(c.measure(|| {
            black_box(libm::sqrtf(black_box(x)));
        }));
        mx.add(c.measure(|| {
            black_box(black_box(x).max(black_box(y)));
        }));
        hsq.add(c.measure(|| {
            black_box(fmath::sqrtf(black_box(x)));
        }));
        hmx.add(c.measure(|| {
            black_box(fmath::maxf(black_box(x), black_box(y)));
        }));
        let p = Vec3::new(x, y, -1.0);
        let v = rng.direction();
        let o = ObstaclePoint::fixed(p + rng.direction() * 0.3, 1);
        bar.add(c.measure(|| {
            black_box(f.barrier(black_box(&p), black_box(&v), black_box(&o)));
        }));
    }
    sq.report("libm::sqrtf (software)");
    hsq.report("parapet_core::fmath::sqrtf (VSQRT.F32)");
    mx.report("f32::max (compiles to a call of fmaxf)");
    hmx.report("parapet_core::fmath::maxf (compare and select)");
    bar.report("SafetyFilter::barrier (one obstacle)");
}

/// One outer step (4 ms) of the mission trajectory (issue 35, `parapet_core::outer::trajectory`)
/// along a 64-waypoint zigzag of 2 m legs turning ±30° at a 5 m/s cruise: 64 measurements, each
/// `REPS` consecutive steps, 100 unmeasured steps apart (the whole path is sampled: corners,
/// blends and the braking look-ahead over many pieces), and the in-place rebuild at a mission
/// start.
fn bench_trajectory(c: &Counter) {
    let params = TrajectoryParams { cruise_speed: 5.0, ..TrajectoryParams::default() };
    let mut pts: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let (mut x, mut y) = (0.0f32, 0.0f32);
    for i in 0..64 {
        let _ = pts.push(Vec3::new(x, y, -1.5));
        let a = if i % 2 == 0 { 0.5236f32 } else { -0.5236 };
        x += 2.0 * fmath::cosf(a);
        y += 2.0 * libm::sinf(a);
    }
    let mut t: Trajectory<64> = Trajectory::idle();
    let build = c.measure(|| {
        black_box(t.rebuild(black_box(params), black_box(&pts)).is_ok());
    });
    let mut build_stats = Stats::default();
    build_stats.add(build);
    if t.rebuild(params, &pts).is_err() {
        exit(false);
    }
    let mut step = Stats::default();
    for _ in 0..64 {
        step.add(c.measure(|| {
            black_box(t.step(black_box(0.004), black_box(1.0)).is_ok());
        }));
        for _ in 0..100 {
            let _ = t.step(0.004, 1.0);
        }
    }
    step.report("trajectory step (64-waypoint zigzag, 5 m/s)");
    build_stats.report("trajectory rebuild in place (64 waypoints)");
}

/// The parts of the cascade and the libm functions they call, each repeated on one input
/// (stateful parts too: repeating an estimator or PID update on the same sample is fine for
/// counting). Tells where the instructions of `step_outer`/`step_inner` go.
fn bench_cascade_parts(c: &Counter) {
    let report = |name: &str, ins: u64| {
        let _ = writeln!(Console, "part {name}: {} instructions", ins / REPS as u64);
    };
    let (x, y) = (black_box(0.3f32), black_box(-0.7f32));
    report(
        "libm::sincosf",
        c.measure(|| {
            black_box(libm::sincosf(black_box(x)));
        }),
    );
    report(
        "libm::cosf",
        c.measure(|| {
            black_box(libm::cosf(black_box(x)));
        }),
    );
    report(
        "libm::tanf",
        c.measure(|| {
            black_box(libm::tanf(black_box(x)));
        }),
    );
    report(
        "libm::atanf",
        c.measure(|| {
            black_box(libm::atanf(black_box(x)));
        }),
    );
    report(
        "libm::atan2f",
        c.measure(|| {
            black_box(libm::atan2f(black_box(x), black_box(y)));
        }),
    );
    report(
        "libm::acosf",
        c.measure(|| {
            black_box(libm::acosf(black_box(x)));
        }),
    );
    report(
        "libm::hypotf",
        c.measure(|| {
            black_box(libm::hypotf(black_box(x), black_box(y)));
        }),
    );
    report(
        "frame::wrap_pi (|a| < pi)",
        c.measure(|| {
            black_box(wrap_pi(black_box(x)));
        }),
    );
    let params = ControllerParams::default();
    let mut est = match AttitudeEstimator::new(params.estimator) {
        Ok(e) => e,
        Err(_) => exit(false),
    };
    let imu = ImuSample { gyro: Vec3::new(0.05, -0.1, 0.02), accel: Vec3::new(0.3, -0.2, -9.7) };
    est.update(&imu, 0.001, None, Some(0.1));
    report(
        "AttitudeEstimator::update (accel aid, external yaw)",
        c.measure(|| {
            black_box(est.update(black_box(&imu), 0.001, Some(Vec3::new(0.1, 0.0, 0.0)), Some(0.1)));
        }),
    );
    report(
        "AttitudeEstimator::euler",
        c.measure(|| {
            black_box(black_box(&est).euler());
        }),
    );
    report(
        "AttitudeEstimator::tilt",
        c.measure(|| {
            black_box(black_box(&est).tilt());
        }),
    );
    let mut att = match AttitudeController::new(params.attitude, params.airframe.inertia) {
        Ok(a) => a,
        Err(_) => exit(false),
    };
    let sp = Euler { roll: 0.1, pitch: -0.05, yaw: 0.2 };
    let now = est.euler();
    report(
        "AttitudeController::update",
        c.measure(|| {
            black_box(att.update(black_box(&sp), black_box(&now), &[0.1, -0.2, 0.05], 0.001, false));
        }),
    );
    let mixer = match Mixer::new(&params.airframe) {
        Ok(m) => m,
        Err(_) => exit(false),
    };
    report(
        "Mixer::mix",
        c.measure(|| {
            black_box(mixer.mix(black_box(5.0), black_box(&Vec3::new(0.01, -0.02, 0.001))));
        }),
    );
    let u = Vec3::new(0.8, -0.5, 0.3);
    report(
        "thrust::map_acceleration",
        c.measure(|| {
            black_box(map_acceleration(
                &params.thrust,
                params.airframe.mass,
                black_box(&u),
                0.2,
                0.05,
                -0.03,
            ));
        }),
    );
    let mut tracker = PdTracker::new(params.tracking);
    let r = Reference {
        position: Vec3::new(1.0, 0.0, -1.5),
        velocity: Vec3::new(0.25, 0.0, 0.0),
        acceleration: Vec3::zeros(),
        yaw: 0.0,
    };
    report(
        "PdTracker::update",
        c.measure(|| {
            black_box(tracker.update(
                black_box(&r),
                &Vec3::new(0.95, 0.05, -1.5),
                &Vec3::new(0.2, 0.0, 0.0),
                0.004,
            ));
        }),
    );
}

// ---------------------------------------------------------------- cascade

fn bench_cascade(c: &Counter) {
    let start = Vec3::new(0.0, 0.0, -1.5);
    let mut fc = match FlightController::new(ControllerParams::default()) {
        Ok(fc) => fc,
        Err(_) => exit(false),
    };
    if fc.set_path(&[start, start + Vec3::new(20_000.0, 0.0, 0.0)]).is_err() {
        exit(false);
    }
    let level = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -9.81) };
    let mut now = 0u64;
    for k in 0..500u64 {
        now = k * 1000;
        if k % 4 == 0 {
            fc.update_position(PositionFix {
                t_us: now,
                position: start,
                velocity: Vec3::zeros(),
                yaw: Some(0.0),
            });
            fc.update_obstacles(now, &[]);
            fc.step_outer(now);
        }
        fc.step_inner(now, &level);
    }
    if fc.arm(now).is_err() || fc.hold_position(now, start).is_err() {
        exit(false);
    }
    fc.step_outer(now);
    if fc.start_mission(now).is_err() {
        exit(false);
    }
    let t_mission = now;
    let mut rng = SplitMix64(SEED ^ 16u64.wrapping_mul(0x1000_0000_01B3));
    let mut noise = SplitMix64(7);
    let (mut upd, mut outer, mut inner, mut inner_plain) =
        (Stats::default(), Stats::default(), Stats::default(), Stats::default());
    let mut intervened = 0u32;
    let steps = 256;
    for _ in 0..steps {
        // One 4 ms period: fix + obstacles + outer, then 4 inner steps.
        let pr = next_problem(&mut rng, 16);
        let offset = noise.direction() * noise.uniform(0.0, 0.2);
        let gyro = noise.direction() * noise.uniform(0.0, 0.3);
        let imu = ImuSample {
            gyro,
            accel: Vec3::new(0.0, 0.0, -9.81) + noise.direction() * noise.uniform(0.0, 0.5),
        };
        now += 4000;
        let p = start + Vec3::new(0.25 * (now - t_mission) as f32 * 1e-6, 0.0, 0.0) + offset;
        let mut obs = [ObstaclePoint::fixed(Vec3::zeros(), 0); 16];
        for (o, src) in obs.iter_mut().zip(&pr.obstacles[..16]) {
            *o = ObstaclePoint { point: src.point - pr.p + p, velocity: Some(Vec3::zeros()), ..*src };
        }
        fc.update_position(PositionFix { t_us: now, position: p, velocity: pr.v, yaw: Some(0.0) });
        // The controller has state: each call is measured once (resolution ≈ 6 instructions).
        upd.add(c.measure_once(|| fc.update_obstacles(black_box(now), black_box(&obs))));
        outer.add(c.measure_once(|| fc.step_outer(black_box(now))));
        intervened += fc.telemetry().filter.intervened as u32;
        for j in 0..4u64 {
            let t = now + j * 1000;
            let ins = c.measure_once(|| {
                black_box(fc.step_inner(black_box(t), black_box(&imu)));
            });
            if j == 0 {
                inner.add(ins);
            } else {
                inner_plain.add(ins);
            }
        }
    }
    let _ = writeln!(
        Console,
        "cascade: filter intervened in {intervened} of {steps} outer steps; state {:?}, mode {:?}",
        fc.state(),
        fc.telemetry().mode
    );
    if fc.state() != FailsafeState::Armed || fc.telemetry().mode != GuidanceMode::Mission {
        print("cascade: the controller left the mission: figures are not valid\n");
        exit(false);
    }
    upd.report("cascade update_obstacles (16 points)");
    outer.report("cascade step_outer (16 obstacles)");
    inner.report("cascade step_inner");
    inner_plain.report("cascade step_inner (steps without outer)");
    let r = REPS as u64;
    let n = steps as u64 * r;
    let period = (upd.sum + outer.sum + inner.sum + inner_plain.sum) / n;
    let _ = writeln!(
        Console,
        "cascade: 1 ms step with the outer loop (update_obstacles + step_outer + step_inner): mean {} max {} instructions",
        (upd.sum + outer.sum + inner.sum) / n,
        (upd.max + outer.max + inner.max) / r
    );
    let _ = writeln!(
        Console,
        "cascade: 4 ms period (1 outer + 4 inner): mean {period} instructions, {} per 1 ms step",
        period / 4
    );
}

/// The obstacle memory (issue 19) on the firmware's configuration: `ObstacleMemory<64>`,
/// a 72-sector planar scan (OBSTACLE_DISTANCE, 5°, 8 m) of a 6 m × 6 m room with a pole,
/// the vehicle crossing it at 1 m/s, one scan per 0.1 s (40 scans). Per scan: `insert_scan`
/// (clearing, merge, tracks, frontier) and `select::<32>` (the points for the filter; the firmware
/// calls `select_set`, the same set without counting the dropped points).
/// `forward`: only the forward 90° of the scan carry ranges (a forward depth camera sent as
/// OBSTACLE_DISTANCE, the rest UINT16_MAX), flown with the speed cap (`PCP_FOV_WALLS` 0, as
/// with `MIS_YAW_MODE` travel), so that the free-cell map of the unrecorded sectors is marked
/// on every scan.
fn bench_memory(c: &Counter, forward: bool) {
    use parapet_core::obstacle_set::Ranking;
    use parapet_core::perception::{
        MemoryParams, ObstacleMemory, Pose, Range, Scan, ScanGeometry, SensorMount, FOV_WALLS_OFF,
    };
    let params = if forward {
        MemoryParams { fov_walls: FOV_WALLS_OFF, ..MemoryParams::default() }
    } else {
        MemoryParams::default()
    };
    let mut mem = ObstacleMemory::<64>::new(params);
    let g = ScanGeometry::planar_360(72, 0.1745, 0.1, 8.0);
    let (mut ins, mut sel, mut sel_set) = (Stats::default(), Stats::default(), Stats::default());
    let mut cells = 0usize;
    for k in 0..40u32 {
        let p = Vec3::new(-2.0 + 0.1 * k as f32, 0.2, -1.0);
        let mut ranges = [Range::Unknown; 72];
        for (col, r) in ranges.iter_mut().enumerate() {
            let u = g.direction(0, col as u16);
            // Walls x = ±3, y = ±3, pole of radius 0.1 at (1.5, 0.5).
            let mut best = f32::INFINITY;
            for (a, w) in [(u.x, 3.0 - p.x), (-u.x, 3.0 + p.x), (u.y, 3.0 - p.y), (-u.y, 3.0 + p.y)] {
                if a > 1e-6 {
                    best = best.min(w / a);
                }
            }
            let (dx, dy) = (p.x - 1.5, p.y - 0.5);
            let b = dx * u.x + dy * u.y;
            let disc = b * b - (dx * dx + dy * dy - 0.01);
            if disc >= 0.0 {
                let s = -b - fmath::sqrtf(disc);
                if s > 0.0 {
                    best = best.min(s);
                }
            }
            *r = if forward && u.x < u.y.abs() {
                Range::Unknown
            } else if best < 8.0 {
                Range::Hit(best)
            } else {
                Range::Clear
            };
        }
        let scan = Scan {
            t_us: 1_000_000 + u64::from(k) * 100_000,
            pose: Pose::from_rpy(p, 0.0, 0.0, 0.0),
            mount: SensorMount::centered(),
            geometry: g,
            ranges: &ranges,
        };
        ins.add(c.measure_once(|| {
            black_box(mem.insert_scan(black_box(&scan)));
        }));
        let v = Vec3::new(1.0, 0.0, 0.0);
        let ranking = Ranking::Critical { mu: 1.4, relative: true };
        sel.add(c.measure_once(|| {
            black_box(mem.select::<32>(scan.t_us, black_box(&p), &v, ranking, 0.1));
        }));
        sel_set.add(c.measure_once(|| {
            black_box(mem.select_set::<32>(scan.t_us, black_box(&p), &v, ranking, 0.1));
        }));
        cells = mem.len();
    }
    if forward {
        ins.report("ObstacleMemory<64>::insert_scan, 72 sectors, forward 90° only, free-cell map");
        sel.report("ObstacleMemory<64>::select::<32>, forward 90° only");
        sel_set.report("ObstacleMemory<64>::select_set::<32> (the firmware's), forward 90° only");
    } else {
        ins.report("ObstacleMemory<64>::insert_scan, 72 sectors");
        sel.report("ObstacleMemory<64>::select::<32>");
        sel_set.report("ObstacleMemory<64>::select_set::<32> (the firmware's)");
    }
    let _ = writeln!(Console, "memory cells after 40 scans: {cells}");
}

/// The navigation filter (`parapet_core::nav`, issue 39): one predict (IMU sample, 9×9
/// covariance) and one delayed position + velocity update (150 ms old), each measured once
/// per call over 64 IMU steps of a filter in flight.
fn bench_nav(c: &Counter) {
    use parapet_core::nav::{FixKind, NavFilter, NavParams};
    let mut f = NavFilter::new(NavParams::default());
    let rot = parapet_core::frame::rotation_from_euler(0.05, -0.03, 0.4);
    let acc = rot.inverse() * Vec3::new(0.3, -0.2, -9.81);
    let _ = f.predict(0, &acc, &rot);
    let _ = f.fuse_position(0, &Vec3::new(1.0, 2.0, -1.5), 0.5, FixKind::Absolute);
    let (mut pred, mut upd) = (Stats::default(), Stats::default());
    for k in 1..=640u64 {
        let t = k * 1_000;
        pred.add(c.measure_once(|| {
            let _ = black_box(f.predict(black_box(t), &acc, &rot));
        }));
        if k % 10 == 0 && k >= 200 {
            let tm = t - 150_000;
            let z = Vec3::new(1.0, 2.0, -1.5);
            upd.add(c.measure_once(|| {
                let _ = black_box(f.fuse_position(tm, &z, 0.5, FixKind::Absolute));
                let _ = black_box(f.fuse_velocity(tm, &Vec3::zeros(), 0.1));
            }));
        }
    }
    pred.report("nav predict (1 IMU sample)");
    upd.report("nav update (delayed position + velocity)");
}

#[entry]
fn main() -> ! {
    let cp = match cortex_m::Peripherals::take() {
        Some(cp) => cp,
        None => exit(false),
    };
    let c = Counter::new(cp.SYST);
    let _ = writeln!(Console, "empty measurement: {} instructions per {REPS} turns", c.overhead);
    check::fmath_bit_exact();
    bench_blocks(&c);
    bench_cascade_parts(&c);
    bench_filter(&c);
    bench_trajectory(&c);
    bench_cascade(&c);
    bench_memory(&c, false);
    bench_memory(&c, true);
    storage::bench_storage(&c);
    replan::bench_replan(&c);
    bench_nav(&c);
    print("done\n");
    exit(true)
}
