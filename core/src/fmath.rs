//! Cheap `f32` primitives for the control loops: square root, minimum, maximum
//! and clamp, bit-identical to what `libm` / `f32::min` / `f32::max` give, and
//! single-precision trigonometry within one ulp of libm's.
//!
//! Why: on the Cortex-M4F (`thumbv7em-none-eabihf`) `libm::sqrtf` is a
//! software routine (≈ 75 instructions) although the FPU has `VSQRT.F32`, and
//! `f32::min`/`max` compile to calls of `fminf`/`fmaxf` (≈ 12 instructions;
//! ARMv7-M has no FP min/max instruction). These helpers compile to the FPU
//! instruction and to compare-and-select respectively. Measured counts:
//! `docs/performance.md`, section 4.
//!
//! * [`sqrtf`]: `VSQRT.F32` on ARM hard-float targets, `libm::sqrtf`
//!   elsewhere. Both are correctly rounded (IEEE 754), so the results are
//!   bit-identical (NaN for negative or NaN input, as before).
//! * [`minf`], [`maxf`]: exactly the rule of libm's `fminf`/`fmaxf` (the
//!   functions `f32::min`/`max` call on ARM): a NaN operand is ignored (the other
//!   is returned), both NaN give NaN; for `±0` the first operand wins on a tie,
//!   as in libm.
//! * [`clampf`](crate::frame::clampf) is built from them.
//! * [`sincosf`], [`cosf`], [`tanf`], [`hypotf`]: evaluated in `f32` (libm's use
//!   `f64` kernels, software on the Cortex-M4F); within about one ulp of libm's,
//!   not bit-identical (see each function).
//!
//! Checked where it matters: the host tests below compare with libm's rules and
//! accuracy; `cargo xtask test` runs `tests/cortex-m4` in QEMU, which checks every
//! function here on the Cortex-M4F bit for bit against the host build (so the
//! firmware computes what the simulator computes) and `sqrtf` against the
//! target's software `libm::sqrtf`.

/// Square root, correctly rounded (NaN for `x < 0` or NaN). `VSQRT.F32` on
/// Cortex-M4F and other ARM hard-float targets, `libm::sqrtf` elsewhere.
#[inline(always)]
pub fn sqrtf(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        vsqrt(x)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// `VSQRT.F32` through `s0`, which is saved and restored around it.
///
/// rustc 1.95 accepts FP register operands (`sreg`) in `asm!` only with the
/// `vfp2` target feature, which `thumbv7em-none-eabihf` (single-precision
/// `vfp4d16sp`) does not report (rust-lang/rust#159976, #161826), so the value
/// travels in a core register and the FP register used is pushed and popped by
/// the asm itself: 5 instructions plus the two moves the compiler adds, against
/// ≈ 75 for `libm::sqrtf`.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[allow(unsafe_code)]
#[inline(always)]
fn vsqrt(x: f32) -> f32 {
    let r: f32;
    // SAFETY: the instructions touch only the core registers given as operands, `s0`
    // (saved to the stack by `vpush` and restored by `vpop` before the asm ends, so no
    // FP register the compiler uses changes) and 4 bytes below the stack pointer
    // (hence no `nostack`). VSQRT.F32 does not change APSR flags; it may set the
    // cumulative exception bits of FPSCR (IOC, IXC), which nothing in this program
    // reads. The target's FPU (vfp4d16sp) implements VSQRT.F32, correctly rounded
    // like `libm::sqrtf`.
    unsafe {
        core::arch::asm!(
            "vpush {{s0}}",
            "vmov s0, {x}",
            "vsqrt.f32 s0, s0",
            "vmov {r}, s0",
            "vpop {{s0}}",
            x = in(reg) x,
            r = lateout(reg) r,
            options(pure, nomem, preserves_flags),
        );
    }
    r
}

/// Minimum of `x` and `y` with libm's `fminf` rule: a NaN operand is ignored
/// (both NaN give NaN); on `x == y` (also `±0`) returns `y`.
#[inline(always)]
pub fn minf(x: f32, y: f32) -> f32 {
    if y.is_nan() || x < y {
        x
    } else {
        y
    }
}

/// Maximum of `x` and `y` with libm's `fmaxf` rule: a NaN operand is ignored
/// (both NaN give NaN); on `x == y` (also `±0`) returns `x`.
#[inline(always)]
pub fn maxf(x: f32, y: f32) -> f32 {
    if x.is_nan() || x < y {
        y
    } else {
        x
    }
}

/// Largest `|x|` [`sincosf`] reduces itself (beyond it, and for non-finite `x`, libm's).
const SINCOS_FAST_LIMIT: f32 = 1000.0;

/// `(sin x, cos x)`, x in rad, in single precision throughout.
///
/// libm's `sincosf`/`sinf`/`cosf`/`tanf` evaluate their polynomials in `f64`, which
/// the Cortex-M4F's single-precision FPU does not have: ≈ 1,100 (`cosf`) to 2,300
/// (`sincosf`) instructions of software double arithmetic per call. Here, for
/// `|x| ≤ 1000`, `x` is reduced by `k·π/2` (Cody–Waite, π/2 split in three parts so
/// that `k·P1` and `k·P2` are exact) to `|r| ≤ π/4`, where Cephes' single-precision
/// minimax polynomials give `sin r`, `cos r`; the quadrant `k mod 4` picks signs and
/// order. The result differs from libm's (correctly rounded in practice) by at most
/// one unit in the last place (test: absolute error ≤ 1.5e-7 for |x| ≤ 1000; measured
/// 6e-8 for sin, 1.2e-7 for cos); larger or non-finite `x` go to libm.
#[inline(never)]
pub fn sincosf(x: f32) -> (f32, f32) {
    if x.abs() > SINCOS_FAST_LIMIT || x.is_nan() {
        return libm::sincosf(x);
    }
    const TWO_OVER_PI: f32 = core::f32::consts::FRAC_2_PI;
    // π/2 = P1 + P2 + P3 (Cephes DP1..DP3 × 2); P1, P2 have few significant bits.
    const P1: f32 = 1.570_312_5;
    const P2: f32 = 4.837_513e-4;
    const P3: f32 = 7.549_79e-8;
    let kf = rintf(x * TWO_OVER_PI);
    let r = ((x - kf * P1) - kf * P2) - kf * P3;
    let z = r * r;
    let s = r + r * z * ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1);
    let c = 1.0 - 0.5 * z + z * z * ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2);
    match (kf as i32) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// `x` rounded to the nearest integer (ties away from zero), for `|x| < 2²³`.
