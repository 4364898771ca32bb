//! Numbers as text: what every CSV and id of pupper writes.

/// A float as the shortest text that reads back to the same bits; NaN empty.
/// From 1e16 on (where the plain form needs 17 or more digits, 301 for
/// 1e300) the shortest exponent form, as `1e300`.
pub fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else if v.abs() >= 1e16 && v.is_finite() {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shortest_round_trip_and_nan_empty() {
        for v in [0.1, 1.0 / 3.0, 1e-300, -2.5, 120.0] {
            assert_eq!(fmt_f64(v).parse::<f64>().unwrap().to_bits(), v.to_bits());
        }
        assert_eq!(fmt_f64(120.0), "120");
        assert_eq!(fmt_f64(f64::NAN), "");
        // huge values in exponent form, still exact
        for v in [1e300, -2.5e16, 123456789e20] {
            let t = fmt_f64(v);
            assert!(t.len() < 16 && t.contains('e'), "{t}");
            assert_eq!(t.parse::<f64>().unwrap().to_bits(), v.to_bits());
        }
        assert_eq!(fmt_f64(1e300), "1e300");
        assert_eq!(fmt_f64(9999999999999998.0), "9999999999999998");
    }
}
