//! Benchmark `perf`: being written.

/// Runs the benchmark.
pub fn run(_args: &super::BenchArgs) -> anyhow::Result<()> {
    anyhow::bail!("benchmark perf has not landed yet")
}