#[inline(always)]
fn rintf(x: f32) -> f32 {
    let h = if x < 0.0 { -0.5 } else { 0.5 };
    ((x + h) as i32) as f32
}

/// `cos x`, x in rad (see [`sincosf`]).
#[inline]
pub fn cosf(x: f32) -> f32 {
    sincosf(x).1
}

/// `tan x`, x in rad, as `sin x / cos x` (see [`sincosf`]; a few ulp from libm's `tanf`).
#[inline]
pub fn tanf(x: f32) -> f32 {
    let (s, c) = sincosf(x);
    s / c
}

/// `√(x² + y²)` in single precision (libm's `hypotf` works in `f64`: ≈ 450 instructions on
/// the Cortex-M4F). Falls back to libm when `x² + y²` overflows or underflows, so the result
/// is always libm's within about one ulp.
#[inline]
pub fn hypotf(x: f32, y: f32) -> f32 {
    let s = x * x + y * y;
    if s.is_finite() && (s >= f32::MIN_POSITIVE || (x == 0.0 && y == 0.0)) {
        sqrtf(s)
    } else {
        libm::hypotf(x, y)
    }
}

/// `|v|` (Euclidean norm of a 3-vector) through [`sqrtf`]; same value as
/// nalgebra's `norm()` (which takes a software square root on the Cortex-M4F).
#[inline(always)]
pub fn norm3(v: &crate::Vec3) -> f32 {
    sqrtf(v.norm_squared())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    // No host test of `sqrtf`: here it IS `libm::sqrtf`, so comparing the two could not fail.
    // `VSQRT.F32` is checked where it runs, on the Cortex-M4F in QEMU, by `cargo xtask test`
    // (`tests/cortex-m4/src/check.rs`): against the target's software `libm::sqrtf` and, with
    // every other function of this module, bit for bit against this host build.

    #[test]
    fn min_max_follow_libm_rule() {
        let vals = [-2.0f32, -0.0, 0.0, 1.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        for &a in &vals {
            for &b in &vals {
                let (mn, mx) = (minf(a, b), maxf(a, b));
                let (ln, lx) = (libm::fminf(a, b), libm::fmaxf(a, b));
                assert!(mn.to_bits() == ln.to_bits() || (mn.is_nan() && ln.is_nan()), "min {a} {b}");
                assert!(mx.to_bits() == lx.to_bits() || (mx.is_nan() && lx.is_nan()), "max {a} {b}");
                if !a.is_nan() && !b.is_nan() {
                    assert_eq!(mn, a.min(b));
                    assert_eq!(mx, a.max(b));
                }
            }
        }
    }

    /// Largest absolute difference to libm over `n` points of `[lo, hi]`.
    fn sincos_error(lo: f32, hi: f32, n: u32) -> (f32, f32) {
        let mut worst = (0.0f32, 0.0f32);
        for i in 0..=n {
            let x = lo + (hi - lo) * (i as f32 / n as f32);
            let (s, c) = sincosf(x);
            let (ls, lc) = libm::sincosf(x);
            worst = (maxf(worst.0, (s - ls).abs()), maxf(worst.1, (c - lc).abs()));
        }
        worst
    }

    #[test]
    fn sincosf_agrees_with_libm_to_a_few_ulp() {
        use core::f32::consts::PI;
        let (es, ec) = sincos_error(-2.0 * PI, 2.0 * PI, 400_000);
        assert!(es <= 1.5e-7 && ec <= 1.5e-7, "{es:e} {ec:e}");
        let (es, ec) = sincos_error(-1000.0, 1000.0, 400_000);
        assert!(es <= 1.5e-7 && ec <= 1.5e-7, "{es:e} {ec:e}");
        // Exact points and the libm fallback.
        assert_eq!(sincosf(0.0), (0.0, 1.0));
        assert_eq!(sincosf(5000.0), libm::sincosf(5000.0));
        assert!(sincosf(f32::NAN).0.is_nan() && sincosf(f32::INFINITY).1.is_nan());
        for x in [0.1f32, 0.61, 1.2, -2.9] {
            assert!((tanf(x) - libm::tanf(x)).abs() <= 4e-7 * (1.0 + libm::tanf(x).abs()), "{x}");
            assert_eq!(cosf(x), sincosf(x).1);
        }
    }

    #[test]
    fn hypotf_agrees_with_libm() {
        for (x, y) in [(3.0f32, 4.0f32), (0.1, -0.2), (1e-30, 1e-30), (1e30, 1e30), (0.0, 0.0), (-7.5, 2.25)]
        {
            let (a, b) = (hypotf(x, y), libm::hypotf(x, y));
            assert!((a - b).abs() <= 1.2e-7 * b, "{x} {y}: {a} vs {b}");
        }
    }

    #[test]
    fn norm3_is_nalgebra_norm() {
        let v = Vec3::new(0.3, -4.0, 12.5);
        assert_eq!(norm3(&v), v.norm());
    }
}
