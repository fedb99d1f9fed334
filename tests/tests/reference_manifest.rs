//! `manifests/reference.toml`, the manifest reference, is a manifest: it parses, every alternative
//! it offers (a run of `#>` lines) still parses when swapped in, it names every section, key and
//! value the parser takes, and its active part bakes.

use otbake::manifest::{Manifest, ProxySource};
use otbake::proxy::ProxyShape;
use otbake::{bake, BakeOptions, Status};
use otbake_formats::storage::Storage;
use otbake_formats::Wrap;
use otbake_tests::{repo_root, scratch};
use std::collections::BTreeSet;
use std::path::PathBuf;

/// Every key the manifest parser accepts, by section (`input` is `[[input]]`).
const KEYS: &[(&str, &[&str])] = &[
    ("output", &["dir"]),
    (
        "proxy",
        &[
            "kind",
            "samples",
            "seed",
            "sigma",
            "turns",
            "thickness",
            "input",
            "leaf_size",
            "weights",
            "iterations",
        ],
    ),
    (
        "solver",
        &[
            "kind",
            "blur",
            "blur_spacing",
            "scaling",
            "tolerance",
            "max_iterations",
            "truncate",
            "map",
            "auction_eps",
            "max_n",
            "iterations",
            "step",
            "seed",
        ],
    ),
    ("input", &["name", "path", "density", "seed", "wrap"]),
    ("brdf", &["resolution"]),
    ("mesh", &["resolution", "fit", "margin"]),
    ("volume", &["fit"]),
    ("limits", &["memory"]),
    (
        "storage",
        &[
            "preset",
            "positions",
            "node_boxes",
            "colors",
            "node_colors",
            "spacings",
        ],
    ),
];

/// Every value of the parser's enumerated keys: (section, key, values).
const VALUES: &[(&str, &str, &[&str])] = &[
    (
        "proxy",
        "kind",
        &["gaussian", "uniform", "spiral", "input", "barycenter"],
    ),
    ("solver", "kind", &["sinkhorn", "exact", "sliced"]),
    ("solver", "map", &["assignment", "barycentric", "flow"]),
    ("input", "density", &["luminance", "inverted", "alpha"]),
    ("input", "wrap", &["clamp", "periodic"]),
    ("mesh", "fit", &["each", "common"]),
    ("volume", "fit", &["stretch", "pad"]),
    ("storage", "preset", &["full", "compact"]),
    ("storage", "positions", &["f32", "u16", "u8"]),
    ("storage", "node_boxes", &["f32", "u16"]),
    ("storage", "colors", &["f32", "u16", "u8", "none"]),
];

/// Input file extensions, one per input kind (`.jpeg` is only named: it is `.jpg`'s kind).
const EXTENSIONS: &[&str] = &["png", "jpg", "exr", "binary", "brdf", "vol", "obj"];

/// Alternatives whose example file does not ship with the data: they may fail to parse only
/// because the file is missing.
const MISSING_FILE_KINDS: &[&str] = &[".binary", ".exr"];

fn reference() -> (PathBuf, String) {
    let path = repo_root().join("manifests").join("reference.toml");
    let text = std::fs::read_to_string(&path).expect("manifests/reference.toml");
    (path, text)
}

/// The table a header line opens, `[proxy]` → `proxy`, `[[input]]` → `input`; `None` for other lines.
fn header(line: &str) -> Option<&str> {
    let l = line.split('#').next().unwrap_or("").trim();
    l.strip_prefix("[[")
        .and_then(|r| r.strip_suffix("]]"))
        .or_else(|| l.strip_prefix('[').and_then(|r| r.strip_suffix(']')))
}

/// The key and value of a `key = value` line (value without its comment), if it is one.
fn key_value(line: &str) -> Option<(&str, &str)> {
    let (key, rest) = line.split_once(" = ")?;
    let key = key.trim();
    let ok = !key.is_empty() && key.chars().all(|c| c.is_ascii_lowercase() || c == '_');
    let value = rest.split(" #").next().unwrap_or("").trim();
    ok.then_some((key, value.trim_matches('"')))
}

