//! `cargo xtask view RECORDING [--out FILE.html]`: a recorded run (`cargo xtask demo
//! --virtual-time --record FILE`, or a study's) as one self-contained HTML page that works
//! offline, from a file, with no server.
//!
//! The page embeds three.js 0.170.0 (vendored in `xtask/vendor/`, MIT) as data: URLs of an
//! import map, the meshes (positions as little-endian `f32`, indices as `u32`, base64) and the
//! frames and contact updates as JSON. It shows the tool, the obstacles and the device's ghost
//! (the tool where the handle holds it) with an orbit camera; a time slider with play and pause
//! at real speed and slowed down; toggles for the raw contacts, the cluster representatives
//! (their area by weight), the force and torque arrows and the coupling spring; plots of force,
//! deviation, penetration, contact rate and query time on a common time axis, whose cursor
//! follows the slider (a click moves it); and the run's summary. Once its first frame is on
//! screen it notes the load time and the share of the canvas that is not background, times the
//! drawing of 30 frames across the run (waiting for the GPU), prints the figures and sets its
//! title to `ready: …` (the browser check waits for that).
//!
//! Long recordings are thinned for the page: frames to `--frame-rate` (by default the recorded
//! rate, lowered so that the page holds at most [`MAX_PAGE_FRAMES`] frames), and the contacts of
//! an update kept only when a kept frame shows it (every update keeps its figures for the
//! plots).

mod display_mesh;

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use haptic_collision::{LoadOptions, TriMesh};
use haptic_core::Vec3;
use haptic_runtime::recording::{RunRecording, content_hash};
use serde::Serialize;

const THREE: &str = include_str!("../../vendor/three-0.170.0/three.module.min.js");
const ORBIT: &str = include_str!("../../vendor/three-0.170.0/OrbitControls.js");
const PAGE: &str = include_str!("page.html");

/// Triangles the page draws at most while the view moves (the tool twice, for its ghost): larger
/// meshes get a lighter copy for motion (see [`display_mesh`]), and the full meshes are drawn
/// when the view stands still. About 10 ms a frame in a software renderer on two cores (the jaws
/// in headless Chromium with SwiftShader on this project's CI machine).
pub const MOVING_TRIANGLES: usize = 12_000;

/// Frames a page holds at most unless `--frame-rate` asks otherwise (a minute at 300 Hz).
pub const MAX_PAGE_FRAMES: usize = 18_000;

/// Arguments of `view`.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// The recording.
    pub recording: PathBuf,
    /// The page to write (default: the recording's path with `.html`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Frames per second of run time to put in the page (default: as recorded, lowered to keep
    /// at most 18,000 frames).
    #[arg(long)]
    pub frame_rate: Option<f64>,
}

/// A mesh as the page draws it.
#[derive(Serialize)]
struct PageMesh {
    role: String,
    placement: [f64; 7],
    triangle_count: usize,
    positions: String,
    indices: String,
    /// The lighter copy drawn while the view moves, if the mesh needs one.
    moving: Option<MovingMesh>,
}

/// A mesh's lighter copy for motion.
#[derive(Serialize)]
struct MovingMesh {
    positions: String,
    indices: String,
    triangle_count: usize,
    /// Largest distance a vertex moved (m).
    error_m: f64,
}

/// Little-endian `f32` positions and `u32` indices, base64.
fn encode(vertices: &[Vec3], triangles: &[[u32; 3]]) -> (String, String) {
    let positions: Vec<u8> = vertices
        .iter()
        .flat_map(|v| [v.x as f32, v.y as f32, v.z as f32])
        .flat_map(f32::to_le_bytes)
        .collect();
    let indices: Vec<u8> = triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    (base64(&positions), base64(&indices))
}

