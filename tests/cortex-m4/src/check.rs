//! Bit-exactness of `parapet_core::fmath` on the Cortex-M4F (run by `cargo xtask test` in QEMU
//! before anything is measured; any mismatch fails the program, so the test command).
//!
//! Two checks:
//! * against the HOST: `sqrtf`, `sincosf`, `cosf`, `tanf`, `sincosf_exact`, `hypotf`, `norm3`, `minf`, `maxf` on
//!   the inputs of `build.rs`, whose results were computed by the host build of the same source
//!   (what the simulator, the PIL host twin and `parapet run` compute): equal bit for bit, NaN
//!   equal to any NaN (the payload of a NaN the FPU creates differs between x86 and ARM);
//! * against the TARGET's libm: `sqrtf` (`VSQRT.F32` here) equals the software `libm::sqrtf` bit
//!   for bit on a geometric sweep of `0..f32::MAX` (subnormals included), random values and the
//!   special cases; `sincosf_exact` equals `libm::sincosf` (soft `f64` here) on a geometric sweep
//!   up to 4.2·10⁸ and random angles; `minf`/`maxf` equal `f32::min`/`max` (which call libm's
//!   `fminf`/`fmaxf`); `floor_i32`/`round_i32` equal `libm::floorf`/`roundf(x) as i32` on random bit patterns and
//!   the edge cases.
//!
//! Imports: `parapet_core::fmath` and the program's console (`crate::Console`, `crate::exit`).

use core::fmt::Write;
use core::hint::black_box;

use parapet_core::fmath;
use parapet_core::Vec3;

use crate::{exit, Console};

mod reference {
    include!(concat!(env!("OUT_DIR"), "/fmath_reference.rs"));
}

/// Mismatches printed before the rest are only counted.
const MAX_PRINTED: u32 = 10;

/// Counts comparisons and mismatches.
struct Tally {
    compared: u32,
    mismatches: u32,
}

impl Tally {
    /// Compare `got` (target) with `want` (bits of the reference), print the first mismatches.
    fn check(&mut self, what: &str, input: &[u32], got: f32, want: u32) {
        self.compared += 1;
        let want_f = f32::from_bits(want);
        if got.to_bits() == want || (got.is_nan() && want_f.is_nan()) {
            return;
        }
        self.mismatches += 1;
        if self.mismatches <= MAX_PRINTED {
            let _ = write!(Console, "MISMATCH {what}(");
            for (i, b) in input.iter().enumerate() {
                let sep = if i == 0 { "" } else { ", " };
                let _ = write!(Console, "{sep}{:e} [0x{b:08x}]", f32::from_bits(*b));
            }
            let _ = writeln!(
                Console,
                "): target {got:e} [0x{:08x}], reference {want_f:e} [0x{want:08x}]",
                got.to_bits()
            );
        }
    }
}

/// The target's results against the host's (tables of `build.rs`).
fn against_host(t: &mut Tally) {
    let f = |b: u32| black_box(f32::from_bits(b));
    for r in &reference::SINCOS {
        let x = f(r[0]);
        let (s, c) = fmath::sincosf(x);
        t.check("sincosf.sin", &r[..1], s, r[1]);
        t.check("sincosf.cos", &r[..1], c, r[2]);
        t.check("cosf", &r[..1], fmath::cosf(x), r[3]);
        t.check("tanf", &r[..1], fmath::tanf(x), r[4]);
    }
    for r in &reference::SINCOS_EXACT {
        let (s, c) = fmath::sincosf_exact(f(r[0]));
        t.check("sincosf_exact.sin", &r[..1], s, r[1]);
        t.check("sincosf_exact.cos", &r[..1], c, r[2]);
    }
    for r in &reference::SQRT {
        t.check("sqrtf", &r[..1], fmath::sqrtf(f(r[0])), r[1]);
    }
    for r in &reference::HYPOT {
        t.check("hypotf", &r[..2], fmath::hypotf(f(r[0]), f(r[1])), r[2]);
    }
    for r in &reference::NORM3 {
        t.check("norm3", &r[..3], fmath::norm3(&Vec3::new(f(r[0]), f(r[1]), f(r[2]))), r[3]);
    }
    for r in &reference::MINMAX {
        let (a, b) = (f(r[0]), f(r[1]));
        t.check("minf", &r[..2], fmath::minf(a, b), r[2]);
        t.check("maxf", &r[..2], fmath::maxf(a, b), r[3]);
    }
}

