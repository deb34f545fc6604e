//! How numbers are shown to the user: byte counts and data values, the same
//! in the viewer's panels and in `vol_app info`.

/// A byte count in binary units.
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
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

/// A value with as many decimals as its size needs.
pub fn value(v: f32) -> String {
    if v == v.round() && v.abs() < 1e7 {
        format!("{v:.0}")
    } else if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn bytes_use_binary_units() {
        assert_eq!(super::bytes(26), "26 B");
        assert_eq!(super::bytes(491_546), "480.0 KiB");
        assert_eq!(super::bytes(3 << 30), "3.0 GiB");
    }

    #[test]
    fn whole_values_have_no_decimals() {
        assert_eq!(super::value(85.0), "85");
        assert_eq!(super::value(-1024.0), "-1024");
        assert_eq!(super::value(0.25), "0.250");
    }
}
