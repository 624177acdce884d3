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
//! * [`round_i32`]: `libm::roundf(x) as i32` likewise (halves away from zero).
//! * [`floor_i32`]: `libm::floorf(x) as i32` for every `x` (saturating, NaN → 0), from
//!   the truncating conversion (`VCVT` on the Cortex-M4F) and one compare, instead of
//!   libm's bit manipulation (≈ 20 instructions and a call: voxel keys, sector indices).
//! * [`sincosf`], [`cosf`], [`tanf`], [`hypotf`]: evaluated in `f32` (libm's use
//!   `f64` kernels, software on the Cortex-M4F); within about one ulp of libm's,
//!   not bit-identical (see each function).
//!
//! Checked where it matters: the host tests below compare with libm's rules and
//! accuracy; `cargo xtask test` runs `tests/cortex-m4` in QEMU, which checks every
//! function here on the Cortex-M4F bit for bit against the host build (so the
//! firmware computes what the simulator computes) and `sqrtf` against the
//! target's software `libm::sqrtf`.

/// `libm::roundf(x) as i32` (halves away from zero), bit for bit, for every `x`: saturating,
/// `0` for NaN. The truncation `t` and the fraction `x − t` are exact (`|x| < 2²³`; beyond,
/// `x` is an integer); a fraction of at least one half moves `t` one away from zero.
#[inline(always)]
pub fn round_i32(x: f32) -> i32 {
    let t = x as i32;
    let frac = x - t as f32;
    if frac >= 0.5 {
        t.saturating_add(1)
    } else if frac <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// `libm::floorf(x) as i32`, bit for bit, for every `x`: saturating at `i32::MIN`/`MAX`
/// (±∞ and beyond), `0` for NaN. The conversion truncates towards zero; a truncated
/// value above `x` (negative non-integers, where `|x| < 2²³` so the conversion is exact)
/// is one too high.
#[inline(always)]
pub fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x {
        i.saturating_sub(1)
    } else {
        i
    }
}

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

/// Largest `|x|` [`sincosf`] reduces by Cody–Waite; beyond it, by Payne–Hanek.
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
/// 6e-8 for sin, 1.2e-7 for cos). Larger finite `x` are reduced by Payne–Hanek in integer
/// arithmetic ([`reduce_large`]) and take the same polynomials (same bound, tested up to
/// `f32::MAX`); non-finite `x` give NaN, as libm. Before, those went to `libm::sincosf`,
/// whose `f64` reduction (`rem_pio2_large`) was ≈ 3 KB of the F405's flash; no caller in
/// the flight code passes such an angle (they are wrapped or bounded).
#[inline(never)]
pub fn sincosf(x: f32) -> (f32, f32) {
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must take this branch too
    if !(x.abs() <= SINCOS_FAST_LIMIT) {
        if !x.is_finite() {
            #[allow(clippy::eq_op)] // NaN as libm makes it (the input's payload for NaN)
            return (x - x, x - x);
        }
        let (r, quadrant) = reduce_large(x.to_bits());
        let (s, c) = quadrant_sincos(r, quadrant);
        return if x < 0.0 { (-s, c) } else { (s, c) };
    }
    const TWO_OVER_PI: f32 = core::f32::consts::FRAC_2_PI;
    // π/2 = P1 + P2 + P3 (Cephes DP1..DP3 × 2); P1, P2 have few significant bits.
    const P1: f32 = 1.570_312_5;
    const P2: f32 = 4.837_513e-4;
    const P3: f32 = 7.549_79e-8;
    let kf = rintf(x * TWO_OVER_PI);
    let r = ((x - kf * P1) - kf * P2) - kf * P3;
    quadrant_sincos(r, kf as i32)
}

