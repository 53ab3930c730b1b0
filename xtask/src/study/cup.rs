//! Study `cup`: being written.

/// Runs the study.
pub fn run(_args: &crate::OutArgs) -> anyhow::Result<()> {
    anyhow::bail!("study cup has not landed yet")
}
