//! CSV and Markdown of the barycenter sweeps.

use super::{AccuracyRow, ResolutionRow, PROXIES, RESOLUTIONS};
use std::fmt::Write;

/// The accuracy CSV's header.
pub const ACCURACY_HEADER: &str =
    "case,proxy,n,weights,region,build_weights,scale,w2_gap,objective,truth_objective,excess";
/// The resolution CSV's header.
pub const RESOLUTION_HEADER: &str = "n,resolution,samples_per_pixel,l1,reference_share";

/// The accuracy rows as CSV (weights joined by `;`, an empty excess at vertices).
pub fn accuracy_csv(rows: &[AccuracyRow]) -> String {
    let mut s = format!("{ACCURACY_HEADER}\n");
    for r in rows {
        let w: Vec<String> = r.weights.iter().map(|w| format!("{w:.4}")).collect();
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{}",
            r.case,
            r.proxy,
            r.n,
            w.join(";"),
            r.region,
            r.build_weights,
            r.scale,
            r.w2_gap,
            r.objective,
            r.truth_objective,
            r.excess.map(|e| format!("{e:.6e}")).unwrap_or_default()
        );
    }
    s
}

/// The resolution rows as CSV.
pub fn resolution_csv(rows: &[ResolutionRow]) -> String {
    let mut s = format!("{RESOLUTION_HEADER}\n");
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{:.6},{:.6e},{:.6e}",
            r.n, r.resolution, r.samples_per_pixel, r.l1, r.reference_share
        );
    }
    s
}

fn stats(v: &[f64]) -> Option<(f64, f64)> {
    (!v.is_empty()).then(|| {
        (
            v.iter().sum::<f64>() / v.len() as f64,
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    })
}

fn pct(v: Option<(f64, f64)>) -> String {
    v.map_or("—".into(), |(m, x)| {
        format!("{:.2} / {:.2}", 100.0 * m, 100.0 * x)
    })
}

/// The summary: per case, per proxy, the W2 gap (% of the scale) and the objective excess (%),
/// mean / worst over the sweep's edges and interior, and at the centre; then the resolution table.
pub fn accuracy_markdown(rows: &[AccuracyRow], res: &[ResolutionRow]) -> String {
    let mut s = String::from("# Proxy blends against true barycenters\n\n");
    let mut cases: Vec<&str> = Vec::new();
    for r in rows {
        if !cases.contains(&r.case.as_str()) {
            cases.push(&r.case);
        }
    }
    for case in cases {
        let of = |p: &'static str| rows.iter().filter(move |r| r.case == case && r.proxy == p);
        let Some(first) = of(PROXIES[0]).next() else {
            continue;
        };
        let _ = writeln!(
            s,
            "## {case}, n = {}, scale s = {:.4e} (RMS pairwise W2 of the inputs)\n",
            first.n, first.scale
        );
        s += "| proxy | W2 gap / s, edges (mean / worst, %) | interior | objective excess, edges (%) | interior | at the centre: gap / excess (%) |\n|---|---|---|---|---|---|\n";
        for p in PROXIES {
            let gap = |region: &str| {
                stats(
                    &of(p)
                        .filter(|r| r.region == region)
                        .map(|r| r.w2_gap)
                        .collect::<Vec<_>>(),
                )
            };
            let exc = |region: &str| {
                stats(
                    &of(p)
                        .filter(|r| r.region == region)
                        .filter_map(|r| r.excess)
                        .collect::<Vec<_>>(),
                )
            };
            let k = first.weights.len();
            let centre =
                of(p).find(|r| r.weights.iter().all(|&w| (w - 1.0 / k as f64).abs() < 1e-9));
            let c = centre.map_or("—".into(), |r| {
                format!(
                    "{:.3} / {:.4}",
                    100.0 * r.w2_gap,
                    100.0 * r.excess.unwrap_or(f64::NAN)
                )
            });
            let _ = writeln!(
                s,
                "| {p} | {} | {} | {} | {} | {c} |",
                pct(gap("edge")),
                pct(gap("interior")),
                pct(exc("edge")),
                pct(exc("interior"))
            );
        }
        s.push('\n');
    }
    if !res.is_empty() {
        s += "## Rendered blend error against n (relative L1 against the largest n, σ = ½ px)\n\n| n | ";
        s += &RESOLUTIONS.map(|r| format!("{r}² (spp)")).join(" | ");
        s += " |\n|---|";
        s += &"---|".repeat(RESOLUTIONS.len());
        s.push('\n');
        let mut ns: Vec<usize> = res.iter().map(|r| r.n).collect();
        ns.dedup();
        for n in ns {
            let _ = write!(s, "| {n} |");
            for r in RESOLUTIONS {
                match res.iter().find(|x| x.n == n && x.resolution == r) {
                    Some(x) => {
                        let _ = write!(s, " {:.3} ({:.2}) |", x.l1, x.samples_per_pixel);
                    }
                    None => s += " — |",
                }
            }
            s.push('\n');
        }
    }
    s
}
