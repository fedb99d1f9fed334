//! Baking and archive handling: `bake`, `bake-one`, `plan`, `pack`, `unpack`, `inspect`.

use super::scene::{Open, Scene, Show};
use anyhow::{bail, Context, Result};
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake_one as bake_product, Action};
use otbake::pipeline::inspect::{describe, validate};
use otbake::pipeline::plan::{render as render_plan, Format};
use std::path::PathBuf;

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
}

/// `otbake bake`: each manifest in turn, stopping at the first that fails.
pub fn bake(args: BakeArgs) -> Result<()> {
    let open = Open {
        force: args.force,
        cache_dir: args.cache_dir.as_deref(),
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
    let mut m = Manifest::load(&args.manifest)?;
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
}

/// `otbake plan`: the bake as a build graph on stdout.
pub fn plan(args: PlanArgs) -> Result<()> {
    let m = Manifest::load(&args.manifest)?;
    let exe = std::env::current_exe().context("cannot locate the otbake executable")?;
    print!("{}", render_plan(&m, &exe, args.format)?);
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