/// `VSQRT.F32` against the target's software `libm::sqrtf`, `minf`/`maxf` against `f32::min`/`max`.
fn against_target_libm(t: &mut Tally) {
    let mut rng = crate::SplitMix64(99);
    let sqrt = |t: &mut Tally, x: f32| {
        t.check("sqrtf vs libm::sqrtf", &[x.to_bits()], fmath::sqrtf(black_box(x)), libm::sqrtf(x).to_bits())
    };
    let mut x = f32::MIN_POSITIVE / 8.0; // subnormals too
    while x < f32::MAX / 1.01 {
        sqrt(t, x);
        x *= 1.01;
    }
    for _ in 0..20_000 {
        sqrt(t, f32::from_bits((rng.next_u64() >> 32) as u32 & 0x7FFF_FFFF));
        sqrt(t, rng.uniform(0.0, 100.0));
    }
    for s in [0.0, -0.0, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN] {
        sqrt(t, s);
    }
    // sincosf_exact = libm::sincosf (the target's, soft f64) for |x| < 2²⁸·π/2: a geometric
    // sweep from 2⁻¹⁴⁹ to 4.2·10⁸ and random angles, both signs.
    let exact = |t: &mut Tally, x: f32| {
        let (s, c) = fmath::sincosf_exact(black_box(x));
        let (ls, lc) = libm::sincosf(x);
        t.check("sincosf_exact.sin vs libm::sincosf", &[x.to_bits()], s, ls.to_bits());
        t.check("sincosf_exact.cos vs libm::sincosf", &[x.to_bits()], c, lc.to_bits());
    };
    let mut x = f32::from_bits(1);
    while x < 4.2e8 {
        exact(t, x);
        exact(t, -x);
        x *= 1.003;
        x = f32::from_bits(x.to_bits() + 1);
    }
    for _ in 0..10_000 {
        exact(t, rng.uniform(-7.1, 7.1));
    }
    // floor_i32/round_i32 = libm::floorf/roundf(x) as i32 (the conversion is `VCVT` here): random bit patterns,
    // integers ± one ulp and a half, the saturation bounds and the special values.
    let floor = |t: &mut Tally, x: f32| {
        let (got, want) = (fmath::floor_i32(black_box(x)), libm::floorf(x) as i32);
        t.check("floor_i32 vs libm::floorf as i32", &[x.to_bits()], f32::from_bits(got as u32), want as u32);
        let (got, want) = (fmath::round_i32(black_box(x)), libm::roundf(x) as i32);
        t.check("round_i32 vs libm::roundf as i32", &[x.to_bits()], f32::from_bits(got as u32), want as u32);
    };
    for _ in 0..20_000 {
        floor(t, f32::from_bits((rng.next_u64() >> 32) as u32));
    }
    for k in -300i32..=300 {
        let x = k as f32 * 0.75;
        for y in [x, x.next_up(), x.next_down(), x + 0.5] {
            floor(t, y);
        }
    }
    for x in [2147483648.0f32, -2147483648.0, -2147483904.0, 2147483520.0, f32::MAX, f32::MIN] {
        floor(t, x);
        floor(t, x.next_up());
        floor(t, x.next_down());
    }
    for x in [0.0f32, -0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e-45, -1e-45] {
        floor(t, x);
    }
    let vals = [-2.0f32, -0.0, 0.0, 1.5, 7.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
    for &a in &vals {
        for &b in &vals {
            let input = [a.to_bits(), b.to_bits()];
            t.check("minf vs f32::min", &input, fmath::minf(a, b), black_box(a).min(black_box(b)).to_bits());
            t.check("maxf vs f32::max", &input, fmath::maxf(a, b), black_box(a).max(black_box(b)).to_bits());
        }
    }
}

/// Runs both checks; prints one summary line per check and exits with a failure on any mismatch.
pub fn fmath_bit_exact() {
    let mut host = Tally { compared: 0, mismatches: 0 };
    against_host(&mut host);
    let _ = writeln!(
        Console,
        "fmath check vs host: {} comparisons (sqrtf, sincosf, cosf, tanf, sincosf_exact, hypotf, norm3, minf, maxf), {} mismatches",
        host.compared, host.mismatches
    );
    let mut libm = Tally { compared: 0, mismatches: 0 };
    against_target_libm(&mut libm);
    let _ = writeln!(
        Console,
        "fmath check vs target libm: {} comparisons (sqrtf = libm::sqrtf, sincosf_exact = libm::sincosf, minf/maxf = f32::min/max, floor_i32/round_i32 = libm::floorf/roundf as i32), {} mismatches",
        libm.compared, libm.mismatches
    );
    if host.mismatches + libm.mismatches > 0 {
        let _ =
            writeln!(Console, "FAIL: fmath on the Cortex-M4F differs from the reference (MISMATCH lines)");
        exit(false);
    }
}
