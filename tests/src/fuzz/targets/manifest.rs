//! The `manifest` target: TOML text → [`Manifest`], every section's validation included.
//!
//! Seeds are the repository's manifests (their input paths renamed to the empty files this target
//! makes next to the manifest, since parsing checks that input files exist) and hand-made edge
//! cases. Mutations are text-level, with a dictionary of every key, table header and alternative
//! line (`#> ` lines without their prefix) the seeds hold, so mutated manifests keep reaching the
//! validators instead of stopping at the TOML syntax.

use crate::fuzz::{mutate, Case, Rng, Scratch, Target};
use otbake::Manifest;
use std::sync::{Mutex, OnceLock};

/// Input files the corpus manifests name (empty: parsing only checks that they exist).
pub const INPUT_FILES: [&str; 9] = [
    "a.png", "b.png", "c.jpg", "d.exr", "e.vol", "f.obj", "g.obj", "h.brdf", "i.binary",
];

/// Longest mutated manifest.
const MAX_LEN: usize = 32 << 10;

/// See the module docs.
#[derive(Default)]
pub struct ManifestTarget {
    dict: OnceLock<Vec<String>>,
    prepared: Mutex<Option<std::path::PathBuf>>,
}

fn dictionary(seeds: &[Case]) -> Vec<String> {
    let mut words = std::collections::BTreeSet::new();
    for case in seeds {
        for line in String::from_utf8_lossy(case.bytes()).lines() {
            let line = line.trim();
            let body = line.strip_prefix("#> ").unwrap_or(line);
            let body = body.split("  #").next().unwrap_or("").trim();
            if body.is_empty() || body.starts_with('#') {
                continue;
            }
            words.insert(body.to_string());
            if let Some((key, value)) = body.split_once('=') {
                words.insert(key.trim().to_string());
                words.insert(value.trim().to_string());
            }
        }
    }
    words.extend(INPUT_FILES.iter().map(|f| format!("\"{f}\"")));
    words.into_iter().collect()
}

impl Target for ManifestTarget {
    fn name(&self) -> &'static str {
        "manifest"
    }

    fn seeds(&self, corpus: &std::path::Path) -> Vec<Case> {
        let seeds = crate::fuzz::files_of(&corpus.join(self.name()));
        let _ = self.dict.set(dictionary(&seeds));
        seeds
    }

    fn mutate(&self, rng: &mut Rng, case: &mut Case, other: &Case) {
        let dict = self
            .dict
            .get_or_init(|| dictionary(std::slice::from_ref(other)));
        for _ in 0..1 + rng.below(3) {
            mutate::text(rng, case.bytes_mut(), other.bytes(), dict, MAX_LEN);
        }
    }

    fn execute(&self, rng: &mut Rng, case: &Case, scratch: &Scratch) -> bool {
        {
            let mut prepared = self.prepared.lock().unwrap();
            if prepared.as_deref() != Some(scratch.dir()) {
                for f in INPUT_FILES {
                    scratch.write(f, b"");
                }
                *prepared = Some(scratch.dir().to_path_buf());
            }
        }
        let text = String::from_utf8_lossy(case.bytes());
        let path = scratch.dir().join("m.toml");
        let parsed = if rng.one_in(8) {
            // A build action's view: only one product's input file must exist.
            scratch.write("m.toml", text.as_bytes());
            let product = ["proxy", "duck", "a", "x"][rng.below(4)];
            Manifest::load_for_product(&path, product)
        } else {
            Manifest::parse(&path, &text)
        };
        match parsed {
            Ok(m) => {
                // What a bake asks of a manifest first.
                let _ = (m.proxy_archive(), m.wrap(), m.budget());
                for i in &m.inputs {
                    let _ = (m.map_archive(&i.name), m.input_index(&i.name));
                }
                true
            }
            Err(e) => {
                // Errors name the file and a place in it.
                let msg = e.to_string();
                assert!(
                    msg.contains("m.toml"),
                    "a manifest error without the file: {msg}"
                );
                false
            }
        }
    }
}
