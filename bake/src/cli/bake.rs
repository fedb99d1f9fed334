//! Baking and archive handling: `bake`, `bake-one`, `plan`, `pack`, `unpack`, `inspect`.

use super::scene::{Open, Scene, Show};
use anyhow::{bail, Context, Result};
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake_one as bake_product, Action};
use otbake::pipeline::bazel::{BazelLabels, DEFAULT_OTBAKE, DEFAULT_RULES};
use otbake::pipeline::inspect::{describe, validate};
use otbake::pipeline::plan::{render as render_plan, Format, PlanOptions};
use otbake::pipeline::remote::{RemoteCache, RemoteConfig, DEFAULT_TIMEOUT_SECS};
use std::path::PathBuf;
use std::time::Duration;

#[derive(clap::Args)]
pub struct BakeArgs {
    /// Manifest files.
    #[arg(required = true)]
    manifests: Vec<PathBuf>,
    /// Rebuild even when archives are current (bypasses the store).
    #[arg(long)]
    force: bool,
    /// Print the report as JSON on stdout (one object per manifest, one per line).
    #[arg(long)]
    json: bool,
    /// Store directory shared between bakes (default: OUTPUT_DIR/.otbake).
    #[arg(long, env = "OTBAKE_CACHE_DIR")]
    cache_dir: Option<PathBuf>,
    /// A Bazel HTTP cache (http://HOST:PORT/) shared with other machines: products missing here
    /// are fetched from it (verified), products baked here are uploaded. A server that is down,
    /// slow or failing never fails the bake.
    #[arg(long, env = "OTBAKE_REMOTE_CACHE", value_name = "URL")]
    remote_cache: Option<String>,
    /// Seconds before a request to the remote cache gives up (and the cache is off for the bake).
    #[arg(long, value_name = "SECONDS", default_value_t = DEFAULT_TIMEOUT_SECS, value_parser = clap::value_parser!(u64).range(1..))]
    remote_timeout: u64,
    /// Read the remote cache only: upload nothing.
    #[arg(long)]
    remote_no_upload: bool,
}

/// `otbake bake`: each manifest in turn, stopping at the first that fails.
pub fn bake(args: BakeArgs) -> Result<()> {
    // An empty OTBAKE_REMOTE_CACHE means none, as unset.
    let remote = match args.remote_cache.as_deref().filter(|u| !u.is_empty()) {
        Some(url) => Some(RemoteCache::new(
            url,
            RemoteConfig {
                timeout: Duration::from_secs(args.remote_timeout),
                upload: !args.remote_no_upload,
            },
        )?),
        None => None,
    };
    let open = Open {
        force: args.force,
        cache_dir: args.cache_dir.as_deref(),
        remote: remote.as_ref(),
        show: Show {
            lines: !args.json,
            json: args.json,
        },
    };
    for m in &args.manifests {
        Scene::bake(m, &open)?;
    }
    Ok(())
}

#[derive(clap::Args)]
pub struct BakeOneArgs {
    /// Manifest file.
    manifest: PathBuf,
    /// `proxy`, or the name of an input.
    #[arg(long)]
    product: String,
    /// The proxy archive (required for maps).
    #[arg(long)]
    proxy: Option<PathBuf>,
    /// Output archive.
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake bake-one`: one product, hermetically.
pub fn bake_one(args: BakeOneArgs) -> Result<()> {
    // Only this product's files need exist: a sandbox shows an action its declared inputs only.
    let mut m = Manifest::load_for_product(&args.manifest, &args.product)?;
    super::budget::apply(&mut m);
    let product = &args.product;
    let action = if product == "proxy" {
        Action::Proxy
    } else {
        let Some(proxy) = args.proxy.as_deref() else {
            bail!("--product {product:?} is a map: give the proxy archive with --proxy PATH");
        };
        Action::Map {
            name: product,
            proxy,
        }
    };
    bake_product(&m, &action, &args.output)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct PlanArgs {
    /// Manifest file.
    manifest: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Ninja)]
    format: Format,
    /// Bazel: the label of the otbake binary the actions run (a file target or any executable).
    #[arg(long, default_value = DEFAULT_OTBAKE)]
    bazel_otbake: String,
    /// Bazel: the label of the rules file (`bake/bazel/otbake.bzl`).
    #[arg(long, default_value = DEFAULT_RULES)]
    bazel_rules: String,
}

/// `otbake plan`: the bake as a build graph on stdout.
pub fn plan(args: PlanArgs) -> Result<()> {
    let m = Manifest::load(&args.manifest)?;
    let exe = std::env::current_exe().context("cannot locate the otbake executable")?;
    let opts = PlanOptions {
        otbake: &exe,
        format: args.format,
        bazel: BazelLabels {
            rules: args.bazel_rules,
            otbake: args.bazel_otbake,
        },
    };
    print!("{}", render_plan(&m, &opts)?);
    Ok(())
}

#[derive(clap::Args)]
pub struct PackArgs {
    /// Archive (.otb).
    archive: PathBuf,
    /// Output (default: ARCHIVE.zst).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// zstd level (1-22).
    #[arg(long, default_value_t = 19)]
    level: i32,
}

/// `otbake pack`: validate, then compress.
pub fn pack(args: PackArgs) -> Result<()> {
    let archive = &args.archive;
    let bytes =
        std::fs::read(archive).with_context(|| format!("cannot read {}", archive.display()))?;
    validate(&bytes).with_context(|| format!("{} is not a valid archive", archive.display()))?;
    let packed = zstd::bulk::compress(&bytes, args.level).context("zstd compression failed")?;
    let out = args
        .output
        .unwrap_or_else(|| PathBuf::from(format!("{}.zst", archive.display())));
    otbake::fsio::write_atomic(&out, &packed)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct UnpackArgs {
    /// Packed archive (.otb.zst).
    packed: PathBuf,
    /// Output archive.
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake unpack`: decompress, then validate before writing.
pub fn unpack(args: UnpackArgs) -> Result<()> {
    let packed = &args.packed;
    let bytes =
        std::fs::read(packed).with_context(|| format!("cannot read {}", packed.display()))?;
    let raw = zstd::stream::decode_all(&bytes[..])
        .with_context(|| format!("{} is not zstd data", packed.display()))?;
    validate(&raw)
        .with_context(|| format!("{} does not hold a valid archive", packed.display()))?;
    otbake::fsio::write_atomic(&args.output, &raw)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct InspectArgs {
    /// Archive file (.otb).
    archive: PathBuf,
}

/// `otbake inspect`: the description on stdout, then the validation's verdict.
pub fn inspect(args: InspectArgs) -> Result<()> {
    let archive = &args.archive;
    let bytes =
        std::fs::read(archive).with_context(|| format!("cannot read {}", archive.display()))?;
    print!("{}", describe(&bytes));
    validate(&bytes).with_context(|| format!("{} is not a valid archive", archive.display()))?;
    Ok(())
}
