//! Reading steps shared by the file loaders: sample data checked against the real file length
//! before anything proportional is allocated, bounded decompression, and a progress bar for
//! large files on a terminal.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use super::decode::read_samples;
use super::{checked_voxel_count, dims_text, Endian, ScalarType, VolumeError};

/// Capacity reserved up front when the data size cannot be checked before reading
/// (compressed data); beyond this, memory grows only as samples arrive.
pub(crate) const UNVERIFIED_RESERVE: usize = 1 << 20;

/// Files larger than this show a progress bar while loading (on a terminal only).
const PROGRESS_BYTES: u64 = 64 << 20;

/// How the samples of a grid are stored.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Layout {
    pub dims: [usize; 3],
    pub scalar: ScalarType,
    pub endian: Endian,
}

impl Layout {
    /// Voxel count (checked against `MAX_VOXELS`) and data size in bytes.
    pub fn sizes(&self) -> Result<(usize, u64), VolumeError> {
        let count = checked_voxel_count(self.dims)?;
        Ok((count, count as u64 * self.scalar.size_bytes() as u64))
    }

    pub fn describe(&self) -> String {
        format!("dims {} of {}", dims_text(&self.dims), self.scalar)
    }
}

pub(crate) fn io_error(path: &Path) -> impl Fn(io::Error) -> VolumeError + '_ {
    move |source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A header error of a format whose headers have no line structure; the message names the
/// format ("DICOM header of …").
pub(crate) fn format_header_error(path: &Path, format: &'static str, message: impl Into<String>) -> VolumeError {
    VolumeError::Header {
        format,
        path: path.to_path_buf(),
        line: None,
        message: message.into(),
    }
}

pub(crate) fn data_error(path: &Path, message: impl Into<String>) -> VolumeError {
    VolumeError::Data {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Reads the samples of `layout` starting at byte `offset` of an uncompressed file. Trailing
/// bytes after the data are allowed (many formats pad); missing bytes are an error reported
/// before any allocation.
pub(crate) fn samples_from_file(
    path: &Path,
    offset: u64,
    layout: Layout,
    kind: &'static str,
) -> Result<Vec<f32>, VolumeError> {
    let (count, expected_bytes) = layout.sizes()?;
    let file = File::open(path).map_err(io_error(path))?;
    let file_bytes = file.metadata().map_err(io_error(path))?.len();
    let actual_bytes = file_bytes.saturating_sub(offset);
    let truncated = |actual_bytes| VolumeError::Truncated {
        kind,
        path: path.to_path_buf(),
        expected_bytes,
        actual_bytes,
        layout: layout.describe(),
    };
    if actual_bytes < expected_bytes {
        return Err(truncated(actual_bytes));
    }
    let mut reader = BufReader::new(file);
    reader.seek(SeekFrom::Start(offset)).map_err(io_error(path))?;
    let bar = progress_bar(expected_bytes, path);
    let mut reader = bar.wrap_read(reader);
    let (data, read) = read_samples(&mut reader, count, layout.scalar, layout.endian, count).map_err(io_error(path))?;
    bar.finish_and_clear();
    if data.len() < count {
        return Err(truncated(read));
    }
    Ok(data)
}

/// Reads the samples of `layout` from a stream whose length is unknown in advance
/// (decompressed data): at most one byte more than needed is read, so a lying header cannot
/// make decompression run unbounded, and memory grows only as data arrives.
pub(crate) fn samples_from_stream<R: Read>(
    reader: R,
    path: &Path,
    layout: Layout,
    kind: &'static str,
) -> Result<Vec<f32>, VolumeError> {
    let (count, expected_bytes) = layout.sizes()?;
    let stream_err = |e: io::Error| data_error(path, format!("{kind}: {e}"));
    let bar = progress_bar(expected_bytes, path);
    let mut limited = bar.wrap_read(reader.take(expected_bytes + 1));
    let (data, read) =
        read_samples(&mut limited, count, layout.scalar, layout.endian, UNVERIFIED_RESERVE).map_err(stream_err)?;
    bar.finish_and_clear();
    if data.len() < count {
        return Err(VolumeError::Truncated {
            kind,
            path: path.to_path_buf(),
            expected_bytes,
            actual_bytes: read,
            layout: layout.describe(),
        });
    }
    Ok(data)
}

/// Decodes the samples of `layout` from bytes already in memory, which must hold at least
/// the data size.
pub(crate) fn samples_from_bytes(
    bytes: &[u8],
    path: &Path,
    layout: Layout,
    kind: &'static str,
) -> Result<Vec<f32>, VolumeError> {
    let (count, expected_bytes) = layout.sizes()?;
    if (bytes.len() as u64) < expected_bytes {
        return Err(VolumeError::Truncated {
            kind,
            path: path.to_path_buf(),
            expected_bytes,
            actual_bytes: bytes.len() as u64,
            layout: layout.describe(),
        });
    }
    let mut data = super::decode::decode_samples(&bytes[..expected_bytes as usize], layout.scalar, layout.endian);
    data.truncate(count);
    Ok(data)
}

/// A bar for large loads; indicatif draws nothing when stderr is not a terminal.
pub(crate) fn progress_bar(bytes: u64, path: &Path) -> indicatif::ProgressBar {
    if bytes < PROGRESS_BYTES {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(bytes);
    if let Ok(style) = indicatif::ProgressStyle::with_template("{msg} {bar:40} {bytes}/{total_bytes} {eta}") {
        bar.set_style(style);
    }
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    bar.set_message(format!("loading {name}"));
    bar
}

/// Multiplies samples by `slope` and adds `intercept` (rescale to physical units); a zero or
/// non-finite slope means "not set" in NIfTI and DICOM and leaves the data alone.
pub(crate) fn rescale(data: &mut [f32], slope: f64, intercept: f64) -> bool {
    if !slope.is_finite() || slope == 0.0 || !intercept.is_finite() || (slope == 1.0 && intercept == 0.0) {
        return false;
    }
    for v in data.iter_mut() {
        *v = (*v as f64 * slope + intercept) as f32;
    }
    true
}
