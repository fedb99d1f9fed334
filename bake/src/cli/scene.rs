//! The one way a command opens a manifest: load it, bake what is not current, read its archives.
//!
//! Every command that renders or exports a blend goes through [`Scene::open`], so they all bake
//! alike (the same [`BakeOptions`], the same progress display, the same failure message) and all
//! check `--weights` against the manifest's inputs with the same words.

use super::progress::Progress;
use anyhow::{bail, Result};
use otbake::pipeline::bake::Event;
use otbake::pipeline::remote::RemoteCache;
use otbake::{bake, Archives, BakeOptions, Manifest, Status};
use otbake_runtime::{Map, Proxy};
use std::path::Path;

/// How a bake shows itself.
#[derive(Clone, Copy, Default)]
pub struct Show {
    /// One line per product on stderr (and spinners on a terminal).
    pub lines: bool,
    /// The JSON report on stdout.
    pub json: bool,
}

/// How to bake a manifest on opening it. The default is the render commands': quiet, products
/// rebuilt only when not current, the store in the manifest's output directory.
#[derive(Clone, Copy, Default)]
pub struct Open<'a> {
    /// Rebuild even when archives are current (bypasses the store).
    pub force: bool,
    /// Store directory (default: OUTPUT_DIR/.otbake).
    pub cache_dir: Option<&'a Path>,
    /// A remote cache shared with other machines.
    pub remote: Option<&'a RemoteCache>,
    /// What the bake prints.
    pub show: Show,
}

/// The archives of a manifest whose products are all baked, read into memory.
pub struct Scene {
    /// The proxy and map archives.
    pub archives: Archives,
}

impl Scene {
    /// Loads the manifest at `path` and bakes what is not current (quietly), checks that `weights`
    /// (when the command takes them) has one value per input, then reads the archives.
    pub fn open(path: &Path, weights: Option<&[f32]>) -> Result<Self> {
        let manifest = Self::bake(path, &Open::default())?;
        if let Some(weights) = weights {
            check_weight_count(&manifest, path, weights)?;
        }
        let archives = Archives::load(&manifest)?;
        Ok(Self { archives })
    }

    /// Loads the manifest at `path` and bakes what is not current, without reading the archives.
    /// Fails naming the first failed product (an input's before the proxy's).
    pub fn bake(path: &Path, open: &Open<'_>) -> Result<Manifest> {
        let mut m = Manifest::load(path)?;
        super::budget::apply(&mut m);
        let progress = Progress::new(open.show.lines);
        let on_event = |e: &Event<'_>| progress.event(e);
        let report = bake(
            &m,
            &BakeOptions {
                force: open.force,
                store: open.cache_dir,
                on_event: Some(&on_event),
                remote: open.remote,
            },
        )?;
        progress.finish();
        for w in &report.warnings {
            eprintln!("warning: {}", w.line());
        }
        let remote = open.remote.map(RemoteCache::take_summary);
        if let Some(r) = &remote {
            // What the server did goes to stderr even with --json: a failing cache is news.
            if open.show.lines || !r.notes.is_empty() {
                eprintln!("{}", r.line());
            }
            for note in &r.notes {
                eprintln!("  {note}");
            }
        }
        if open.show.json {
            let mut json = report.to_value();
            if let Some(r) = &remote {
                json["remote"] = r.to_value();
            }
            println!("{json}");
        }
        let failed: Vec<_> = report
            .products
            .iter()
            .filter(|p| p.status == Status::Failed)
            .collect();
        // Name an input's failure first: a proxy skipped because every input failed is a consequence.
        if let Some(first) = failed.iter().find(|p| p.name != "proxy").or(failed.first()) {
            bail!(
                "{} of {} products failed; first: {}: {}",
                failed.len(),
                report.products.len(),
                first.name,
                first.detail
            );
        }
        Ok(m)
    }

    /// The proxy archive, opened (validated).
    pub fn proxy(&self) -> Result<Proxy<'_>> {
        Ok(self.archives.proxy()?)
    }

    /// Every map archive, opened (validated), in manifest order.
    pub fn maps(&self) -> Result<Vec<Map<'_>>> {
        Ok(self.archives.maps()?)
    }
}

/// One weight per input, or an error naming the inputs.
fn check_weight_count(m: &Manifest, manifest: &Path, weights: &[f32]) -> Result<()> {
    if weights.len() != m.inputs.len() {
        bail!(
            "--weights has {} values but {} has {} inputs ({}): give one weight per input",
            weights.len(),
            manifest.display(),
            m.inputs.len(),
            input_names(m)
        );
    }
    for (i, (&w, input)) in weights.iter().zip(&m.inputs).enumerate() {
        if !(w.is_finite() && w >= 0.0) {
            let what = if w.is_nan() {
                "not a number"
            } else if w < 0.0 {
                "negative"
            } else {
                "infinite"
            };
            bail!(
                "--weights: value {w} (position {}, for input {:?}) is {what}: every weight must be a finite number >= 0",
                i + 1,
                input.name
            );
        }
    }
    Ok(())
}

/// The manifest's input names, comma-separated, for messages that list the choices.
pub fn input_names(m: &Manifest) -> String {
    m.inputs
        .iter()
        .map(|i| i.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}
