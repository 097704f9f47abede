//! JSON numbers to `f64`, correctly rounded, for the step-error decoder.
//!
//! The grammar is JSON's (RFC 8259 §6): `-? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)?`.
//! The value is the nearest `f64` (ties to even) of the decimal `w * 10^q` (`w` the significant
//! digits), by one of three exact routes:
//!
//! * `|q| <= 22` with `w <= 2^53`: Clinger's fast path (W. D. Clinger, "How to read floating
//!   point numbers accurately", PLDI 1990): `w` and `10^|q|` are exact in `f64`, so `w * 10^q`
//!   or `w / 10^-q` is one correctly rounded IEEE operation.
//! * `-22 <= q < 0` with `2^53 < w` and at most 19 significant digits (the 17-digit output of
//!   shortest round-trip printers for values in mm): `w / 10^k = (w / 5^k) 2^-k`, the quotient
//!   from a product with a truncated reciprocal of `5^k`, checked, and by integer division when
//!   the check cannot decide ([`div_pow10`]).
//! * Anything else (more than 19 digits, large exponents): the standard library's parser on the
//!   validated text.
//!
//! Digits are read eight at a time (SWAR), as in fast_float (Lemire 2021, §5).

/// Why the text at the cursor is not a usable number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BadNumber {
    /// No number starts here (a letter, a quote, a bracket, the end).
    NotANumber,
    /// A number with a syntax error: `01`, `1.`, `1e`, `-`.
    Malformed,
    /// Valid syntax whose value overflows to infinity (`1e999`).
    NonFinite,
}

const MAX_DIGITS: u32 = 19;

/// `10^k`, exact in `f64` for `k <= 22`.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `5^k` for `k <= 22` (all below `2^52`).
const POW5: [u64; 23] = {
    let mut t = [1u64; 23];
    let mut k = 1;
    while k < 23 {
        t[k] = t[k - 1] * 5;
        k += 1;
    }
    t
};

/// Parses the JSON number starting at `b[*pos]` and moves `*pos` past it.
///
/// Returns the nearest `f64` to the decimal value (ties to even). `-0` gives `-0.0`. Errors
/// leave `*pos` unspecified.
#[inline]
pub fn parse_number(b: &[u8], pos: &mut usize) -> Result<f64, BadNumber> {
    let start = *pos;
    let mut i = start;
    let neg = b.get(i) == Some(&b'-');
    i += neg as usize;
    let mut w: u64 = 0;
    let mut nd: u32 = 0;
    let mut q: i64 = 0;
    match b.get(i) {
        Some(b'0') => {
            i += 1;
            if matches!(b.get(i), Some(b'0'..=b'9')) {
                return Err(BadNumber::Malformed);
            }
        }
        Some(b'1'..=b'9') => {
            digits(b, &mut i, &mut w, &mut nd);
        }
        _ if neg => return Err(BadNumber::Malformed),
        _ => return Err(BadNumber::NotANumber),
    }
    if b.get(i) == Some(&b'.') {
        i += 1;
        let s = i;
        if w == 0 {
            while b.get(i) == Some(&b'0') {
                i += 1;
            }
        }
        digits(b, &mut i, &mut w, &mut nd);
        if i == s {
            return Err(BadNumber::Malformed);
        }
        q -= (i - s) as i64;
    }
    if matches!(b.get(i), Some(b'e' | b'E')) {
        i += 1;
        let eneg = match b.get(i) {
            Some(b'-') => {
                i += 1;
                true
            }
            Some(b'+') => {
                i += 1;
                false
            }
            _ => false,
        };
        let s = i;
        let mut x: i64 = 0;
        while let Some(&c @ b'0'..=b'9') = b.get(i) {
            x = (x * 10 + (c - b'0') as i64).min(1 << 40);
            i += 1;
        }
        if i == s {
            return Err(BadNumber::Malformed);
        }
        q += if eneg { -x } else { x };
    }
    *pos = i;
    let exact = if nd <= MAX_DIGITS { fast(w, q) } else { None };
    let v = match exact {
        Some(v) => v,
        None => {
            // The text is validated JSON, which Rust's float grammar accepts.
            let text = std::str::from_utf8(&b[start + neg as usize..i]).expect("ASCII");
            let v: f64 = text.parse().map_err(|_| BadNumber::Malformed)?;
            if !v.is_finite() {
                return Err(BadNumber::NonFinite);
            }
            v
        }
    };
    Ok(if neg { -v } else { v })
}

