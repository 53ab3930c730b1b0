//! `cargo xtask`: the demo, the paper's studies, the benchmarks and the stress runs.
//!
//! Every command writes its machine-readable results as JSON (and plots as SVG) under `--out`
//! (default `target/xtask/<command>`), and prints a readable summary.

mod bench;
#[allow(dead_code)]
mod common;
mod demo;
mod devices;
/// The drifting contact patch xtask's benches share with the crates' tests and benches, compiled
/// from its one source in `haptic-test-support` (a path module rather than a dependency, so that
/// xtask stays packageable while the support crate is not published).
#[path = "../../haptic-test-support/src/contacts.rs"]
mod fixture_contacts;
/// The jaws' pose path, likewise.
#[path = "../../haptic-test-support/src/poses.rs"]
mod fixture_poses;
#[allow(dead_code)]
mod plot;
mod recording;
mod stress;
mod study;
mod view;

use std::path::PathBuf;

use clap::{Parser, Subcommand};

/// Demo, studies and benchmarks of the haptic workspace.
#[derive(Parser, Debug)]
#[command(name = "cargo xtask", arg_required_else_help = true, version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Options shared by the studies and benchmarks.
#[derive(clap::Args, Debug, Clone)]
pub struct OutArgs {
    /// Directory for JSON results and SVG plots.
    #[arg(long, global = true)]
    pub out: Option<PathBuf>,
    /// A shorter run (fewer configurations or samples), for CI and acceptance checks.
    #[arg(long, global = true)]
    pub quick: bool,
}

impl OutArgs {
    /// The output directory, created, defaulting to `target/xtask/<name>`.
    pub fn dir(&self, name: &str) -> anyhow::Result<PathBuf> {
        let dir = self
            .out
            .clone()
            .unwrap_or_else(|| common::repo_root().join("target").join("xtask").join(name));
        std::fs::create_dir_all(&dir)?;
        Ok(dir)
    }
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a simulated device manipulating a tool through the full multirate runtime.
    Demo(demo::DemoArgs),
    /// Reproduce the paper's experiments.
    Study {
        #[command(subcommand)]
        which: study::Study,
    },
    /// Benchmarks: `bench perf` (the default), `bench collision`, `bench realtime`.
    Bench(bench::BenchArgs),
    /// Same as `study work-precision` (the old name, kept).
    #[command(hide = true)]
    WorkPrecision(OutArgs),
    /// Randomized long runs that stress numerical stability and the failure paths.
    Stress(stress::StressArgs),
    /// List the available devices.
    Devices,
    /// Write a recorded run as a self-contained HTML replay page.
    View(view::ViewArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Demo(args) => demo::run(&args),
        Command::Study { which } => study::run(which),
        Command::Bench(args) => bench::run(&args),
        Command::WorkPrecision(args) => study::run(study::Study::WorkPrecision(args)),
        Command::Stress(args) => stress::run(&args),
        Command::Devices => devices::run(),
        Command::View(args) => view::run(&args),
    }
}