/// An alternative: its first line (1-based), its text with the `#> ` prefixes dropped, and the
/// tables it names.
struct Alternative {
    line: usize,
    text: String,
    tables: BTreeSet<String>,
}

fn uncomment(line: &str) -> Option<&str> {
    line.strip_prefix("#> ").or_else(|| line.strip_prefix("#>"))
}

fn alternatives(text: &str) -> Vec<Alternative> {
    let mut out: Vec<Alternative> = Vec::new();
    let mut open = false;
    for (i, line) in text.lines().enumerate() {
        match uncomment(line) {
            Some(u) => {
                if !open {
                    let first = header(u).unwrap_or_else(|| {
                        panic!(
                            "reference.toml:{}: an alternative starts with a table header",
                            i + 1
                        )
                    });
                    out.push(Alternative {
                        line: i + 1,
                        text: String::new(),
                        tables: BTreeSet::from([first.to_string()]),
                    });
                    open = true;
                }
                let alt = out.last_mut().unwrap();
                if let Some(h) = header(u) {
                    alt.tables.insert(h.to_string());
                }
                alt.text.push_str(u);
                alt.text.push('\n');
            }
            None => open = false,
        }
    }
    out
}

/// The active text without the tables `drop` names (every `[[input]]` for `input`), then `alt`.
fn swapped_in(text: &str, alt: &Alternative) -> String {
    let mut out = String::new();
    let mut current: Option<&str> = None;
    for line in text.lines() {
        if let Some(h) = header(line) {
            current = Some(h);
        }
        if current.is_none_or(|c| !alt.tables.contains(c)) {
            out.push_str(line);
            out.push('\n');
        }
    }
    out + &alt.text
}

/// (section, key, value) of every key line, active or in an alternative.
fn documented(text: &str) -> BTreeSet<(String, String, String)> {
    let mut seen = BTreeSet::new();
    let (mut active, mut alt) = (String::new(), String::new());
    for line in text.lines() {
        let (section, body) = match uncomment(line) {
            Some(u) => {
                if let Some(h) = header(u) {
                    alt = h.to_string();
                }
                (&alt, u)
            }
            None if line.starts_with('#') => continue,
            None => {
                if let Some(h) = header(line) {
                    active = h.to_string();
                }
                (&active, line)
            }
        };
        if let Some((k, v)) = key_value(body) {
            seen.insert((section.clone(), k.to_string(), v.to_string()));
        }
    }
    seen
}

#[test]
fn the_reference_parses_as_the_manifest_it_describes() {
    let (path, _) = reference();
    let m = Manifest::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        m.output_dir.ends_with("out/reference"),
        "{:?}",
        m.output_dir
    );
    assert_eq!(m.proxy.samples, 2000);
    assert_eq!(m.proxy.leaf_size, 8);
    assert!(matches!(
        m.proxy.source,
        ProxySource::Shape(ProxyShape::Gaussian { .. })
    ));
    // The solver's settings are written out at their defaults.
    assert!(
        format!("{:?}", m.solver).starts_with("Sinkhorn"),
        "{:?}",
        m.solver
    );
    let names: Vec<&str> = m.inputs.iter().map(|i| i.name.as_str()).collect();
    assert_eq!(names, ["duck", "leaves", "onyx"]);
    assert_eq!(m.wrap(), Wrap::Clamp);
    assert_eq!(m.storage, Storage::FULL, "[storage] spells out the default");
}

