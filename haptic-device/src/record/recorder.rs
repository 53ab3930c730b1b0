//! The [`Recorder`]: any device, with every reading and command written to a recording.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use haptic_core::{Device, DeviceLimits, DeviceState, Real, Wrench};

use crate::error::{DeviceError, finite_time};
use crate::scripted::check_state;

use super::format::*;

/// Records every reading of a device, and every wrench it is sent, as CSV (format in the
/// [module docs](super)).
///
/// A row is written when the next read comes (it carries the commands that answered its
/// reading), and the last one by [`Recorder::finish`] or, failing that, on drop (errors then
/// ignored). Reads must go strictly forward in time. A failed read or command is passed on and
/// not recorded; a reading with NaN or Inf is an error ([`DeviceError::NonFinite`]), not a row.
///
/// Rows are formatted into a reused buffer and written through `W` (wrap files in a
/// [`BufWriter`], as [`Recorder::create`] does).
pub struct Recorder<D, W: Write> {
    inner: D,
    writer: Option<W>,
    line: String,
    pending: Option<RecordedSample>,
    last_wrench: Wrench,
    rows: u64,
}

impl<D: std::fmt::Debug, W: Write> std::fmt::Debug for Recorder<D, W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("inner", &self.inner)
            .field("rows", &self.rows)
            .finish_non_exhaustive()
    }
}

impl<D: Device> Recorder<D, BufWriter<File>> {
    /// Records `inner` to a new file at `path` (truncated if it exists).
    ///
    /// # Errors
    /// [`DeviceError::Io`] if the file cannot be created or the header written.
    pub fn create(inner: D, path: impl AsRef<Path>) -> Result<Self, DeviceError> {
        let file = File::create(path).map_err(|source| DeviceError::Io {
            context: "creating a recording",
            source,
        })?;
        Self::new(inner, BufWriter::new(file))
    }
}

impl<D: Device, W: Write> Recorder<D, W> {
    /// Records `inner` to `writer`, with the header [`RecordingHeader::for_device`].
    ///
    /// # Errors
    /// [`DeviceError::Io`] if the header cannot be written.
    pub fn new(inner: D, writer: W) -> Result<Self, DeviceError> {
        let header = RecordingHeader::for_device(&inner);
        Self::with_header(inner, writer, header)
    }

    /// Records `inner` to `writer` with the given header.
    ///
    /// # Errors
    /// [`DeviceError::Parameter`] for a non-positive rate or scale, [`DeviceError::Io`] if the
    /// header cannot be written.
    pub fn with_header(
        inner: D,
        mut writer: W,
        header: RecordingHeader,
    ) -> Result<Self, DeviceError> {
        header.validate()?;
        header
            .write_to(&mut writer)
            .map_err(|source| DeviceError::Io {
                context: "writing a recording header",
                source,
            })?;
        Ok(Self {
            inner,
            writer: Some(writer),
            line: String::with_capacity(512),
            pending: None,
            last_wrench: Wrench::zero(),
            rows: 0,
        })
    }

    /// The recorded device.
    pub fn inner(&self) -> &D {
        &self.inner
    }

    /// The recorded device, mutably.
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.inner
    }

    /// Rows written so far (the pending one excluded).
    pub fn rows_written(&self) -> u64 {
        self.rows
    }

    fn flush_pending(&mut self) -> Result<(), DeviceError> {
        if let (Some(sample), Some(w)) = (self.pending.take(), self.writer.as_mut()) {
            write_row(&mut self.line, &sample);
            w.write_all(self.line.as_bytes())
                .map_err(|source| DeviceError::Io {
                    context: "writing a recording row",
                    source,
                })?;
            self.rows += 1;
        }
        Ok(())
    }

    /// Writes the last row, flushes, and returns the writer.
    ///
    /// # Errors
    /// [`DeviceError::Io`] if writing or flushing fails.
    pub fn finish(mut self) -> Result<W, DeviceError> {
        self.flush_pending()?;
        match self.writer.take() {
            Some(mut w) => {
                w.flush().map_err(|source| DeviceError::Io {
                    context: "flushing a recording",
                    source,
                })?;
                Ok(w)
            }
            None => Err(DeviceError::Io {
                context: "finishing a recording",
                source: std::io::Error::other("the recording was already finished"),
            }),
        }
    }
}

impl<D, W: Write> Drop for Recorder<D, W> {
    fn drop(&mut self) {
        if let (Some(sample), Some(w)) = (self.pending.take(), self.writer.as_mut()) {
            write_row(&mut self.line, &sample);
            let _ = w.write_all(self.line.as_bytes());
        }
        if let Some(w) = self.writer.as_mut() {
            let _ = w.flush();
        }
    }
}

impl<D: Device, W: Write> Device for Recorder<D, W> {
    type Error = DeviceError;

    fn name(&self) -> &str {
        self.inner.name()
    }

    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }

    fn read(&mut self, now_s: Real) -> Result<DeviceState, DeviceError> {
        let now_s = finite_time(now_s)?;
        if let Some(p) = &self.pending {
            if now_s <= p.t_s {
                return Err(DeviceError::TimeWentBack {
                    previous_s: p.t_s,
                    now_s,
                });
            }
        }
        let state = self.inner.read(now_s).map_err(DeviceError::from_device)?;
        let state = check_state(state)?;
        self.flush_pending()?;
        self.pending = Some(RecordedSample {
            t_s: now_s,
            state,
            wrench: self.last_wrench,
            commands: 0,
        });
        Ok(state)
    }

    fn command(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        self.inner
            .command(wrench)
            .map_err(DeviceError::from_device)?;
        self.last_wrench = *wrench;
        if let Some(p) = &mut self.pending {
            p.wrench = *wrench;
            p.commands = p.commands.saturating_add(1);
        }
        Ok(())
    }

    fn command_zero(&mut self) -> Result<(), DeviceError> {
        self.inner
            .command_zero()
            .map_err(DeviceError::from_device)?;
        self.last_wrench = Wrench::zero();
        if let Some(p) = &mut self.pending {
            p.wrench = Wrench::zero();
            p.commands = p.commands.saturating_add(1);
        }
        Ok(())
    }
}
