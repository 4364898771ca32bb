//! Numbers as text: what every CSV and id of pupper writes.

/// A float as the shortest text that reads back to the same bits; NaN empty.
pub fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        String::new()
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
    }
}
