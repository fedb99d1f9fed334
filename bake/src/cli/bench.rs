//! `otbake bench`: a thin front of the solver bench in [`otbake::bench`].

use anyhow::{bail, Context, Result};
use otbake::bench::{BarycenterOptions, BenchOptions, SolverKind, TerminalProgress};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Small n and a reduced sweep (seconds; for CI and tests).
    #[arg(long)]
    quick: bool,
    /// Sizes for every case, e.g. 1000,5000 (default: 1000,5000, plus 50000,250000 for
    /// gaussian; exact runs only up to 10000).
    #[arg(long, value_delimiter = ',')]
    n: Option<Vec<usize>>,
    /// Cases: gaussian, blobs, shapes (all shapes) or shape names, e.g. gaussian,duck.
    #[arg(long, value_delimiter = ',')]
    cases: Option<Vec<String>>,
    /// Solvers, e.g. exact,sinkhorn (default: all).
    #[arg(long, value_delimiter = ',', value_enum)]
    solvers: Option<Vec<SolverKind>>,
    /// Directory of the shape PNGs.
    #[arg(long, default_value = "../shared/data/shapes")]
    shapes: PathBuf,
    /// Output directory.
    #[arg(long, default_value = "out/bench")]
    out: PathBuf,
    /// Instead of the solvers: proxy blends against true barycenters of the shapes for every proxy
    /// kind over a sweep of weights (exact maps, n = --n or 1000), and a rendered blend's error
    /// against n (Sinkhorn): barycenters.csv, barycenters.png, resolution.csv, resolution.png,
    /// barycenters.md.
    #[arg(long)]
    barycenters: bool,
    /// With --barycenters: sizes of the resolution sweep, the last the reference (default
    /// 2000,8000,32000,128000,512000; one value skips the sweep).
    #[arg(long, value_delimiter = ',')]
    resolution_n: Option<Vec<usize>>,
}

/// Runs the bench with a terminal progress display, then names the files it wrote on stderr.
pub fn bench(args: BenchArgs) -> Result<()> {
    if args.barycenters {
        return barycenters(args);
    }
    let options = BenchOptions {
        quick: args.quick,
        ns: args.n,
        cases: args.cases,
        solvers: args.solvers,
        shapes_dir: args.shapes,
        out: args.out,
    };
    let mut progress = TerminalProgress::new();
    let result = otbake::bench::run(&options, &mut |e| progress.event(e));
    progress.finish();
    let report = result?;
    let failed = report.rows.iter().filter(|r| !r.converged).count();
    eprintln!(
        "{} runs ({failed} not converged or failed): {}, {}, {}",
        report.rows.len(),
        report.csv.display(),
        report.chart.display(),
        report.summary.display()
    );
    Ok(())
}

/// `otbake bench --barycenters`: the shapes of --shapes, sorted by name.
fn barycenters(args: BenchArgs) -> Result<()> {
    let mut shapes: Vec<(String, PathBuf)> = std::fs::read_dir(&args.shapes)
        .with_context(|| format!("listing shapes in {}", args.shapes.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .filter_map(|p| Some((p.file_stem()?.to_str()?.to_string(), p)))
        .collect();
    shapes.sort();
    if let Some(cases) = &args.cases {
        shapes.retain(|(name, _)| cases.contains(name));
    }
    if shapes.len() < 2 {
        bail!(
            "--barycenters needs at least two shape PNGs in {} (or in --cases): pass --shapes DIR",
            args.shapes.display()
        );
    }
    let n = match args.n.as_deref() {
        None => None,
        Some([n]) => Some(*n),
        Some(_) => bail!("--n: --barycenters takes one size (the accuracy sweep's n)"),
    };
    let options = BarycenterOptions {
        quick: args.quick,
        n,
        resolution_ns: args.resolution_n,
        shapes,
        out: args.out,
    };
    let report = otbake::bench::run_barycenters(&options, &mut |line| eprintln!("{line}"))?;
    eprintln!(
        "{} accuracy rows, {} resolution rows: {}",
        report.accuracy.len(),
        report.resolution.len(),
        report
            .files
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