/// `(sin, cos)` of `r + k·π/2` for |r| ≤ π/4: Cephes' single-precision minimax polynomials
/// for `sin r`, `cos r`, then [`quadrant`].
#[inline(always)]
fn quadrant_sincos(r: f32, k: i32) -> (f32, f32) {
    let z = r * r;
    let s = r + r * z * ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1);
    let c = 1.0 - 0.5 * z + z * z * ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2);
    quadrant(s, c, k)
}

/// 4/π to 192 bits, 8 new bits per entry (so three 32-bit words at any 8-bit offset are
/// consecutive bits): ARM optimized-routines' `__inv_pio4` (MIT OR Apache-2.0 WITH
/// LLVM-exception), for [`reduce_large`].
const INV_PIO4: [u32; 24] = [
    0xa2, 0xa2f9, 0xa2f983, 0xa2f9836e, 0xf9836e4e, 0x836e4e44, 0x6e4e4415, 0x4e441529, 0x441529fc,
    0x1529fc27, 0x29fc2757, 0xfc2757d1, 0x2757d1f5, 0x57d1f534, 0xd1f534dd, 0xf534ddc0, 0x34ddc0db,
    0xddc0db62, 0xc0db6295, 0xdb629599, 0x6295993c, 0x95993c43, 0x993c4390, 0x3c439041,
];

/// π/2 · 2³¹, truncated (0xC90FDAA2).
const PIO2_Q31: u64 = 0xc90f_daa2;

/// `|x| = (k + f)·π/2` for the `f32` with bits `xi` (|x| ≥ 2, finite; the sign bit is
/// ignored), with `k` an integer (mod 4 is what counts) and |f| ≤ ½: returns `(f·π/2, k)`.
/// Payne–Hanek in integer arithmetic (ARM optimized-routines' `reduce_large`): the 24-bit
/// mantissa times the 96 bits of 4/π that matter at its exponent gives f exactly in 2.62
/// fixed point (at most 29 leading zero bits, so ≥ 33 significant ones); f·π/2 is then formed
/// from its top 32 bits and π/2 to 32 bits in one 64-bit product and rounded once to `f32`
/// (≤ ½ ulp plus 2⁻³⁰ relative). No `f64`: the Cortex-M4F has no double-precision FPU.
fn reduce_large(xi: u32) -> (f32, i32) {
    let i = ((xi >> 26) & 15) as usize;
    let word = |k: usize| INV_PIO4.get(i + k).copied().unwrap_or(0);
    let m = ((xi & 0x00ff_ffff) | 0x0080_0000) << ((xi >> 23) & 7);
    let res0 = u64::from(m.wrapping_mul(word(0)));
    let res1 = u64::from(m) * u64::from(word(4));
    let res2 = u64::from(m) * u64::from(word(8));
    let res = ((res2 >> 32) | (res0 << 32)).wrapping_add(res1);
    let n = res.wrapping_add(1 << 61) >> 62;
    // fx = f·2⁶², |fx| ≤ 2⁶¹: lz ≥ 2, and `top` holds |fx|'s leading 32 bits (the first one set).
    let fx = res.wrapping_sub(n << 62) as i64;
    let k = n as i32;
    if fx == 0 {
        return (0.0, k);
    }
    let lz = fx.unsigned_abs().leading_zeros();
    let top = (fx.unsigned_abs() << lz) >> 32;
    // f·π/2 = top · 2^(32 − lz) · (PIO2_Q31 · 2⁻³¹) · 2⁻⁶² = (top · PIO2_Q31) · 2^(−61 − lz).
    let scale = f32::from_bits((127 - 61 - lz) << 23);
    let r = ((top * PIO2_Q31) as f32) * scale;
    (if fx < 0 { -r } else { r }, k)
}

