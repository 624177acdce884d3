//! Fixed-precision decimal text of an `f64`, the text of `format!("{x:.d$}")` (correctly
//! rounded, ties to even, the sign of a negative value or `-0.0` kept), written fast for the
//! report files: `trajectory.csv` and `ranges.csv` hold millions of numbers, and std's
//! exact-precision formatting fell back to its big-integer algorithm (Dragon) for most of
//! them — 2.2 of the 4.5 G instructions of the office flight's report (callgrind,
//! 2026-12-05).
//!
//! Written here, not taken from a crate: the crates of the field (`ryu`, `dtoa`) write the
//! shortest round-trip text, not a fixed number of decimals, and the files keep their
//! format.
//!
//! **Method.** For `|x|·10^d < 2^52` (`d ≤ 9`): `s = |x|·10^d` rounded to `f64`, and
//! `n = s` rounded to an integer, ties to even (adding and subtracting 2^52). The product's
//! rounding can only matter when `s` is exactly halfway between integers: then the exact
//! residual `|x|·10^d − s` (one fused multiply-add, exact) says on which side the true value
//! lies. `n` is then the correctly rounded value of `|x|·10^d`, written as digits. Other
//! values (non-finite, larger, more decimals) are written by std. Checked against std on
//! random and constructed values (`the_text_is_std_s`).
//!
//! May import: std only.

/// `10^d` for the decimals handled fast.
const POW10: [f64; 10] = [1.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9];
const POW10_U: [u64; 10] =
    [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000, 1_000_000_000];
/// 2^52: for `0 ≤ s < 2^52`, `(s + 2^52) − 2^52` is `s` rounded to an integer, ties to even
/// (the default rounding of the addition; the subtraction is exact).
const TWO_52: f64 = 4_503_599_627_370_496.0;

/// Calls `f` with the text of `x` with `d` decimals (`format!("{x:.d$}")`).
pub fn with_fixed<R>(x: f64, d: usize, f: impl FnOnce(&str) -> R) -> R {
    let mut buf = [0u8; 40];
    match fast(x, d, &mut buf).and_then(|n| buf.get(..n)).and_then(|b| std::str::from_utf8(b).ok()) {
        Some(text) => f(text),
        None => f(&format!("{x:.d$}")),
    }
}

/// Appends the text of `x` with `d` decimals to `out`.
pub fn push_fixed(out: &mut Vec<u8>, x: f64, d: usize) {
    let mut buf = [0u8; 40];
    match fast(x, d, &mut buf).and_then(|n| buf.get(..n)) {
        Some(b) => out.extend_from_slice(b),
        None => out.extend_from_slice(format!("{x:.d$}").as_bytes()),
    }
}

/// The text into `buf`, its length; `None`: not handled here.
fn fast(x: f64, d: usize, buf: &mut [u8; 40]) -> Option<usize> {
    let (&scale, &scale_u) = (POW10.get(d)?, POW10_U.get(d)?);
    let a = x.abs();
    let s = a * scale;
    if s.is_nan() || s >= TWO_52 {
        return None; // NaN, ±∞ or too large
    }
    let mut n = (s + TWO_52) - TWO_52;
    let diff = s - n; // exact (Sterbenz; 0 ≤ s < 2^52)
    if diff == 0.5 || diff == -0.5 {
        // s is halfway: the product's exact residual decides.
        let r = a.mul_add(scale, -s);
        if diff == 0.5 && r > 0.0 {
            n += 1.0;
        } else if diff == -0.5 && r < 0.0 {
            n -= 1.0;
        }
    }
    let m = n as u64;
    let (int, frac) = (m / scale_u, m % scale_u);
    let mut len = 0;
    let mut put = |c: u8| {
        if let Some(b) = buf.get_mut(len) {
            *b = c;
            len += 1;
        }
    };
    if x.is_sign_negative() {
        put(b'-');
    }
    let mut digits = [0u8; 20];
    let mut k = 0;
    let mut v = int;
    loop {
        if let Some(dg) = digits.get_mut(k) {
            *dg = b'0' + (v % 10) as u8;
        }
        k += 1;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    for i in (0..k).rev() {
        put(digits.get(i).copied().unwrap_or(b'0'));
    }
    if d > 0 {
        put(b'.');
        let mut p = scale_u / 10;
        while p > 0 {
            put(b'0' + ((frac / p) % 10) as u8);
            p /= 10;
        }
    }
    Some(len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn check(x: f64, d: usize) {
        let want = format!("{x:.d$}");
        with_fixed(x, d, |got| assert_eq!(got, want, "{x:e} with {d} decimals"));
        let mut v = Vec::new();
        push_fixed(&mut v, x, d);
        assert_eq!(String::from_utf8(v).unwrap(), want);
    }

    /// The same text as std on random values of every magnitude, `f32` values (the report's
    /// columns), exact ties and values next to them, signed zeros, non-finite and too-large
    /// values (std's own text).
    #[test]
    fn the_text_is_std_s() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(19);
        let specials = [
            0.0,
            -0.0,
            0.25,
            -0.25,
            2.5,
            3.5,
            0.125,
            1.03125,
            -1.03125,
            5e-5,
            -1e-5,
            1e-300,
            f64::MIN_POSITIVE,
        ];
        let big =
            [4.5e15, 4.503599627370496e15, 1e16, 1e300, f64::MAX, f64::INFINITY, f64::NEG_INFINITY, f64::NAN];
        for d in 0..=11 {
            for &x in specials.iter().chain(big.iter()) {
                check(x, d);
            }
            for _ in 0..20_000 {
                let e = rng.random_range(-12..16);
                let x = rng.random_range(-1.0..1.0) * 10f64.powi(e);
                check(x, d);
                check(x as f32 as f64, d);
                // Halfway cases: (k + ½)/10^d, exactly representable or not, and their neighbours.
                let k = rng.random_range(0..1_000_000u64) as f64;
                let t = (k + 0.5) / 10f64.powi(d as i32);
                for y in [t, t.next_up(), t.next_down(), -t, (k + 0.5) / 1024.0] {
                    check(y, d);
                }
            }
        }
    }
}
