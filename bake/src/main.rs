//! The `otbake` command line: parses the arguments, runs the command, prints the error chain.

mod cli;

use clap::{CommandFactory, FromArgMatches};
use cli::args::{Cli, Command};
use cli::{bake, bench, brdf, budget, fit, image, volume};

fn main() {
    // Freed solver buffers go back to the system (the peak resident memory of a bake; D147).
    otbake_ot::memory::keep_large_blocks_mapped();
    let matches = Cli::command()
        .mut_arg("memory", |a| a.help(budget::help()))
        .get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    budget::set(cli.memory);
    if let Err(e) = run(cli.command) {
        eprintln!("error: {e}");
        let mut source = e.source();
        while let Some(s) = source {
            // thiserror sources are usually already part of the message; print only new text.
            let text = s.to_string();
            if !e.to_string().contains(&text) {
                eprintln!("  caused by: {text}");
            }
            source = s.source();
        }
        std::process::exit(1);
    }
}

/// Dispatches a parsed command to its family's module.
fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Bake(args) => bake::bake(args),
        Command::BakeOne(args) => bake::bake_one(args),
        Command::Plan(args) => bake::plan(args),
        Command::Pack(args) => bake::pack(args),
        Command::Unpack(args) => bake::unpack(args),
        Command::Blend(args) => image::blend(args),
        Command::Grid(args) => image::grid(args),
        Command::Texture(args) => image::texture(args),
        Command::Fit(args) => fit::fit(args),
        Command::Points(args) => image::points(args),
        Command::BrdfSlice(args) => brdf::slice(args),
        Command::BrdfSpheres(args) => brdf::spheres(args),
        Command::BrdfExport(args) => brdf::export(args),
        Command::Volume(args) => volume::volume(args),
        Command::Render(args) => volume::render(args),
        Command::Slice(args) => volume::slice(args),
        Command::Inspect(args) => bake::inspect(args),
        Command::Bench(args) => bench::bench(args),
    }
}
