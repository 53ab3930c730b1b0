//! Recordings of a run for replay: what the tool felt, frame by frame, and what the contact
//! thread found at each update. Written by [`RunRecorder`]: as a [`RunObserver`] of a
//! virtual-time run ([`crate::Pipeline::run_virtual_observed`]), or after a real-time run
//! ([`crate::Pipeline::run_realtime_recorded`], whose haptic thread fills a buffer reserved
//! before its loop). Read back by [`RunRecording::read`]; `cargo xtask view` turns one into a
//! self-contained HTML page.
//!
//! # Format (`haptic-run-recording`, version 1)
//! UTF-8 JSON Lines. The first line is the [`RecordingHeader`] (`"format":
//! "haptic-run-recording"`, `"version": 1`, the meshes by path and content hash, the run's
//! settings). Then, in time order, one line per recorded haptic frame, `{"frame": Frame}`, and
//! one per contact update, `{"update": UpdateRecord}`. The last line is `{"end": Summary}`; a file
//! without it is truncated. Units: metres, seconds, newtons, newton-metres; quaternions
//! `[w, x, y, z]`, body to world.
//!
//! Frames are decimated to `frame_rate_hz` (the haptic rate at most). Each update keeps at most
//! `contact_cap` raw contacts (the deepest first) and says how many there were.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

use haptic_core::{Contact, ContactSet, Pose, Real, Vec3};
use serde::{Deserialize, Serialize};

use crate::stages::{ContactUpdate, HapticStage};
use crate::telemetry::Summary;

/// The format's name, in every header.
pub const FORMAT: &str = "haptic-run-recording";
/// The format version this crate writes and reads.
pub const VERSION: u32 = 1;
/// Raw contacts kept per update by default.
pub const DEFAULT_CONTACT_CAP: usize = 256;

/// A mesh of the scene, by reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshRecord {
    /// `"tool"` or `"obstacle"`.
    pub role: String,
    /// The file it was loaded from.
    pub path: PathBuf,
    /// Scale applied when loading (m per file unit).
    pub scale_m_per_unit: Real,
    /// FNV-1a 64-bit hash of the file's bytes, hexadecimal: a viewer checks the file it loads.
    pub content_hash: String,
    /// For the tool: the offset from the mesh's frame to its body frame (the centre of mass,
    /// m); for an obstacle: its world pose, `[x, y, z, qw, qx, qy, qz]`.
    pub placement: [Real; 7],
}

/// The first line of a recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingHeader {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// What was run, in words (scene name).
    pub name: String,
    /// Integrator, back-end and contact model settings, in words.
    pub settings: Vec<(String, String)>,
    /// The meshes.
    pub meshes: Vec<MeshRecord>,
    /// The haptic rate of the run (Hz) and the rate frames are recorded at (Hz).
    pub haptic_rate_hz: Real,
    /// Frames per second recorded.
    pub frame_rate_hz: Real,
    /// Raw contacts kept per update at most.
    pub contact_cap: usize,
}

/// One recorded haptic frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// Time (s).
    pub t: Real,
    /// Tool pose (its body frame), `[x, y, z, qw, qx, qy, qz]`.
    pub tool: [Real; 7],
    /// The tool pose at which the coupling would be at rest, given the handle and the grasp:
    /// where the device puts the tool (the viewer's ghost).
    pub ghost: [Real; 7],
    /// Device handle pose.
    pub device: [Real; 7],
    /// Where the coupling holds the tool (world, m): the handle's target point.
    pub grasp_m: [Real; 3],
    /// Force and torque sent to the device (N, N m).
    pub force_n: [Real; 3],
    /// Torque sent (N m).
    pub torque_nm: [Real; 3],
    /// Coupling deviation (m).
    pub deviation_m: Real,
}

/// A contact as recorded: point on the tool (world), normal, depth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContactRecord {
    /// Point on the tool, world (m).
    pub p: [Real; 3],
    /// Normal, out of the tool.
    pub n: [Real; 3],
    /// Depth (m; negative: within δ, not touching).
    pub d: Real,
}