#[test]
fn every_alternative_parses_in_place_of_the_tables_it_names() {
    let (path, text) = reference();
    let active = Manifest::parse(&path, &text).unwrap_or_else(|e| panic!("{e}"));
    let alts = alternatives(&text);
    assert!(alts.len() >= 15, "only {} alternatives", alts.len());
    let mut missing_files = 0;
    for alt in &alts {
        let variant = swapped_in(&text, alt);
        match Manifest::parse(&path, &variant) {
            Ok(m) => assert_ne!(
                m, active,
                "the alternative at reference.toml:{} changes nothing",
                alt.line
            ),
            Err(e) => {
                let named = MISSING_FILE_KINDS.iter().any(|k| e.message.contains(k));
                assert!(
                    e.message.contains("does not exist") && named,
                    "the alternative at reference.toml:{} does not parse: {e}",
                    alt.line
                );
                missing_files += 1;
            }
        }
    }
    assert_eq!(missing_files, MISSING_FILE_KINDS.len());

    // What the alternatives reach: periodic inputs, every solver and proxy kind, 3D inputs.
    let parsed: Vec<Manifest> = alts
        .iter()
        .filter_map(|a| Manifest::parse(&path, &swapped_in(&text, a)).ok())
        .collect();
    assert!(parsed.iter().any(|m| m.wrap() == Wrap::Periodic));
    for kind in ["Exact", "Sliced", "Sinkhorn"] {
        assert!(
            parsed
                .iter()
                .any(|m| format!("{:?}", m.solver).starts_with(kind)),
            "no alternative uses the {kind} solver"
        );
    }
    assert!(parsed
        .iter()
        .any(|m| matches!(m.proxy.source, ProxySource::Input(_))));
    assert!(parsed.iter().any(|m| m.storage == Storage::COMPACT));
    let three_d = |m: &Manifest| {
        m.inputs.iter().all(|i| {
            i.path
                .extension()
                .is_some_and(|e| ["obj", "vol", "brdf"].contains(&e.to_str().unwrap_or("")))
        })
    };
    assert!(parsed.iter().any(|m| m.inputs.len() == 3 && three_d(m)));
}

#[test]
fn every_key_and_value_of_the_parser_is_documented() {
    let (_, text) = reference();
    let seen = documented(&text);
    for (section, keys) in KEYS {
        for key in *keys {
            assert!(
                seen.iter().any(|(s, k, _)| s == section && k == key),
                "reference.toml does not show `{key}` in [{section}]"
            );
        }
    }
    // Nothing else: a key the list lacks is one the parser does not take (or this list is stale).
    for (s, k, _) in &seen {
        let known = KEYS
            .iter()
            .any(|(section, keys)| section == s && keys.contains(&k.as_str()));
        assert!(
            known,
            "reference.toml shows `{k}` in [{s}], which KEYS lacks"
        );
    }
    for (section, key, values) in VALUES {
        for value in *values {
            assert!(
                seen.contains(&(section.to_string(), key.to_string(), value.to_string())),
                "reference.toml does not show {key} = \"{value}\" in [{section}]"
            );
        }
    }
    for ext in EXTENSIONS {
        assert!(
            seen.iter()
                .any(|(s, k, v)| s == "input" && k == "path" && v.ends_with(&format!(".{ext}"))),
            "no input of reference.toml is a .{ext} file"
        );
    }
    assert!(text.contains(".jpeg"), "the .jpeg extension is not named");
    // Key examples live in alternatives, where the test parses them, never in plain comments.
    for (i, line) in text.lines().enumerate() {
        if let Some(rest) = line.strip_prefix('#').filter(|_| !line.starts_with("#>")) {
            assert!(
                key_value(rest.trim_start()).is_none(),
                "reference.toml:{}: a commented-out key; put it in a `#>` alternative",
                i + 1
            );
        }
    }
}

#[test]
fn the_reference_bakes() {
    let (path, _) = reference();
    let mut m = Manifest::load(&path).unwrap_or_else(|e| panic!("{e}"));
    m.output_dir = scratch("reference-manifest");
    let report = bake(&m, &BakeOptions::default()).unwrap();
    let built: Vec<(&str, Status)> = report
        .products
        .iter()
        .map(|p| (p.name.as_str(), p.status))
        .collect();
    assert_eq!(
        built,
        [
            ("proxy", Status::Built),
            ("duck", Status::Built),
            ("leaves", Status::Built),
            ("onyx", Status::Built),
        ],
        "{:?}",
        report.products
    );
    for p in &report.products {
        assert!(p.path.is_file(), "{} was not written", p.path.display());
    }
}
