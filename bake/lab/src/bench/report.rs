//! The bench's text outputs: the CSV (full precision) and the Markdown summary table.

use super::Row;

/// The CSV header (one row per run follows).
pub const CSV_HEADER: &str = "case,solver,settings,n,seconds,cost,cost_ratio,uvp_exact_percent,uvp_closed_form_percent,distance_sw2,iterations,residual,converged,error";

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// RFC 4180 quoting: fields with commas, quotes or newlines are quoted, quotes doubled.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The CSV text of the rows (floats in Rust's shortest round-trip form).
pub fn to_csv(rows: &[Row]) -> String {
    let mut out = String::from(CSV_HEADER);
    out.push('\n');
    for r in rows {
        let fields = [
            csv_field(&r.case),
            r.solver.to_string(),
            csv_field(&r.settings),
            r.n.to_string(),
            format!("{:.6}", r.seconds),
            opt(r.cost),
            opt(r.cost_ratio),
            opt(r.uvp_exact),
            opt(r.uvp_closed_form),
            opt(r.distance),
            opt(r.iterations),
            opt(r.residual),
            r.converged.to_string(),
            csv_field(r.error.as_deref().unwrap_or("")),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// A Markdown table of the rows (rounded for reading; the CSV has full precision).
pub fn to_markdown(rows: &[Row]) -> String {
    let mut out = String::from(
        "| case | solver | settings | n | seconds | cost / exact | L2-UVP vs exact (%) | L2-UVP vs closed form (%) | SW2 pushed vs target | converged |\n\
         |---|---|---|---:|---:|---:|---:|---:|---:|---|\n",
    );
    let ratio = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.5}"));
    // Percentages: three decimals, or two significant digits below 0.01 (Sinkhorn's matchings are
    // often within 1e-4 % of the exact one, which three decimals would show as 0).
    let pct = |v: Option<f64>| match v {
        None => "—".to_string(),
        Some(0.0) => "0".to_string(),
        Some(v) if v < 0.01 => format!("{v:.1e}"),
        Some(v) => format!("{v:.3}"),
    };
    for r in rows {
        let converged = match (&r.error, r.converged) {
            (None, true) => "yes".to_string(),
            (Some(e), _) => {
                // The CSV has the whole message; the table keeps its start.
                let e = e.replace('|', "/");
                match e.char_indices().nth(100) {
                    Some((cut, _)) => format!("no: {}…", &e[..cut]),
                    None => format!("no: {e}"),
                }
            }
            (None, false) => "no".to_string(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {:.3} | {} | {} | {} | {} | {} |\n",
            r.case,
            r.solver,
            r.settings,
            r.n,
            r.seconds,
            ratio(r.cost_ratio),
            pct(r.uvp_exact),
            pct(r.uvp_closed_form),
            match r.distance {
                None => "—".into(),
                Some(0.0) => "0".into(),
                Some(v) => format!("{v:.2e}"),
            },
            converged
        ));
    }
    out
}