/// Reads decimal digits, appending the first [`MAX_DIGITS`] to `w` and counting all in `nd`.
/// Callers start it on a significant digit (leading zeros are skipped before), so `nd` counts
/// significant digits; past [`MAX_DIGITS`] the caller takes the exact slow route.
///
/// Eight bytes at a time: the run of leading digits in a little-endian word is found with a
/// mask and read in one SWAR step, so a 17-digit number takes three steps, not 17 dependent
/// multiply-adds.
#[inline(always)]
fn digits(b: &[u8], i: &mut usize, w: &mut u64, nd: &mut u32) {
    while let Some(chunk) = b.get(*i..*i + 8) {
        let v = u64::from_le_bytes(chunk.try_into().expect("8 bytes"));
        let n = leading_digits(v);
        if n == 0 {
            return;
        }
        if *nd + n > MAX_DIGITS {
            break;
        }
        let value = if n == 8 {
            parse_8digits(v)
        } else {
            // The n digits moved to the top bytes, '0' below them.
            parse_8digits((v << (8 * (8 - n))) | (0x3030_3030_3030_3030 >> (8 * n)))
        };
        *w = *w * POW10_U64[n as usize] + value;
        *nd += n;
        *i += n as usize;
        if n < 8 {
            return;
        }
    }
    while let Some(&c @ b'0'..=b'9') = b.get(*i) {
        if *nd < MAX_DIGITS {
            *w = *w * 10 + (c - b'0') as u64;
        }
        *nd += 1;
        *i += 1;
    }
}

/// `10^n` for `n <= 8`.
const POW10_U64: [u64; 9] = [
    1,
    10,
    100,
    1000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
];

/// How many of the 8 little-endian bytes of `v`, from the first, are ASCII digits. A byte
/// below '0' borrows and one above '9' carries into its top bit; carries and borrows run
/// towards later bytes only, so the first non-digit is always flagged.
#[inline(always)]
fn leading_digits(v: u64) -> u32 {
    let flags = (v.wrapping_add(0x4646_4646_4646_4646) | v.wrapping_sub(0x3030_3030_3030_3030))
        & 0x8080_8080_8080_8080;
    flags.trailing_zeros() / 8
}

/// The value of 8 ASCII digits (first digit in the lowest byte), SWAR.
#[inline(always)]
fn parse_8digits(mut v: u64) -> u64 {
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    const MUL1: u64 = 0x000F_4240_0000_0064;
    const MUL2: u64 = 0x0000_2710_0000_0001;
    v -= 0x3030_3030_3030_3030;
    v = (v * 10) + (v >> 8);
    let v1 = (v & MASK).wrapping_mul(MUL1);
    let v2 = ((v >> 16) & MASK).wrapping_mul(MUL2);
    ((v1.wrapping_add(v2) >> 32) as u32) as u64
}

/// `w * 10^q` correctly rounded when one of the exact routes applies.
#[inline(always)]
fn fast(w: u64, q: i64) -> Option<f64> {
    if w == 0 {
        return Some(0.0);
    }
    if w <= 1 << 53 {
        // Exact operands, one rounding (`as i64`: the one-instruction conversion).
        if (0..=22).contains(&q) {
            return Some(w as i64 as f64 * POW10[q as usize]);
        }
        if (-22..0).contains(&q) {
            return Some(w as i64 as f64 / POW10[(-q) as usize]);
        }
        return None;
    }
    if (-22..0).contains(&q) {
        return Some(div_pow10(w, (-q) as u32));
    }
    None
}

