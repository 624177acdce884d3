//! Cheap `f32` primitives for the control loops: square root, minimum, maximum
//! and clamp, bit-identical to what `libm` / `f32::min` / `f32::max` give.
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

    #[test]
    fn sqrtf_matches_libm_bit_for_bit() {
        let mut x = 1.0e-38f32;
        while x < 1.0e38 {
            for y in [x, x * 1.000_001, x * 3.7, x * 0.6180339] {
                assert_eq!(sqrtf(y).to_bits(), libm::sqrtf(y).to_bits(), "{y}");
            }
            x *= 1.37;
        }
        assert_eq!(sqrtf(0.0), 0.0);
        assert!(sqrtf(-1.0).is_nan() && sqrtf(f32::NAN).is_nan());
        assert_eq!(sqrtf(f32::INFINITY), f32::INFINITY);
    }

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

    #[test]
    fn norm3_is_nalgebra_norm() {
        let v = Vec3::new(0.3, -4.0, 12.5);
        assert_eq!(norm3(&v), v.norm());
    }
}
