//! Memory sizes as people write them (`4GiB`, `512MB`, `1.5G`, `1048576`) and as messages print
//! them.

/// Parses a size in bytes: a non-negative number (fractions allowed) and an optional unit, with or
/// without a space between. `KiB`/`MiB`/`GiB`/`TiB` and the bare `K`/`M`/`G`/`T` (as Docker,
/// `sort -S` and `ulimit` read them) are powers of 1024; `kB`/`KB`/`MB`/`GB`/`TB` are powers of
/// 1000; `B` or no unit is bytes. Units are case-insensitive. Zero is refused: a budget of nothing
/// refuses everything, which is never what was meant.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let example = "write e.g. 4GiB, 512MiB, 8G or 2000000000 (bytes)";
    if number.is_empty() {
        return Err(format!(
            "{text:?} is not a size: it does not start with a number; {example}"
        ));
    }
    let value: f64 = number
        .parse()
        .map_err(|_| format!("{text:?} is not a size: {number:?} is not a number; {example}"))?;
    let scale: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" => 1024.0,
        "m" | "mib" => 1024f64.powi(2),
        "g" | "gib" => 1024f64.powi(3),
        "t" | "tib" => 1024f64.powi(4),
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "tb" => 1e12,
        other => {
            return Err(format!(
                "{text:?} is not a size: unknown unit {other:?} (use B, KiB, MiB, GiB, TiB, their \
                 short forms K, M, G, T, or the decimal kB, MB, GB, TB); {example}"
            ))
        }
    };
    let bytes = value * scale;
    if bytes.is_nan() || bytes < 1.0 {
        return Err(format!(
            "{text:?} is not a usable size: give at least 1 byte; {example}"
        ));
    }
    if bytes >= u64::MAX as f64 {
        return Err(format!("{text:?} is too large a size; {example}"));
    }
    Ok(bytes.round() as u64)
}

/// `bytes` in the largest binary unit that keeps at least one whole unit, one decimal: "6.0 GiB",
/// "512.0 MiB", "900 B".
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["KiB", "MiB", "GiB", "TiB", "PiB"];
    if bytes < 1024 {
        return format!("{bytes} B");
    }
    let mut value = bytes as f64;
    let mut unit = "B";
    for u in UNITS {
        if value < 1024.0 {
            break;
        }
        value /= 1024.0;
        unit = u;
    }
    format!("{value:.1} {unit}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_and_decimal_units() {
        assert_eq!(parse_size("4GiB"), Ok(4 << 30));
        assert_eq!(parse_size("4 GiB"), Ok(4 << 30));
        assert_eq!(parse_size("4g"), Ok(4 << 30));
        assert_eq!(parse_size("512MB"), Ok(512_000_000));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("2000"), Ok(2000));
        assert_eq!(parse_size("2000B"), Ok(2000));
        assert_eq!(parse_size("1kB"), Ok(1000));
        assert_eq!(parse_size("1KiB"), Ok(1024));
    }

    #[test]
    fn bad_sizes_say_what_to_write() {
        for bad in [
            "",
            "GiB",
            "4 parsecs",
            "0",
            "0GiB",
            "1.2.3G",
            "-1G",
            "1e999",
        ] {
            let e = parse_size(bad).unwrap_err();
            assert!(e.contains("e.g. 4GiB"), "{bad:?}: {e}");
        }
        assert!(parse_size("4 parsecs")
            .unwrap_err()
            .contains("unknown unit \"parsecs\""));
        assert!(parse_size("99999999TiB").unwrap_err().contains("too large"));
    }

    #[test]
    fn bytes_format_in_binary_units() {
        assert_eq!(format_bytes(900), "900 B");
        assert_eq!(format_bytes(1536), "1.5 KiB");
        assert_eq!(format_bytes(6 << 30), "6.0 GiB");
        assert_eq!(format_bytes(6_400_000_000), "6.0 GiB");
    }
}
