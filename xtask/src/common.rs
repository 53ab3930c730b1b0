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

/// Where xtask keeps the LOD hierarchies it built (`target/lod-cache`), so that a second demo,
/// study or benchmark on the same meshes reads them back instead of building them again.
pub fn lod_cache_dir() -> PathBuf {
    repo_root().join("target").join("lod-cache")
}

/// `LodBackend::with_cache` in [`lod_cache_dir`], saying what it did.
pub fn lod_backend(
    tool: &haptic_collision::TriMesh,
    obstacles: &[(haptic_collision::TriMesh, haptic_core::Pose)],
) -> anyhow::Result<haptic_collision::LodBackend> {
    use haptic_collision::lod::CacheOutcome;
    let started = std::time::Instant::now();
    let (backend, outcomes) =
        haptic_collision::LodBackend::with_cache(tool, obstacles, &lod_cache_dir())?;
    let loaded = outcomes
        .iter()
        .filter(|o| matches!(o, CacheOutcome::Loaded(_)))
        .count();
    for o in &outcomes {
        match o {
            CacheOutcome::Rebuilt(path, why) => {
                eprintln!("note: rebuilt the hierarchy of {} ({why})", path.display());
            }
            CacheOutcome::NotSaved(path, why) => {
                eprintln!("note: could not save {} ({why})", path.display());
            }
            _ => {}
        }
    }
    println!(
        "LOD hierarchies ready in {:.2} s ({loaded} of {} read back from {})",
        started.elapsed().as_secs_f64(),
        outcomes.len(),
        lod_cache_dir().display()
    );
    Ok(backend)
}

/// What loading changed in a mesh, for a person to read (`None` when it changed nothing):
/// degenerate and repeated triangles dropped, triangles wound against their neighbours turned.
pub fn mesh_repairs(report: &haptic_collision::LoadReport) -> Option<String> {
    let plural = |n: usize| if n == 1 { "" } else { "s" };
    let mut parts = Vec::new();
    if report.degenerate_dropped > 0 {
        let n = report.degenerate_dropped;
        parts.push(format!("{n} degenerate triangle{} dropped", plural(n)));
    }
    if report.duplicates_dropped > 0 {
        let n = report.duplicates_dropped;
        parts.push(format!("{n} repeated triangle{} dropped", plural(n)));
    }
    if report.triangles_rewound > 0 {
        let n = report.triangles_rewound;
        parts.push(format!(
            "{n} triangle{} wound against {} neighbours turned back",
            plural(n),
            if n == 1 { "its" } else { "their" }
        ));
    }
    (!parts.is_empty()).then(|| parts.join(", "))
}
