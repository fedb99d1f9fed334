//! `otbake bench --quick` end to end: the CSV has one row per planned run with sane values, and the
//! chart is a PNG of the documented size.

use otbake_tests::{otbake, otbake_ok, scratch, shared_data};
use std::collections::HashMap;

/// Splits one CSV line (fields may be quoted, with doubled quotes inside).
fn fields(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut cur)),
            _ => cur.push(c),
        }
    }
    out.push(cur);
    out
}

fn num(row: &HashMap<String, String>, key: &str) -> Option<f64> {
    let v = &row[key];
    (!v.is_empty()).then(|| v.parse().unwrap_or_else(|_| panic!("{key} = {v:?}")))
}

#[test]
fn quick_bench_writes_expected_rows_and_chart() {
    let dir = scratch("bench-quick");
    let shapes = shared_data().join("shapes");
    otbake_ok(
        &dir,
        &[
            "bench",
            "--quick",
            "--out",
            "out",
            "--shapes",
            shapes.to_str().unwrap(),
        ],
    );
    let csv = std::fs::read_to_string(dir.join("out/bench.csv")).unwrap();
    let mut lines = csv.lines();
    let header = fields(lines.next().unwrap());
    assert_eq!(header, fields(otbake_lab::bench::CSV_HEADER));
    let rows: Vec<HashMap<String, String>> = lines
        .map(|l| header.iter().cloned().zip(fields(l)).collect())
        .collect();

    // 6 cases (gaussian, 4 shapes, blobs) × (1 exact + 2 sliced + 3 sinkhorn) at n = 400.
    let mut shape_names: Vec<String> = std::fs::read_dir(&shapes)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "png").then(|| p.file_stem().unwrap().to_string_lossy().into())
        })
        .collect();
    shape_names.sort();
    let mut cases = vec!["gaussian".to_string()];
    cases.extend(shape_names);
    cases.push("blobs".into());
    assert_eq!(rows.len(), cases.len() * 6, "{csv}");
    for case in &cases {
        let of = |solver: &str| {
            rows.iter()
                .filter(|r| &r["case"] == case && r["solver"] == solver)
                .count()
        };
        assert_eq!(
            (of("exact"), of("sliced"), of("sinkhorn")),
            (1, 2, 3),
            "{case}"
        );
    }

    for r in &rows {
        let what = format!("{r:?}");
        assert_eq!(r["n"], otbake_lab::bench::QUICK_N.to_string(), "{what}");
        assert_eq!(r["converged"], "true", "{what}");
        assert_eq!(r["error"], "", "{what}");
        let seconds = num(r, "seconds").unwrap();
        assert!(seconds > 0.0 && seconds < 60.0, "{what}");
        let cost = num(r, "cost").unwrap();
        assert!(cost > 0.0 && cost < 1.0, "{what}");
        let ratio = num(r, "cost_ratio").unwrap();
        let uvp = num(r, "uvp_exact_percent").unwrap();
        let distance = num(r, "distance_sw2").unwrap();
        match r["solver"].as_str() {
            "exact" => {
                assert_eq!(ratio, 1.0, "{what}");
                assert_eq!(uvp, 0.0, "{what}");
                // A matching pushes the source exactly onto the target samples.
                assert_eq!(distance, 0.0, "{what}");
            }
            "sinkhorn" => {
                // Its default map is a matching too: never cheaper than the optimal one, and close:
                // the auction stops within ε/4 per point of the best matching its support allows,
                // ε the final blur², so the bound grows with blur_spacing (at 2 spacings that ε/4
                // is a full spacing²: 1.3–2.0% above exact on the four shapes at n = 400).
                let limit = if r["settings"].contains("blur_spacing=2") {
                    1.035
                } else {
                    1.02
                };
                assert!((1.0 - 1e-9..limit).contains(&ratio), "{what}");
                assert!(uvp < 5.0, "{what}");
                assert_eq!(distance, 0.0, "{what}");
            }
            "sliced" => {
                // Not a matching: may undercut the optimal matching's cost a little, and leaves a
                // small but nonzero distance to the target samples.
                assert!((0.85..1.2).contains(&ratio), "{what}");
                assert!(uvp > 0.0 && uvp < 30.0, "{what}");
                assert!(distance > 0.0 && distance < 0.02, "{what}");
            }
            other => panic!("unexpected solver {other}"),
        }
        let closed = num(r, "uvp_closed_form_percent");
        if r["case"] == "gaussian" {
            // Even the exact matching of 400 samples is ~1% from the continuous map.
            let closed = closed.unwrap();
            assert!(closed > 0.05 && closed < 10.0, "{what}");
        } else {
            assert_eq!(closed, None, "{what}");
        }
    }

    let png = image::open(dir.join("out/bench.png")).unwrap();
    // 6 panels in 3 columns of 520 × 380, plus a 44-pixel legend strip.
    assert_eq!((png.width(), png.height()), (3 * 520, 2 * 380 + 44));
    let summary = std::fs::read_to_string(dir.join("out/summary.md")).unwrap();
    assert!(summary.starts_with("Load average"), "{summary}");
    assert_eq!(
        summary.lines().filter(|l| l.starts_with("| ")).count(),
        1 + rows.len()
    );
}

#[test]
fn bench_filters_cases_and_solvers_and_rejects_unknown_cases() {
    let dir = scratch("bench-filter");
    let shapes = shared_data().join("shapes");
    let shapes = shapes.to_str().unwrap();
    otbake_ok(
        &dir,
        &[
            "bench",
            "--n",
            "200,300",
            "--cases",
            "blobs,heart",
            "--solvers",
            "sliced",
            "--out",
            "out",
            "--shapes",
            shapes,
        ],
    );
    let csv = std::fs::read_to_string(dir.join("out/bench.csv")).unwrap();
    let rows: Vec<Vec<String>> = csv.lines().skip(1).map(fields).collect();
    // 2 cases × 2 sizes × 2 sliced settings, in case order then size order; the exact reference
    // still runs (cost ratios are filled) but has no row of its own.
    let keys: Vec<(String, String, String)> = rows
        .iter()
        .map(|r| (r[0].clone(), r[1].clone(), r[3].clone()))
        .collect();
    let want: Vec<(String, String, String)> = ["blobs", "heart"]
        .iter()
        .flat_map(|c| ["200", "300"].map(move |n| (c.to_string(), n)))
        .flat_map(|(c, n)| std::iter::repeat_n((c, "sliced".to_string(), n.to_string()), 2))
        .collect();
    assert_eq!(keys, want);
    // A converged run is measured against the reference; one that is not (sliced at 50 iterations
    // may miss its tolerance on so few points) keeps its cost and says why in the error column.
    for r in &rows {
        match r[12].as_str() {
            "true" => assert!(!r[6].is_empty() && r[13].is_empty(), "{csv}"),
            _ => assert!(
                !r[5].is_empty() && r[13].contains("did not converge"),
                "{csv}"
            ),
        }
    }

    let out = otbake(
        &dir,
        &["bench", "--quick", "--cases", "nosuch", "--shapes", shapes],
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown case \"nosuch\"") && err.contains("duck"),
        "{err}"
    );
}