/// One contact update.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UpdateRecord {
    /// Time of the query (s).
    pub t: Real,
    /// Time the update took effect (s).
    pub available_t: Real,
    /// Wall time of the query and clustering (s).
    pub query_time_s: Real,
    /// The error threshold the query used (fraction of the tool radius).
    pub threshold: Real,
    /// Raw contacts found.
    pub raw_contact_count: usize,
    /// The deepest of them, at most the header's `contact_cap`.
    pub raw: Vec<ContactRecord>,
    /// The cluster representatives.
    pub representatives: Vec<ContactRecord>,
    /// Each representative's weight (m): the sum of its raw contacts' weights `d_i + δ`.
    pub representative_weights_m: Vec<Real>,
    /// Deepest penetration (m).
    pub max_penetration_m: Real,
}

impl Frame {
    /// The frame of `haptic` after its step ending at `t_s`. Allocates nothing.
    pub fn of<I: haptic_core::Integrator, D: haptic_core::Device>(
        t_s: Real,
        haptic: &HapticStage<I, D>,
    ) -> Self {
        let tool = haptic.tool();
        let coupling = &haptic.forces().coupling;
        let device = coupling.device();
        let w = haptic.last_wrench();
        let grasp: Vec3 = tool.x + tool.q * coupling.grasp().r_c;
        Frame {
            t: t_s,
            tool: pose_array(&tool.pose()),
            device: pose_array(&device.pose),
            ghost: pose_array(&coupling.tool_at_handle().pose()),
            grasp_m: grasp.into(),
            force_n: w.force.into(),
            torque_nm: w.torque.into(),
            deviation_m: coupling.deviation(tool).translation_m,
        }
    }
}

impl UpdateRecord {
    /// The record of a contact query at `t_s` that takes effect at `available_s`: the deepest
    /// `cap` raw contacts (sorted in `scratch`, reused), the representatives, and the threshold
    /// the query used.
    #[allow(clippy::too_many_arguments)]
    pub fn of(
        t_s: Real,
        available_s: Real,
        update: &ContactUpdate,
        raw: &ContactSet,
        representatives: &ContactSet,
        representative_weights_m: &[Real],
        query_time_s: Real,
        cap: usize,
        scratch: &mut Vec<Contact>,
    ) -> Self {
        scratch.clear();
        scratch.extend_from_slice(raw.as_slice());
        scratch.sort_by(|a, b| b.depth_m.total_cmp(&a.depth_m));
        scratch.truncate(cap);
        UpdateRecord {
            t: t_s,
            available_t: available_s,
            query_time_s,
            threshold: update.error_threshold,
            raw_contact_count: update.raw_contact_count,
            raw: scratch.iter().map(contact_record).collect(),
            representatives: representatives.iter().map(contact_record).collect(),
            representative_weights_m: representative_weights_m.to_vec(),
            max_penetration_m: update.max_penetration_m,
        }
    }
}

/// One line of a recording after the header.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum Line {
    Frame(Frame),
    Update(UpdateRecord),
    End(Box<Summary>),
}

/// A recording read back.
#[derive(Debug, Clone)]
pub struct RunRecording {
    /// Its header.
    pub header: RecordingHeader,
    /// The frames, in time order.
    pub frames: Vec<Frame>,
    /// The contact updates, in time order.
    pub updates: Vec<UpdateRecord>,
    /// The run's summary.
    pub summary: Summary,
}

/// A recording could not be read or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordingError {
    /// The file could not be read or written.
    #[error("recording {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The first line is not a header of this format.
    #[error("not a haptic run recording (its first line is not a `{FORMAT}` header)")]
    NotARecording,
    /// A version this crate does not read.
    #[error("recording format version {found}; this build reads version {VERSION}")]
    UnsupportedVersion {
        /// The version found.
        found: u32,
    },
    /// A line that does not parse.
    #[error("recording line {line}: {message}")]
    Malformed {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The file ends before its `end` line.
    #[error("the recording is truncated: it ends at line {lines} without its summary")]
    Truncated {
        /// Lines read.
        lines: usize,
    },
}

