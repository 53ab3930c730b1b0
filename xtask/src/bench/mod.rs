//! `cargo xtask bench`: the collision benchmark and the performance report.

mod collision;
mod perf;
mod realtime;

/// Arguments of `bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// `collision` for the collision benchmark only, `realtime` for the real-time demo under
    /// load; nothing for the whole report.
    pub which: Option<String>,
    /// Scene of the collision benchmark: `jaws`, `spoon-cup`, or `FILE_A,FILE_B`.
    #[arg(long, default_value = "jaws")]
    pub scene: String,
    /// Unit scale of meshes given by path (metres per file unit).
    #[arg(long)]
    pub scale: Option<f64>,
    /// Output options.
    #[command(flatten)]
    pub out: crate::OutArgs,
}

/// Runs a benchmark.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    match args.which.as_deref() {
        Some("collision") => collision::run(args),
        Some("realtime") => realtime::run(args),
        None | Some("all") => perf::run(args),
        Some(other) => {
            anyhow::bail!("unknown benchmark `{other}`: use `collision`, `realtime` or nothing")
        }
    }
}
