//! `cargo xtask demo`: lands with the runtime issue.

/// Arguments of the demo.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Scene: `spoon-cup`, `jaws` or a TOML file.
    #[arg(long, default_value = "spoon-cup")]
    pub scene: String,
    /// Seconds to run.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Integrator: be, newton-be, rk4, fe.
    #[arg(long, default_value = "be")]
    pub integrator: String,
    /// Collision back-end: lod or parry.
    #[arg(long, default_value = "lod")]
    pub backend: String,
    /// Step in simulated time instead of real time.
    #[arg(long)]
    pub virtual_time: bool,
    /// Write the telemetry summary as JSON.
    #[arg(long)]
    pub json: Option<std::path::PathBuf>,
}

/// Runs the demo.
pub fn run(_args: &DemoArgs) -> anyhow::Result<()> {
    println!("The demo needs haptic-runtime, which has not landed yet.");
    Ok(())
}