/// Pose as `[x, y, z, qw, qx, qy, qz]`.
pub fn pose_array(p: &Pose) -> [Real; 7] {
    let q = p.orientation;
    [p.position.x, p.position.y, p.position.z, q.w, q.i, q.j, q.k]
}

fn contact_record(c: &Contact) -> ContactRecord {
    ContactRecord {
        p: c.p_a.into(),
        n: c.n.into(),
        d: c.depth_m,
    }
}

/// FNV-1a 64-bit hash of `bytes`, as 16 hexadecimal digits.
pub fn content_hash(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// What a run reports to an observer as it goes (see [`crate::Pipeline::run_virtual_observed`]).
pub trait RunObserver<I, D> {
    /// After every haptic step, at time `t_s`.
    fn haptic_step(&mut self, t_s: Real, haptic: &HapticStage<I, D>);
    /// After every contact query, at its time `t_s`: the update, the raw contacts and the
    /// representatives it came from (with their weights, m), the query's wall time and when it
    /// takes effect.
    #[allow(clippy::too_many_arguments)]
    fn contact_update(
        &mut self,
        t_s: Real,
        available_s: Real,
        update: &ContactUpdate,
        raw: &ContactSet,
        representatives: &ContactSet,
        representative_weights_m: &[Real],
        query_time_s: Real,
    );
}

/// Writes a recording as the run goes (a [`RunObserver`]). Errors while writing are kept and
/// returned by [`RunRecorder::finish`]; the run is not disturbed.
pub struct RunRecorder<W: Write> {
    out: W,
    frame_period_s: Real,
    /// The first step's time (s): the origin of the frame grid.
    first_frame_s: Option<Real>,
    /// The index of the next frame on the grid `first + k · frame_period_s`.
    next_frame: u64,
    contact_cap: usize,
    threshold: Real,
    error: Option<std::io::Error>,
    scratch: Vec<Contact>,
}

impl<W: Write> RunRecorder<W> {
    /// A recorder writing `header` to `out` first.
    ///
    /// # Errors
    /// The header could not be written.
    pub fn new(mut out: W, header: &RecordingHeader, threshold: Real) -> std::io::Result<Self> {
        serde_json::to_writer(&mut out, header)?;
        out.write_all(b"\n")?;
        Ok(Self {
            out,
            frame_period_s: 1.0 / header.frame_rate_hz.max(1e-9),
            first_frame_s: None,
            next_frame: 0,
            contact_cap: header.contact_cap,
            threshold,
            error: None,
            scratch: Vec::new(),
        })
    }

    fn line(&mut self, line: &Line) {
        if self.error.is_some() {
            return;
        }
        let r = serde_json::to_writer(&mut self.out, line)
            .map_err(std::io::Error::from)
            .and_then(|()| self.out.write_all(b"\n"));
        if let Err(e) = r {
            self.error = Some(e);
        }
    }

    /// Writes a frame.
    pub fn write_frame(&mut self, frame: &Frame) {
        self.line(&Line::Frame(*frame));
    }

    /// Writes a contact update.
    pub fn write_update(&mut self, update: &UpdateRecord) {
        self.line(&Line::Update(update.clone()));
    }

    /// Seconds between two recorded frames.
    pub fn frame_period_s(&self) -> Real {
        self.frame_period_s
    }

    /// Raw contacts kept per update at most.
    pub fn contact_cap(&self) -> usize {
        self.contact_cap
    }

    /// The error threshold the recorder was made with (the run's configured one). Each update
    /// records the threshold its own query used, which a time budget picks.
    pub fn threshold(&self) -> Real {
        self.threshold
    }

    /// Writes the summary line and returns the writer.
    ///
    /// # Errors
    /// The first write error of the run, or of this line.
    pub fn finish(mut self, summary: &Summary) -> std::io::Result<W> {
        self.line(&Line::End(Box::new(summary.clone())));
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write, I: haptic_core::Integrator, D: haptic_core::Device> RunObserver<I, D>
    for RunRecorder<W>
{
    fn haptic_step(&mut self, t_s: Real, haptic: &HapticStage<I, D>) {
        // Frames on the fixed grid `first + k · period` (the first step at or after each grid
        // time), so that decimation does not drift when the period is not a whole number of
        // haptic steps.
        let first = *self.first_frame_s.get_or_insert(t_s);
        let t = t_s - first + 1e-9;
        if t < self.next_frame as Real * self.frame_period_s {
            return;
        }
        self.next_frame = (t / self.frame_period_s).floor() as u64 + 1;
        self.write_frame(&Frame::of(t_s, haptic));
    }

    fn contact_update(
        &mut self,
        t_s: Real,
        available_s: Real,
        update: &ContactUpdate,
        raw: &ContactSet,
        representatives: &ContactSet,
        representative_weights_m: &[Real],
        query_time_s: Real,
    ) {
        let mut scratch = std::mem::take(&mut self.scratch);
        let record = UpdateRecord::of(
            t_s,
            available_s,
            update,
            raw,
            representatives,
            representative_weights_m,
            query_time_s,
            self.contact_cap,
            &mut scratch,
        );
        self.scratch = scratch;
        self.write_update(&record);
    }
}

impl RunRecording {
    /// Reads a recording.
    ///
    /// # Errors
    /// [`RecordingError`]: unreadable, foreign, another version, a malformed line, truncated.
    pub fn read(path: &Path) -> Result<Self, RecordingError> {
        let file = std::fs::File::open(path).map_err(|source| RecordingError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_reader(BufReader::new(file)).map_err(|e| match e {
            RecordingError::Io { source, .. } => RecordingError::Io {
                path: path.to_owned(),
                source,
            },
            other => other,
        })
    }

    /// Reads a recording from any reader.
    ///
    /// # Errors
    /// As [`RunRecording::read`].
    pub fn from_reader(reader: impl BufRead) -> Result<Self, RecordingError> {
        let mut lines = reader.lines();
        let io = |source| RecordingError::Io {
            path: PathBuf::new(),
            source,
        };
        let first = match lines.next() {
            // Bytes that are not UTF-8 (a binary file) are not a recording.
            Some(Err(e)) if e.kind() == std::io::ErrorKind::InvalidData => {
                return Err(RecordingError::NotARecording);
            }
            Some(l) => l.map_err(io)?,
            None => return Err(RecordingError::NotARecording),
        };
        let probe: serde_json::Value = match serde_json::from_str(&first) {
            Ok(v) => v,
            // A header cut short: ours if it starts like one.
            Err(e) if e.is_eof() && first.contains(&format!("\"{FORMAT}\"")) => {
                return Err(RecordingError::Truncated { lines: 1 });
            }
            Err(_) => return Err(RecordingError::NotARecording),
        };
        if probe.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(RecordingError::NotARecording);
        }
        let version = probe
            .get("version")
            .and_then(serde_json::Value::as_u64)
            .unwrap_or(0);
        if version != u64::from(VERSION) {
            return Err(RecordingError::UnsupportedVersion {
                found: u32::try_from(version).unwrap_or(u32::MAX),
            });
        }
        let header: RecordingHeader =
            serde_json::from_value(probe).map_err(|e| RecordingError::Malformed {
                line: 1,
                message: e.to_string(),
            })?;
        let (mut frames, mut updates) = (Vec::new(), Vec::new());
        let mut count = 1;
        for line in lines {
            count += 1;
            let line = match line {
                Ok(l) => l,
                Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                    return Err(RecordingError::Malformed {
                        line: count,
                        message: "not UTF-8".into(),
                    });
                }
                Err(e) => return Err(io(e)),
            };
            if line.trim().is_empty() {
                continue;
            }
            match serde_json::from_str::<Line>(&line) {
                Ok(Line::Frame(f)) => frames.push(f),
                Ok(Line::Update(u)) => updates.push(u),
                Ok(Line::End(summary)) => {
                    return Ok(Self {
                        header,
                        frames,
                        updates,
                        summary: *summary,
                    });
                }
                Err(e) if e.is_eof() => return Err(RecordingError::Truncated { lines: count }),
                Err(e) => {
                    return Err(RecordingError::Malformed {
                        line: count,
                        message: e.to_string(),
                    });
                }
            }
        }
        Err(RecordingError::Truncated { lines: count })
    }
}
