//! `otbake bench --barycenters --quick` end to end: every proxy kind over the whole sweep in the
//! CSV, properties the ground truths guarantee (a blend at a vertex is the input itself; nothing
//! beats the McCann optimum; the barycenter proxy at its weights is within 0.1%), the charts.

use otbake_lab::bench::barycenter::{ACCURACY_HEADER, PROXIES, RESOLUTION_HEADER};
use otbake_tests::{otbake_ok, scratch, shared_data};
use std::collections::HashMap;

fn rows(text: &str, header: &str) -> Vec<HashMap<String, String>> {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(header));
    let keys: Vec<&str> = header.split(',').collect();
    lines
        .map(|l| {
            keys.iter()
                .map(|k| k.to_string())
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

fn num(r: &HashMap<String, String>, k: &str) -> f64 {
    r[k].parse().unwrap_or_else(|_| panic!("{k} = {:?}", r[k]))
}

#[test]
fn quick_barycenter_bench_measures_every_proxy_against_the_truth() {
    let dir = scratch("bench-barycenters");
    let out = dir.join("out");
    otbake_ok(
        &dir,
        &[
            "bench",
            "--barycenters",
            "--quick",
            "--n",
            "120",
            "--resolution-n",
            "400,1600",
            "--shapes",
            shared_data().join("shapes").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let acc = rows(
        &std::fs::read_to_string(out.join("barycenters.csv")).unwrap(),
        ACCURACY_HEADER,
    );
    // 2-way: 2 vertices + 5 interior; 4-way: 4 vertices, 6 edges, the centre, 4 leaning points.
    assert_eq!(acc.len(), PROXIES.len() * (7 + 15));
    for p in PROXIES {
        assert!(acc.iter().any(|r| r["proxy"] == p), "no rows for {p}");
    }
    for r in &acc {
        let gap = num(r, "w2_gap");
        if r["region"] == "vertex" {
            // Exact maps are permutations: at unit weight a blend is the input's samples.
            assert!(gap < 1e-6, "{r:?}");
            assert!(r["excess"].is_empty(), "{r:?}");
        } else {
            let excess = num(r, "excess");
            assert!(excess >= -1e-9, "a blend below the truth: {r:?}");
        }
        if r["build_weights"] == "true" && r["proxy"] == "barycenter" {
            assert!(num(r, "excess") <= 1e-3, "{r:?}");
        }
    }
    let res = rows(
        &std::fs::read_to_string(out.join("resolution.csv")).unwrap(),
        RESOLUTION_HEADER,
    );
    assert_eq!(
        res.len(),
        4,
        "one size against the reference, four resolutions"
    );
    // Coarser grids average more points per pixel: the error falls with the resolution.
    let l1: Vec<f64> = res.iter().map(|r| num(r, "l1")).collect();
    assert!(l1.windows(2).all(|w| w[0] < w[1]), "{l1:?}");
    for f in ["barycenters.png", "resolution.png"] {
        let bytes = std::fs::read(out.join(f)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "{f}");
    }
    let md = std::fs::read_to_string(out.join("barycenters.md")).unwrap();
    assert!(md.contains("4-way") && md.contains("scale s"), "{md}");
}