/// `libm::sincosf(x)` bit for bit for |x| < 2²⁸·π/2 ≈ 4.2·10⁸ and for non-finite `x`: libm
/// 0.2.16's code for that range — its `f64` kernels and its `rem_pio2f` for medium arguments
/// — copied (FreeBSD msun, MIT). Beyond (no caller's angle), [`sincosf`]'s Payne–Hanek
/// reduction in `f32`, within one ulp of libm's.
///
/// For results that must stay what `libm::sincosf` gave, on the boards the Euler-angle
/// constructions ([`crate::frame::quat_from_euler`], [`crate::frame::rotation_from_euler`])
/// and the onboard log's quaternions: libm's own function also reduces large arguments
/// with `rem_pio2_large`, ≈ 3 KB of the F405's flash for angles no caller passes.
/// Software `f64` on the Cortex-M4F (≈ 1,000–2,000 instructions); not for the control loops,
/// which take [`sincosf`].
pub fn sincosf_exact(x: f32) -> (f32, f32) {
    use core::f64::consts::FRAC_PI_2 as S1PIO2;
    let ix = x.to_bits() & 0x7fff_ffff;
    if ix <= 0x3f49_0fda {
        // |x| ≲ π/4; below 2⁻¹² libm returns (x, 1).
        if ix < 0x3980_0000 {
            return (x, 1.0);
        }
        return k_sincosf(f64::from(x));
    }
    if ix >= 0x7f80_0000 {
        #[allow(clippy::eq_op)] // libm's NaN: the input's payload for NaN
        return (x - x, x - x);
    }
    if ix >= 0x4dc9_0fdb {
        return sincosf(x);
    }
    // |x| = j·π/2 + y with |y| ≲ π/4, y in f64: up to 9π/4 libm's branches subtract its
    // constants j·π/2 (j·S1PIO2 rounded, as libm's S2PIO2..S4PIO2); beyond, its rem_pio2f
    // (j = rint(|x|·2/π), y = |x| − j·PIO2_1 − j·PIO2_1T). libm writes each branch for
    // both signs; as k_sinf is odd and k_cosf even in their arithmetic, the values are the
    // ones of |x| with the sine's sign flipped (tested against libm, bit for bit).
    let a = f64::from(f32::from_bits(ix));
    let (j, y) = if ix <= 0x40e2_31d5 {
        // libm's bounds: |x| ≲ 3π/4, 5π/4, 7π/4, 9π/4.
        let j = 1 + i32::from(ix > 0x4016_cbe3) + i32::from(ix > 0x407b_53d1) + i32::from(ix > 0x40af_eddf);
        (j, a - f64::from(j) * S1PIO2)
    } else {
        const TOINT: f64 = 1.5 / f64::EPSILON;
        const INV_PIO2: f64 = f64::from_bits(0x3fe4_5f30_6dc9_c883); // 53 bits of 2/π
        const PIO2_1: f64 = f64::from_bits(0x3ff9_21fb_5000_0000); // first 25 bits of π/2
        const PIO2_1T: f64 = f64::from_bits(0x3e51_10b4_611a_6263); // π/2 − PIO2_1
        let f_n = (a * INV_PIO2 + TOINT) - TOINT;
        (f_n as i32, a - f_n * PIO2_1 - f_n * PIO2_1T)
    };
    let (s, c) = k_sincosf(y);
    let (s, c) = quadrant(s, c, j);
    if x.is_sign_negative() {
        (-s, c)
    } else {
        (s, c)
    }
}

