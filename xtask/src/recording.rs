//! Recording headers for the demo and the studies: the meshes by path and content hash, and the
//! run's settings in words (see `haptic_runtime::recording`).

use std::path::Path;

use haptic_core::{Pose, Real, Vec3};
use haptic_runtime::Scene;
use haptic_runtime::recording::{
    DEFAULT_CONTACT_CAP, FORMAT, MeshRecord, RecordingHeader, VERSION, content_hash, pose_array,
};

/// A mesh file by path, with its content hash.
pub fn mesh_record(
    role: &str,
    path: &Path,
    scale_m_per_unit: Real,
    placement: [Real; 7],
) -> anyhow::Result<MeshRecord> {
    let bytes = std::fs::read(path)
        .map_err(|e| anyhow::anyhow!("reading {} for the recording: {e}", path.display()))?;
    let path = path.canonicalize().unwrap_or_else(|_| path.to_owned());
    Ok(MeshRecord {
        role: role.to_owned(),
        path,
        scale_m_per_unit,
        content_hash: content_hash(&bytes),
        placement,
    })
}

/// The tool's placement: its mesh-to-body offset (m) in the first three numbers.
pub fn tool_placement(offset_m: &Vec3) -> [Real; 7] {
    [offset_m.x, offset_m.y, offset_m.z, 1.0, 0.0, 0.0, 0.0]
}

/// The header of a recording of `scene`.
pub fn header_for_scene(
    scene: &Scene,
    tool_offset_m: &Vec3,
    settings: Vec<(String, String)>,
    haptic_rate_hz: Real,
    frame_rate_hz: Real,
) -> anyhow::Result<RecordingHeader> {
    let mut meshes = vec![mesh_record(
        "tool",
        &scene.tool.mesh,
        scene.tool.scale_m_per_unit,
        tool_placement(tool_offset_m),
    )?];
    for o in &scene.obstacles {
        meshes.push(mesh_record(
            "obstacle",
            &o.mesh,
            o.scale_m_per_unit,
            pose_array(&o.pose.pose()),
        )?);
    }
    Ok(header(
        &scene.name,
        settings,
        meshes,
        haptic_rate_hz,
        frame_rate_hz,
    ))
}

/// A header from its parts.
pub fn header(
    name: &str,
    settings: Vec<(String, String)>,
    meshes: Vec<MeshRecord>,
    haptic_rate_hz: Real,
    frame_rate_hz: Real,
) -> RecordingHeader {
    RecordingHeader {
        format: FORMAT.to_owned(),
        version: VERSION,
        name: name.to_owned(),
        settings,
        meshes,
        haptic_rate_hz,
        frame_rate_hz: frame_rate_hz.min(haptic_rate_hz),
        contact_cap: DEFAULT_CONTACT_CAP,
    }
}

/// An obstacle's placement.
pub fn obstacle_placement(pose: &Pose) -> [Real; 7] {
    pose_array(pose)
}

/// Ends `recorder` with the run's summary whatever the outcome: a failed run's recording ends
/// with the summary of the run up to the failure (when the error carries one), so that it reads
/// back and can be viewed. Returns the run's outcome, or the recording's write error.
pub fn finish_recording<W: std::io::Write>(
    outcome: Result<haptic_runtime::Summary, haptic_runtime::RuntimeError>,
    recorder: haptic_runtime::RunRecorder<W>,
    path: &Path,
) -> anyhow::Result<haptic_runtime::Summary> {
    match outcome {
        Ok(summary) => {
            recorder
                .finish(&summary)
                .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
            Ok(summary)
        }
        Err(e) => {
            if let Some(summary) = e.summary() {
                // The run's error is what the user needs; a write error here would hide it.
                if let Err(w) = recorder.finish(summary) {
                    eprintln!(
                        "warning: the recording {} is incomplete: {w}",
                        path.display()
                    );
                }
            }
            Err(e.into())
        }
    }
}
