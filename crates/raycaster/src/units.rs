//! How numbers are shown to people, the same in every program of the
//! workspace: byte counts in binary units, data values, and measured
//! quantities (spacing, extents) without float noise.

/// A byte count in binary units with one decimal (`480.0 KiB`, `3.0 GiB`);
/// below 1 KiB the exact count (`26 B`).
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// A data value with as many decimals as its size needs: whole numbers
/// without any (`-1024`), others with 1 (from 100 up) or 3.
pub fn value(v: f32) -> String {
    if v == v.round() && v.abs() < 1e7 {
        format!("{v:.0}")
    } else if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

/// `v` rounded to at most `digits` significant digits, trailing zeros
/// trimmed: `3.0000002` → `3`, `0.703125` → `0.703125`, `0.957` → `0.957`
/// (an `f32` read from a file prints without its binary noise). Digits left
/// of the point are never dropped (`1234567` stays whole).
pub fn significant(v: impl Into<f64>, digits: u32) -> String {
    let v: f64 = v.into();
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return v.to_string();
    }
    let magnitude = v.abs().log10().floor() as i32;
    let decimals = (digits.max(1) as i32 - 1 - magnitude).max(0) as usize;
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.truncate(s.trim_end_matches('0').trim_end_matches('.').len());
    }
    if s == "-0" { "0".into() } else { s }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_use_binary_units() {
        assert_eq!(bytes(26), "26 B");
        assert_eq!(bytes(491_546), "480.0 KiB");
        assert_eq!(bytes(3 << 30), "3.0 GiB");
    }

    #[test]
    fn disk_sizes_too() {
        // vol_gen's free-space message and summary.
        assert_eq!(bytes(26), "26 B");
        assert_eq!(bytes(9_800_000_000), "9.1 GiB");
        assert_eq!(bytes(512_000_026), "488.3 MiB");
    }

    #[test]
    fn whole_values_have_no_decimals() {
        assert_eq!(value(85.0), "85");
        assert_eq!(value(-1024.0), "-1024");
        assert_eq!(value(0.25), "0.250");
    }

    #[test]
    fn significant_digits_drop_float_noise() {
        assert_eq!(significant(3.000_000_2_f32, 6), "3");
        assert_eq!(significant(0.703_125_f32, 6), "0.703125");
        assert_eq!(significant(0.957_f32, 6), "0.957");
        assert_eq!(significant(2.5_f32, 6), "2.5");
        assert_eq!(significant(-1.5e-7, 6), "-0.00000015");
        assert_eq!(significant(360.000_03_f32, 6), "360");
        assert_eq!(significant(1_234_567.0, 6), "1234567");
        assert_eq!(significant(0.0, 6), "0");
        assert_eq!(significant(-1e-12, 2), "-0.000000000001");
        assert_eq!(significant(f64::INFINITY, 6), "inf");
    }
}
