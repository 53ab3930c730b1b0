//! `cargo xtask view RECORDING [--out FILE.html]`: a recorded run (`cargo xtask demo
//! --virtual-time --record FILE`, or a study's) as one self-contained HTML page that works
//! offline, from a file, with no server.
//!
//! The page embeds three.js 0.170.0 (vendored in `xtask/vendor/`, MIT) as data: URLs of an
//! import map, the meshes (positions as little-endian `f32`, indices as `u32`, base64) and the
//! frames and contact updates as JSON. It shows the tool, the obstacles and the device's ghost
//! pose with an orbit camera; a time slider with play and pause at real speed and slowed down;
//! toggles for the raw contacts, the cluster representatives (sized by depth), the force and
//! torque arrows and the coupling spring; plots of force, deviation, penetration, contact rate and
//! query time whose cursor follows the slider (a click moves it); and the run's summary. When
//! drawn, it times the drawing of 30 frames, prints the figures and sets its title to
//! `ready: …` (the browser check waits for that).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use haptic_collision::{LoadOptions, TriMesh};
use haptic_core::Vec3;
use haptic_runtime::recording::{RunRecording, content_hash};
use serde::Serialize;

const THREE: &str = include_str!("../../vendor/three-0.170.0/three.module.min.js");
const ORBIT: &str = include_str!("../../vendor/three-0.170.0/OrbitControls.js");
const PAGE: &str = include_str!("page.html");

/// Arguments of `view`.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// The recording.
    pub recording: PathBuf,
    /// The page to write (default: the recording's path with `.html`).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// A mesh as the page draws it.
#[derive(Serialize)]
struct PageMesh {
    role: String,
    placement: [f64; 7],
    positions: String,
    indices: String,
}

/// The frames, one array per quantity (flattened vectors).
#[derive(Serialize, Default)]
struct PageFrames {
    t: Vec<f32>,
    tool: Vec<f32>,
    device: Vec<f32>,
    grasp: Vec<f32>,
    force: Vec<f32>,
    torque: Vec<f32>,
    f: Vec<f32>,
    tq: Vec<f32>,
    dev: Vec<f32>,
}

/// A contact update as the page draws it: contacts flattened `[p, n, d]`.
#[derive(Serialize)]
struct PageUpdate {
    t: f32,
    at: f32,
    q: f32,
    n: usize,
    pen: f32,
    raw: Vec<f32>,
    reps: Vec<f32>,
}

/// Everything the page shows.
#[derive(Serialize)]
struct PageData<'a> {
    name: &'a str,
    settings: &'a [(String, String)],
    summary: &'a haptic_runtime::Summary,
    meshes: Vec<PageMesh>,
    frames: PageFrames,
    updates: Vec<PageUpdate>,
    contact_cap: usize,
    frame_rate_hz: f64,
}

/// Standard base64 (RFC 4648) of `bytes`.
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(A[((n >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn flat(values: impl IntoIterator<Item = f64>) -> Vec<f32> {
    values.into_iter().map(|v| v as f32).collect()
}

/// Loads a recorded mesh, checking that the file is the one recorded.
fn page_mesh(m: &haptic_runtime::recording::MeshRecord) -> anyhow::Result<PageMesh> {
    let bytes = std::fs::read(&m.path)
        .with_context(|| format!("the recording's mesh {}", m.path.display()))?;
    let hash = content_hash(&bytes);
    if hash != m.content_hash {
        bail!(
            "the mesh {} has changed since the run was recorded (content hash {hash}, recorded {})",
            m.path.display(),
            m.content_hash
        );
    }
    let (mut mesh, _) = TriMesh::load(&m.path, &LoadOptions::with_scale(m.scale_m_per_unit))?;
    if m.role == "tool" {
        mesh = mesh.translated(&Vec3::new(m.placement[0], m.placement[1], m.placement[2]))?;
    }
    let positions: Vec<u8> = mesh
        .vertices()
        .iter()
        .flat_map(|v| [v.x as f32, v.y as f32, v.z as f32])
        .flat_map(f32::to_le_bytes)
        .collect();
    let indices: Vec<u8> = mesh
        .triangles()
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    Ok(PageMesh {
        role: m.role.clone(),
        placement: m.placement,
        positions: base64(&positions),
        indices: base64(&indices),
    })
}

/// Writes the page of `recording` to `out`; returns its size in bytes.
pub fn write_page(recording: &Path, out: &Path) -> anyhow::Result<usize> {
    let r = RunRecording::read(recording)
        .with_context(|| format!("reading {}", recording.display()))?;
    let meshes = r
        .header
        .meshes
        .iter()
        .map(page_mesh)
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut frames = PageFrames::default();
    for f in &r.frames {
        frames.t.push(f.t as f32);
        frames.tool.extend(flat(f.tool));
        frames.device.extend(flat(f.device));
        frames.grasp.extend(flat(f.grasp_m));
        frames.force.extend(flat(f.force_n));
        frames.torque.extend(flat(f.torque_nm));
        frames.f.push(Vec3::from(f.force_n).norm() as f32);
        frames.tq.push(Vec3::from(f.torque_nm).norm() as f32);
        frames.dev.push(f.deviation_m as f32);
    }
    let contacts = |cs: &[haptic_runtime::recording::ContactRecord]| -> Vec<f32> {
        cs.iter()
            .flat_map(|c| flat([c.p[0], c.p[1], c.p[2], c.n[0], c.n[1], c.n[2], c.d]))
            .collect()
    };
    let updates = r
        .updates
        .iter()
        .map(|u| PageUpdate {
            t: u.t as f32,
            at: u.available_t as f32,
            q: u.query_time_s as f32,
            n: u.raw_contact_count,
            pen: u.max_penetration_m as f32,
            raw: contacts(&u.raw),
            reps: contacts(&u.representatives),
        })
        .collect();
    let data = PageData {
        name: &r.header.name,
        settings: &r.header.settings,
        summary: &r.summary,
        meshes,
        frames,
        updates,
        contact_cap: r.header.contact_cap,
        frame_rate_hz: r.header.frame_rate_hz,
    };
    // `</` cannot appear inside a script element.
    let json = serde_json::to_string(&data)?.replace("</", "<\\/");
    let page = PAGE
        .replace("__THREE__", &base64(THREE.as_bytes()))
        .replace("__ORBIT__", &base64(ORBIT.as_bytes()))
        .replace("__DATA__", &json);
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(out, &page).with_context(|| format!("writing {}", out.display()))?;
    Ok(page.len())
}

/// Runs `view`.
pub fn run(args: &ViewArgs) -> anyhow::Result<()> {
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.recording.with_extension("html"));
    let bytes = write_page(&args.recording, &out)?;
    println!(
        "wrote {} ({:.1} MB): open it in a browser, no server needed",
        out.display(),
        bytes as f64 / 1e6
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }
}
