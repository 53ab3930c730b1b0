//! Study `free_space`: being written.

/// Runs the study.
pub fn run(_args: &crate::OutArgs) -> anyhow::Result<()> {
    anyhow::bail!("study free_space has not landed yet")
}