/// Gives each mesh its copy for motion, so that the triangles drawn while moving (the tool
/// counted twice, for the ghost) stay within [`MOVING_TRIANGLES`].
fn add_moving_copies(meshes: &mut [(PageMesh, TriMesh)]) {
    let drawn: usize = meshes
        .iter()
        .map(|(p, m)| m.triangles().len() * if p.role == "tool" { 2 } else { 1 })
        .sum();
    if drawn <= MOVING_TRIANGLES {
        return;
    }
    let share = MOVING_TRIANGLES as f64 / drawn as f64;
    for (page, mesh) in meshes {
        let budget = ((mesh.triangles().len() as f64 * share) as usize).max(500);
        if let Some(d) = display_mesh::simplified(mesh.vertices(), mesh.triangles(), budget) {
            let (positions, indices) = encode(&d.vertices, &d.triangles);
            page.moving = Some(MovingMesh {
                positions,
                indices,
                triangle_count: d.triangles.len(),
                error_m: 3f64.sqrt() * d.cell_m,
            });
        }
    }
}

/// The frames, one array per quantity (flattened vectors).
#[derive(Serialize, Default)]
struct PageFrames {
    t: Vec<f32>,
    tool: Vec<f32>,
    ghost: Vec<f32>,
    device: Vec<f32>,
    grasp: Vec<f32>,
    force: Vec<f32>,
    torque: Vec<f32>,
    f: Vec<f32>,
    tq: Vec<f32>,
    dev: Vec<f32>,
}

