//! Correct rounding of the number parser against the standard library and hard cases.

use super::*;

fn parse(s: &str) -> Result<f64, BadNumber> {
    let mut i = 0;
    let v = parse_number(s.as_bytes(), &mut i)?;
    assert_eq!(i, s.len(), "{s}: stopped at {i}");
    Ok(v)
}

#[test]
fn matches_the_standard_parser_on_shortest_and_long_forms() {
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for n in 0..400_000 {
        let bits = next();
        let v = match n % 4 {
            // any finite double
            0 => f64::from_bits(bits),
            // mm-scale values, 17 digits
            1 => (bits >> 11) as f64 / (1u64 << 53) as f64 * 2000.0 - 1000.0,
            2 => (bits >> 11) as f64 * 1e-9,
            _ => ((bits >> 11) % 100_000_000) as f64 / 1e6,
        };
        if !v.is_finite() {
            continue;
        }
        let texts = [
            ryu::Buffer::new().format(v).to_string(),
            format!("{v:e}"),
            format!("{v:.6}"),
            format!("{v:.20}"),
            format!("{:.3E}", v),
        ];
        for t in texts {
            let t = t.replace("E", "e+").replace("e+-", "e-");
            let want: f64 = t.parse().unwrap();
            let got = parse(&t).unwrap_or_else(|e| panic!("{t}: {e:?}"));
            assert_eq!(got.to_bits(), want.to_bits(), "{t}");
        }
    }
}

#[test]
fn the_product_route_agrees_with_the_division_route() {
    let mut x: u64 = 0x2545_F491_4F6C_DD1D;
    for n in 0..2_000_000u64 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let w = (x >> (n % 64)).max(1);
        let k = 1 + (n % 22) as u32;
        assert_eq!(
            div_pow10(w, k).to_bits(),
            div_pow10_exact(w, k).to_bits(),
            "{w}e-{k}"
        );
        let want: f64 = format!("{w}e-{k}").parse().unwrap();
        if n % 16 == 0 {
            assert_eq!(div_pow10(w, k), want, "{w}e-{k}");
        }
    }
    // exact ties between two doubles: w = 5^k times an odd 54-bit number
    for k in 1..=5u32 {
        let d = POW5[k as usize];
        for odd in [(1u64 << 53) + 1, (1 << 53) + 3, (1 << 54) - 1] {
            if let Some(w) = odd.checked_mul(d) {
                let want: f64 = format!("{w}e-{k}").parse().unwrap();
                assert_eq!(div_pow10(w, k), want, "{w}e-{k}");
            }
        }
    }
}

#[test]
fn rounds_halfway_cases_to_even() {
    // 2^53 + 1 and 2^53 + 3 are exactly between two doubles.
    for t in [
        "9007199254740993",
        "9007199254740995",
        "9007199254740993e-5",
        "900719925474099.3",
        "1.8014398509481985e-3",
        "18014398509481985e-10",
        "0.30000000000000004",
        "123456789012345678e-20",
        "9999999999999999999e-22",
        "12345678901234567890123e-20",
        "0.000000000000000000000000000001234567890123456789",
    ] {
        assert_eq!(parse(t).unwrap(), t.parse::<f64>().unwrap(), "{t}");
    }
}

#[test]
fn follows_the_json_grammar() {
    for (t, v) in [
        ("0", 0.0),
        ("-0", -0.0),
        ("-12.5e+1", -125.0),
        ("1E2", 100.0),
        ("0.001e3", 1.0),
        ("0e7", 0.0),
    ] {
        assert_eq!(parse(t).unwrap(), v, "{t}");
    }
    assert!(parse("-0").unwrap().is_sign_negative());
    for t in ["01", "1.", "1.e5", "1e", "1e+", "-", "-a", "--1"] {
        assert_eq!(
            parse_number(t.as_bytes(), &mut 0),
            Err(BadNumber::Malformed),
            "{t}"
        );
    }
    for t in ["", "+1", ".5", "NaN", "Infinity", "\"1\"", "[1]"] {
        assert_eq!(
            parse_number(t.as_bytes(), &mut 0),
            Err(BadNumber::NotANumber),
            "{t}"
        );
    }
    assert_eq!(parse("1e999"), Err(BadNumber::NonFinite));
    assert_eq!(parse("-1e400"), Err(BadNumber::NonFinite));
    assert_eq!(parse("1e-999").unwrap(), 0.0);
    // stops at the first byte that is not part of the number
    let mut i = 0;
    assert_eq!(parse_number(b"2.5,3", &mut i), Ok(2.5));
    assert_eq!(i, 3);
}