/// `(sin, cos)` of `r + k·π/2` from `s = sin r`, `c = cos r`: the quadrant `k mod 4` picks
/// signs and order.
#[inline(always)]
fn quadrant(s: f32, c: f32, k: i32) -> (f32, f32) {
    match k & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// libm's `k_sinf` and `k_cosf` (one `z = x²`, `w = z²` for both, as each computes them): sin x
/// and cos x for |x| ≲ π/4, evaluated in `f64`, each rounded once to `f32`.
fn k_sincosf(x: f64) -> (f32, f32) {
    const S1: f64 = f64::from_bits(0xbfc5_5555_54cb_ac77); // −0x15555554cbac77p−55
    const S2: f64 = f64::from_bits(0x3f81_1110_896e_fbb2); // 0x111110896efbb2p−59
    const S3: f64 = f64::from_bits(0xbf2a_00f9_e2ca_e774); // −0x1a00f9e2cae774p−65
    const S4: f64 = f64::from_bits(0x3ec6_cd87_8c3b_46a7); // 0x16cd878c3b46a7p−71
    const C0: f64 = f64::from_bits(0xbfdf_ffff_fd0c_5e81); // −0x1ffffffd0c5e81p−54
    const C1: f64 = f64::from_bits(0x3fa5_5553_e105_3a42); // 0x155553e1053a42p−57
    const C2: f64 = f64::from_bits(0xbf56_c087_e80f_1e27); // −0x16c087e80f1e27p−62
    const C3: f64 = f64::from_bits(0x3ef9_9342_e0ee_5069); // 0x199342e0ee5069p−68
    let z = x * x;
    let w = z * z;
    let s = z * x;
    let sin = (x + s * (S1 + z * S2)) + s * w * (S3 + z * S4);
    let cos = ((1.0 + z * C0) + w * C1) + (w * z) * (C2 + z * C3);
    (sin as f32, cos as f32)
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

/// Bound (rad) of `|atan2_approx(y, x) − libm::atan2f(y, x)|` that callers may rely on:
/// five times the largest difference the test measures (≈ 1.0e-5, the Hastings polynomial's
/// 1e-5 plus round-off), so a decision taken with it is libm's decision.
pub const ATAN2_APPROX_ERROR: f32 = 1e-4;

/// `atan2(y, x)` (rad, −π..π) within [`ATAN2_APPROX_ERROR`] of `libm::atan2f` for finite
/// `(y, x) ≠ (0, 0)`, NaN otherwise: a degree-9 odd polynomial for the arctangent on
/// [−1, 1] (Hastings, Abramowitz & Stegun 4.4.47, |error| ≤ 1e-5) and the octant folding,
/// the sign of the result that of `y` (−0 included) as libm's. About 20 instructions against
/// libm's ≈ 85: for callers that only need to know on which side of a boundary an angle lies
/// and fall back to `libm::atan2f` when it is too close to tell ([`certain`]).
#[inline]
pub fn atan2_approx(y: f32, x: f32) -> f32 {
    use core::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    if !(ax.is_finite() && ay.is_finite()) || (ax == 0.0 && ay == 0.0) {
        return f32::NAN;
    }
    let swap = ay > ax;
    let t = if swap { ax / ay } else { ay / ax };
    let z = t * t;
    let mut a = t * (0.999_866 + z * (-0.330_299_5 + z * (0.180_141 + z * (-0.085_133 + z * 0.020_835_1))));
    if swap {
        a = FRAC_PI_2 - a;
    }
    if x.is_sign_negative() {
        a = PI - a;
    }
    if y.is_sign_negative() {
        -a
    } else {
        a
    }
}

/// `f(x)` for a non-decreasing `f` (floor, round) when `f(x − e) == f(x + e)`, i.e. when
/// every value within `e` of `x` gives the same result; `None` when they differ or `x` is not
/// finite. With `x` an approximation of `x*` within `e`, `Some(k)` is `f(x*)`.
#[inline]
pub fn certain<T: PartialEq>(x: f32, e: f32, f: impl Fn(f32) -> T) -> Option<T> {
    if !x.is_finite() {
        return None;
    }
    let lo = f(x - e);
    (lo == f(x + e)).then_some(lo)
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

    /// The approximation is within a fifth of [`ATAN2_APPROX_ERROR`] of libm on a dense
    /// sweep of directions and magnitudes (the octant folds, ±0, the branch cut), NaN where
    /// libm's value is not an angle of a direction.
    #[test]
    fn atan2_approx_is_within_its_bound_of_libm() {
        let mut worst = 0.0f32;
        for k in 0..2_000_000u32 {
            let a = (k as f32 / 2_000_000.0) * core::f32::consts::TAU - core::f32::consts::PI;
            for r in [1e-30f32, 1e-3, 0.7, 1.0, 123.0, 3e30] {
                let (s, c) = (libm::sinf(a), libm::cosf(a));
                let (y, x) = (s * r, c * r);
                let d = (atan2_approx(y, x) - libm::atan2f(y, x)).abs();
                worst = worst.max(d);
            }
        }
        for (y, x) in
            [(0.0f32, 1.0f32), (-0.0, 1.0), (0.0, -1.0), (-0.0, -1.0), (1.0, 0.0), (1.0, -0.0), (-1.0, 0.0)]
        {
            let d = (atan2_approx(y, x) - libm::atan2f(y, x)).abs();
            assert!(d < 1e-6, "({y}, {x}): {} vs {}", atan2_approx(y, x), libm::atan2f(y, x));
        }
        assert!(worst <= ATAN2_APPROX_ERROR / 5.0, "largest difference {worst:e}");
        for (y, x) in [(0.0f32, 0.0f32), (f32::NAN, 1.0), (1.0, f32::INFINITY), (f32::NEG_INFINITY, 1.0)] {
            assert!(atan2_approx(y, x).is_nan(), "({y}, {x})");
        }
    }

    #[test]
    fn certain_answers_only_when_the_interval_agrees() {
        assert_eq!(certain(2.4, 0.05, libm::roundf), Some(2.0));
        assert_eq!(certain(2.48, 0.05, libm::roundf), None);
        assert_eq!(certain(-0.3, 0.1, floor_i32), Some(-1));
        assert_eq!(certain(0.05, 0.1, floor_i32), None);
        assert_eq!(certain(f32::NAN, 0.1, floor_i32), None);
        assert_eq!(certain(f32::INFINITY, 0.1, floor_i32), None);
    }

    /// `check` of every 251st `f32` bit pattern (all signs and exponents, NaNs and infinities).
    fn every_251st_bit_pattern(check: impl Fn(f32)) {
        let mut b: u32 = 0;
        loop {
            check(f32::from_bits(b));
            match b.checked_add(251) {
                Some(n) => b = n,
                None => break,
            }
        }
    }

    #[test]
    fn round_i32_is_libm_roundf_as_i32() {
        let check = |x: f32| {
            assert_eq!(round_i32(x), libm::roundf(x) as i32, "x = {x:e} ({:#010x})", x.to_bits());
        };
        every_251st_bit_pattern(check);
        for k in -4096i32..=4096 {
            let x = k as f32;
            for y in [x, x + 0.5, x - 0.5, (x + 0.5).next_up(), (x + 0.5).next_down(), (x - 0.5).next_up()] {
                check(y);
                check(y.next_down());
            }
        }
        for x in [
            0.49999997f32,
            -0.49999997,
            0.5,
            -0.5,
            8388607.5,
            -8388607.5,
            8388608.0,
            2147483520.0,
            2147483648.0,
            -2147483904.0,
        ] {
            check(x);
            check(x.next_up());
            check(x.next_down());
        }
        for x in [0.0f32, -0.0, f32::MAX, f32::MIN, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e-45] {
            check(x);
        }
    }

    #[test]
    fn floor_i32_is_libm_floorf_as_i32() {
        let check = |x: f32| {
            assert_eq!(floor_i32(x), libm::floorf(x) as i32, "x = {x:e} ({:#010x})", x.to_bits());
        };
        every_251st_bit_pattern(check);
        // Around every integer up to ±2^12, and near the saturation bounds.
        for k in -4096i32..=4096 {
            let x = k as f32;
            for y in [x, x.next_up(), x.next_down(), x + 0.5, x - 0.5] {
                check(y);
            }
        }
        for x in [2147483648.0f32, -2147483648.0, 2147483520.0, -2147483520.0, -2147483904.0, 16777216.0] {
            for y in [x, x.next_up(), x.next_down()] {
                check(y);
            }
        }
        for x in [
            0.0f32,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ] {
            check(x);
        }
    }

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
        // Exact points and non-finite input.
        assert_eq!(sincosf(0.0), (0.0, 1.0));
        assert!(sincosf(f32::NAN).0.is_nan() && sincosf(f32::INFINITY).1.is_nan());
        assert!(sincosf(f32::NEG_INFINITY).0.is_nan());
        for x in [0.1f32, 0.61, 1.2, -2.9] {
            assert!((tanf(x) - libm::tanf(x)).abs() <= 4e-7 * (1.0 + libm::tanf(x).abs()), "{x}");
            assert_eq!(cosf(x), sincosf(x).1);
        }
    }

    #[test]
    fn sincosf_beyond_the_fast_range_agrees_with_libm() {
        // Payne–Hanek for |x| > 1000: every binade up to f32::MAX, a pseudo-random mantissa
        // sweep in each, both signs; and the hardest case for the reduction, the f32 closest to
        // a multiple of π/2 (16367173·2⁷², J.-M. Muller, "Elementary Functions").
        let mut worst = (0.0f32, 0.0f32);
        let mut bits = 0x447a_0001u32; // just above 1000
        let mut seed = 0x9e37_79b9u32;
        while bits < 0x7f80_0000 {
            for _ in 0..2_000 {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                let x = f32::from_bits((bits & 0xff80_0000) | (seed & 0x007f_ffff));
                for x in [x, -x] {
                    let (s, c) = sincosf(x);
                    let (ls, lc) = libm::sincosf(x);
                    worst = (maxf(worst.0, (s - ls).abs()), maxf(worst.1, (c - lc).abs()));
                }
            }
            bits += 0x0080_0000;
        }
        assert!(worst.0 <= 1.5e-7 && worst.1 <= 1.5e-7, "{worst:?}");
        for x in [1000.5f32, 5000.0, 16_367_173.0 * 4_722_366_482_869_645_213_696.0, f32::MAX, -f32::MAX] {
            let ((s, c), (ls, lc)) = (sincosf(x), libm::sincosf(x));
            assert!((s - ls).abs() <= 1.5e-7 && (c - lc).abs() <= 1.5e-7, "{x:e}: {s} {c} vs {ls} {lc}");
        }
    }

    #[test]
    fn sincosf_exact_is_libms_bit_for_bit() {
        // Every branch boundary (±1 ulp), a dense sweep of |x| ≤ 9π/4 and a geometric sweep up
        // to 2²⁸·π/2 (libm's medium reduction), both signs; then non-finite input.
        let edges = [
            0x3980_0000u32,
            0x3f49_0fda,
            0x4016_cbe3,
            0x407b_53d1,
            0x40af_eddf,
            0x40e2_31d5,
            0x4dc9_0fd9,
            0x0000_0001,
            0x0080_0000,
        ];
        let dense = (0..=1_000_000u32).map(|i| i as f32 * (7.07 / 1_000_000.0));
        let wide = (0..=200_000u32).map(|i| 7.0 * libm::powf(6.0e7, i as f32 / 200_000.0));
        let xs = edges.iter().flat_map(|&b| [b - 1, b, b + 1]).map(f32::from_bits).chain(dense).chain(wide);
        for x in xs {
            for x in [x, -x] {
                let (s, c) = sincosf_exact(x);
                let (ls, lc) = libm::sincosf(x);
                assert_eq!((s.to_bits(), c.to_bits()), (ls.to_bits(), lc.to_bits()), "{x:e}");
            }
        }
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let (s, c) = sincosf_exact(x);
            assert!(s.is_nan() && c.is_nan());
        }
        // Beyond libm's medium range: the f32 Payne–Hanek, within one ulp.
        let (s, c) = sincosf_exact(1.0e9);
        let (ls, lc) = libm::sincosf(1.0e9);
        assert!((s - ls).abs() <= 1.5e-7 && (c - lc).abs() <= 1.5e-7);
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
