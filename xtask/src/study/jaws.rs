//! Study `jaws`: being written.

/// Runs the study.
pub fn run(_args: &crate::OutArgs) -> anyhow::Result<()> {
    anyhow::bail!("study jaws has not landed yet")
}