/// A contact update as the page draws it: raw contact points and representatives' points
/// flattened `[x, y, z]`, the representatives' weights (m).
#[derive(Serialize)]
struct PageUpdate {
    t: f32,
    at: f32,
    q: f32,
    n: usize,
    pen: f32,
    raw: Vec<f32>,
    reps: Vec<f32>,
    w: Vec<f32>,
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

/// Which frames a page shows: every `stride`-th, so that the page's rate is at most `rate_hz`
/// (default: the recorded rate) and, without an explicit rate, the page holds at most
/// [`MAX_PAGE_FRAMES`]. Returns the stride and the page's frame rate.
fn frame_stride(frames: usize, recorded_hz: f64, rate_hz: Option<f64>) -> (usize, f64) {
    let stride = match rate_hz {
        Some(r) => (recorded_hz / r).round().max(1.0) as usize,
        None => frames.div_ceil(MAX_PAGE_FRAMES).max(1),
    };
    (stride, recorded_hz / stride as f64)
}

/// For each update, whether a shown frame displays it: the last update in effect at each shown
/// frame's time (`updates` by `available_t`, both in time order).
fn updates_shown(frame_times: &[f64], available: &[f64]) -> Vec<bool> {
    let mut shown = vec![false; available.len()];
    let mut k = 0;
    for &t in frame_times {
        while k < available.len() && available[k] <= t {
            k += 1;
        }
        if k > 0 {
            shown[k - 1] = true;
        }
    }
    shown
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
fn page_mesh(m: &haptic_runtime::recording::MeshRecord) -> anyhow::Result<(PageMesh, TriMesh)> {
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
    let (positions, indices) = encode(mesh.vertices(), mesh.triangles());
    Ok((
        PageMesh {
            role: m.role.clone(),
            placement: m.placement,
            triangle_count: mesh.triangles().len(),
            positions,
            indices,
            moving: None,
        },
        mesh,
    ))
}

/// Writes the page of `recording` to `out`, with frames at `frame_rate_hz` (see
/// [`frame_stride`]); returns its size in bytes.
///
/// # Errors
/// The recording cannot be read or has no frames, a mesh is missing or changed, or the page
/// cannot be written.
pub fn write_page(
    recording: &Path,
    out: &Path,
    frame_rate_hz: Option<f64>,
) -> anyhow::Result<usize> {
    let r = RunRecording::read(recording)
        .with_context(|| format!("reading {}", recording.display()))?;
    if r.frames.is_empty() {
        bail!(
            "{} has no frames: the run ended before its first recorded step",
            recording.display()
        );
    }
    if let Some(rate) = frame_rate_hz {
        if !(rate.is_finite() && rate > 0.0) {
            bail!("--frame-rate must be a positive number of frames per second, not {rate}");
        }
    }
    let (stride, page_rate_hz) =
        frame_stride(r.frames.len(), r.header.frame_rate_hz, frame_rate_hz);
    let shown_frames: Vec<_> = r.frames.iter().step_by(stride).collect();
    let shown = updates_shown(
        &shown_frames.iter().map(|f| f.t).collect::<Vec<_>>(),
        &r.updates.iter().map(|u| u.available_t).collect::<Vec<_>>(),
    );
    let meshes = r
        .header
        .meshes
        .iter()
        .map(page_mesh)
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut meshes = meshes;
    add_moving_copies(&mut meshes);
    let meshes: Vec<PageMesh> = meshes.into_iter().map(|(p, _)| p).collect();
    let mut frames = PageFrames::default();
    for f in shown_frames {
        frames.t.push(f.t as f32);
        frames.tool.extend(flat(f.tool));
        frames.ghost.extend(flat(f.ghost));
        frames.device.extend(flat(f.device));
        frames.grasp.extend(flat(f.grasp_m));
        frames.force.extend(flat(f.force_n));
        frames.torque.extend(flat(f.torque_nm));
        frames.f.push(Vec3::from(f.force_n).norm() as f32);
        frames.tq.push(Vec3::from(f.torque_nm).norm() as f32);
        frames.dev.push(f.deviation_m as f32);
    }
    let points = |cs: &[haptic_runtime::recording::ContactRecord], on: bool| -> Vec<f32> {
        cs.iter().filter(|_| on).flat_map(|c| flat(c.p)).collect()
    };
    let updates = r
        .updates
        .iter()
        .zip(&shown)
        .map(|(u, &on)| PageUpdate {
            t: u.t as f32,
            at: u.available_t as f32,
            q: u.query_time_s as f32,
            n: u.raw_contact_count,
            pen: u.max_penetration_m as f32,
            raw: points(&u.raw, on),
            reps: points(&u.representatives, on),
            w: if on {
                flat(u.representative_weights_m.iter().copied())
            } else {
                Vec::new()
            },
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
        frame_rate_hz: page_rate_hz,
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
    let bytes = write_page(&args.recording, &out, args.frame_rate)?;
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
    fn long_recordings_are_thinned_to_the_page_limit() {
        assert_eq!(frame_stride(900, 1000.0, None), (1, 1000.0));
        let (stride, hz) = frame_stride(60_000, 1000.0, None);
        assert!(60_000usize.div_ceil(stride) <= MAX_PAGE_FRAMES, "{stride}");
        assert!((hz - 1000.0 / stride as f64).abs() < 1e-12);
        assert_eq!(frame_stride(60_000, 1000.0, Some(100.0)), (10, 100.0));
        assert_eq!(frame_stride(10, 1000.0, Some(5000.0)).0, 1);
    }

    #[test]
    fn an_update_is_kept_when_a_shown_frame_displays_it() {
        // Updates in effect from 0.0, 0.1, 0.2, 0.35; frames shown at 0.15 and 0.4.
        let shown = updates_shown(&[0.15, 0.4], &[0.0, 0.1, 0.2, 0.35]);
        assert_eq!(shown, vec![false, true, false, true]);
        // A frame before any update shows none.
        assert_eq!(updates_shown(&[0.0], &[0.5]), vec![false]);
    }

    #[test]
    fn a_recording_without_frames_gets_no_page() {
        let dir = std::env::temp_dir().join(format!("haptic-view-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rec = dir.join("empty.rec");
        let header = crate::recording::header("empty", Vec::new(), Vec::new(), 1000.0, 1000.0);
        let recorder =
            haptic_runtime::RunRecorder::new(std::fs::File::create(&rec).unwrap(), &header, 0.0)
                .unwrap();
        recorder
            .finish(&haptic_runtime::Summary::default())
            .unwrap();
        let err = write_page(&rec, &dir.join("empty.html"), None).unwrap_err();
        assert!(err.to_string().contains("no frames"), "{err}");
        assert!(!dir.join("empty.html").exists());
        let err = write_page(&rec, &dir.join("empty.html"), Some(0.0)).unwrap_err();
        assert!(err.to_string().contains("no frames"), "{err}");
    }

    #[test]
    fn base64_matches_rfc_4648() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }
}
