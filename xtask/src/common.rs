//! Paths and output helpers shared by the xtask commands.

use std::path::{Path, PathBuf};

/// The workspace root (the directory holding the top-level `Cargo.toml`).
///
/// Taken from the `CARGO_MANIFEST_DIR` that `cargo run` (and so `cargo xtask`) sets when the
/// command runs, and only failing that from the one it was compiled with: two checkouts that
/// share a target directory share the one `target/release/xtask`, which must serve the checkout
/// it is run from.
pub fn repo_root() -> PathBuf {
    let manifest_dir = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    manifest_dir
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// The repository's meshes, `assets/meshes` under the repository root (licences in its
/// `SOURCES.md`).
pub fn meshes_dir() -> PathBuf {
    repo_root().join("assets").join("meshes")
}

/// Writes any serializable report as pretty JSON, and says so.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(value)?)?;
    println!("wrote {}", path.display());
    Ok(())
}
