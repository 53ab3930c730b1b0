//! `cargo xtask stress`: lands with the stress issue.

/// Arguments of the stress runs.
#[derive(clap::Args, Debug)]
pub struct StressArgs {
    /// Output options.
    #[command(flatten)]
    pub out: crate::OutArgs,
    /// Total haptic steps over all runs.
    #[arg(long)]
    pub steps: Option<u64>,
}

/// Runs the stress tests.
pub fn run(_args: &StressArgs) -> anyhow::Result<()> {
    anyhow::bail!("`cargo xtask stress` lands with the stress issue")
}