/// `2^(127 + b) / 5^k` truncated, `b` the bit length of `5^k`: the 128-bit normalised
/// reciprocals of `5^k`, `k <= 22` (long division at compile time).
const INV5: [u128; 23] = {
    let mut t = [0u128; 23];
    let mut k = 1;
    while k < 23 {
        let d = POW5[k] as u128;
        let bits = 128 - d.leading_zeros();
        // Binary long division of 2^(127 + bits) by d; the quotient is below 2^128.
        let mut rem: u128 = 1;
        let mut quo: u128 = 0;
        let mut step = 0;
        while step < 127 + bits {
            rem <<= 1;
            quo <<= 1;
            if rem >= d {
                rem -= d;
                quo |= 1;
            }
            step += 1;
        }
        t[k] = quo;
        k += 1;
    }
    t
};

/// `w / 10^k` correctly rounded, for `1 <= w < 2^64` and `1 <= k <= 22` (used for `w > 2^53`):
/// `w / 10^k = (w / 5^k) 2^-k`, the quotient from a 64 x 128-bit product with the truncated
/// reciprocal [`INV5`] (the method of D. Lemire, "Number parsing at a gigabyte per second",
/// Software: Practice and Experience 51(8), 2021, with the table limited to these `k`). The
/// product `P` is below the exact `X` by less than `2^64`, so `X >> 64` is `P >> 64` or one
/// more; when that could change the rounding (the low word of `P >> 64` is 0 or all ones, about
/// once in 2^63), the exact integer division decides ([`div_pow10_exact`]).
#[inline(always)]
fn div_pow10(w: u64, k: u32) -> f64 {
    let t = INV5[k as usize];
    let lz = w.leading_zeros() as i32;
    let wn = (w << lz) as u128;
    // floor(P / 2^64), P = wn * t (192 bits), as two words.
    let high = wn * (t >> 64) + ((wn * (t as u64 as u128)) >> 64);
    let (hi, lo) = ((high >> 64) as u64, high as u64);
    // hi >= 2^62: the 53 kept bits and the round bits are all in `hi`. The exact quotient's
    // `high` is this one or one more: with `lo` neither 0 nor all ones, that cannot carry into
    // `hi` nor make an exact tie, so the rounding is decided (else: integer division).
    if lo == 0 || lo == u64::MAX {
        return div_pow10_exact(w, k);
    }
    let shift = 11 - hi.leading_zeros() as i32;
    let mut mant = hi >> shift;
    let rest = hi & ((1u64 << shift) - 1);
    let mut e = shift + 1 - LOG2_POW5[k as usize] - lz - k as i32;
    if rest >= 1 << (shift - 1) {
        mant += 1;
        if mant == 1 << 53 {
            mant >>= 1;
            e += 1;
        }
    }
    mant as i64 as f64 * pow2(e)
}

/// Bit lengths of `5^k`.
const LOG2_POW5: [i32; 23] = {
    let mut t = [0i32; 23];
    let mut k = 0;
    while k < 23 {
        t[k] = 64 - POW5[k].leading_zeros() as i32;
        k += 1;
    }
    t
};

/// `2^e` for a normal exponent.
#[inline(always)]
fn pow2(e: i32) -> f64 {
    f64::from_bits(((1023 + e) as u64) << 52)
}

/// [`div_pow10`] by integer division: the quotient with at least 54 bits, rounded to 53 with
/// the remainder as sticky bit (ties to even).
fn div_pow10_exact(w: u64, k: u32) -> f64 {
    let d = POW5[k as usize];
    let lw = 64 - w.leading_zeros() as i32;
    let ld = 64 - d.leading_zeros() as i32;
    let s = (54 + ld - lw).max(0);
    let n = (w as u128) << s;
    let quo = n / d as u128;
    let rem = n - quo * d as u128;
    let bits = 128 - quo.leading_zeros() as i32;
    let mut drop = bits - 53;
    let mut mant = (quo >> drop) as u64;
    let low = quo & ((1u128 << drop) - 1);
    let half = 1u128 << (drop - 1);
    if low > half || (low == half && (rem != 0 || mant & 1 == 1)) {
        mant += 1;
        if mant == 1 << 53 {
            mant >>= 1;
            drop += 1;
        }
    }
    // mant < 2^53 is exact; the scale is a power of two and the result stays normal
    // (w / 10^k >= 10^-22).
    mant as f64 * pow2(drop - s - k as i32)
}

#[cfg(test)]
mod tests;
