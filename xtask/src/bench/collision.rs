//! Benchmark `collision`: being written.

/// Runs the benchmark.
pub fn run(_args: &super::BenchArgs) -> anyhow::Result<()> {
    anyhow::bail!("benchmark collision has not landed yet")
}
