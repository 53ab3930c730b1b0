//! `cargo xtask bench …`: the performance report (the default), the collision back-ends, and the
//! real-time demo under load.

mod chart;
mod collision;
mod perf;
mod realtime;
mod shapes;
mod suite;
mod wrench;

use haptic_collision::StoppingRule;

use crate::OutArgs;

/// Arguments of `bench`: a benchmark (the performance report when none is named) and where to
/// write.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Which benchmark; the performance report when none is named.
    #[command(subcommand)]
    pub which: Option<Bench>,
    /// Output options (also accepted after the benchmark's name).
    #[command(flatten)]
    pub out: OutArgs,
}

/// The benchmarks.
#[derive(clap::Subcommand, Debug)]
pub enum Bench {
    /// The performance report (`perf.json`): haptic step, clustering, collision and build times.
    Perf,
    /// Collision back-ends, run time against error (`collision.json`).
    Collision(CollisionArgs),
    /// The real-time demo at 1 and 10 kHz, idle and under load (`realtime.json`).
    Realtime,
}

/// Arguments of `bench collision`.
#[derive(clap::Args, Debug, Clone)]
pub struct CollisionArgs {
    /// Scene: `jaws`, `spoon-cup`, or `FILE_A,FILE_B` (tool, obstacle).
    #[arg(long, default_value = "jaws")]
    pub scene: String,
    /// Unit scale of meshes given by path (metres per file unit).
    #[arg(long)]
    pub scale: Option<f64>,
    /// The penalty's reach `δ` (mm) for a `FILE_A,FILE_B` scene; by default 1 % of the tool's
    /// diagonal.
    #[arg(long, conflicts_with = "suite")]
    pub delta_mm: Option<f64>,
    /// Every scene of the generalization suite (`suite.json`), instead of one scene.
    #[arg(long)]
    pub suite: bool,
    /// With `--suite`: only these scenes of the suite, by name (comma-separated), e.g.
    /// `--only boxes-coarse,fork-in-mug`. The worst figures are then over those scenes only.
    #[arg(long, value_delimiter = ',', requires = "suite")]
    pub only: Option<Vec<String>>,
    /// The LOD walk's stopping rule: `coherence-budget` (the default: the pieces' normal
    /// coherence held for the regions' sum against the net force), `deviation` (the paper's) or
    /// `coherence` (that coherence wherever a pair writes a contact).
    #[arg(long, default_value = "coherence-budget")]
    pub stopping_rule: StoppingRule,
}

/// Runs a benchmark.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    match &args.which {
        None | Some(Bench::Perf) => perf::run(&args.out),
        Some(Bench::Collision(c)) => collision::run(c, &args.out),
        Some(Bench::Realtime) => realtime::run(&args.out),
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Parser)]
    struct Cmd {
        #[command(flatten)]
        collision: CollisionArgs,
    }

    #[test]
    fn stopping_rule_is_the_default_unless_asked() {
        let rule = |args: &[&str]| {
            Cmd::try_parse_from(std::iter::once("collision").chain(args.iter().copied()))
                .map(|c| c.collision.stopping_rule)
        };
        assert_eq!(rule(&[]).unwrap(), StoppingRule::default());
        assert_eq!(
            rule(&["--stopping-rule", "deviation"]).unwrap(),
            StoppingRule::Deviation
        );
        assert_eq!(
            rule(&["--stopping-rule", "coherence"]).unwrap(),
            StoppingRule::DeviationAndCoherence
        );
        assert!(rule(&["--stopping-rule", "normals"]).is_err());
    }
}
