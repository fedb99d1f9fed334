//! `otbake bench`: a thin front of the solver bench in [`otbake::bench`].

use anyhow::Result;
use otbake::bench::{BenchOptions, SolverKind, TerminalProgress};
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
}

/// Runs the bench with a terminal progress display, then names the files it wrote on stderr.
pub fn bench(args: BenchArgs) -> Result<()> {
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
