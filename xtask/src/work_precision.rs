//! `cargo xtask work-precision`: lands with the benchmark issue.

/// Runs the work-precision study.
pub fn run(_args: &crate::OutArgs) -> anyhow::Result<()> {
    anyhow::bail!("`cargo xtask work-precision` lands with the benchmark issue")
}
