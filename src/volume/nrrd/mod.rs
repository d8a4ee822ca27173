//! NRRD volume files: reading attached or detached data (raw, gzip, ascii) and writing.

mod header;
#[cfg(test)]
mod tests;
mod write;

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use flate2::read::MultiGzDecoder;

use self::header::{Encoding, NrrdHeader};
use super::decode::read_samples;
use super::{checked_voxel_count, dims_text, Format, Loaded, Volume, VolumeError, VolumeMeta};

pub use self::write::write_nrrd;

/// Capacity reserved up front when the data size cannot be checked before reading
/// (compressed or text data); beyond this, memory grows only as samples arrive.
const UNVERIFIED_RESERVE: usize = 1 << 20;

/// Longest ascii sample token accepted.
const MAX_TOKEN_BYTES: usize = 128;

/// Loads a `.nrrd` (attached data) or `.nhdr` (detached data) file.
pub fn load_nrrd(path: &Path) -> Result<Volume, VolumeError> {
    open_nrrd(path).map(|loaded| loaded.volume)
}

/// Loads a NRRD file with its metadata: a `modality:=CT` key/value pair marks Hounsfield units.
pub fn open_nrrd(path: &Path) -> Result<Loaded, VolumeError> {
    let file = File::open(path).map_err(io_error(path))?;
    let mut reader = BufReader::new(file);
    let header = header::read_header(&mut reader, path)?;
    let count = checked_voxel_count(header.dims)?;
    let data = match &header.data_file {
        None => read_data(reader, path, &header, count)?,
        Some(data_path) => {
            let file = File::open(data_path).map_err(io_error(data_path))?;
            read_data(BufReader::new(file), data_path, &header, count)?
        }
    };
    let mut meta = VolumeMeta::new(Format::Nrrd, Some(header.scalar));
    if let Some(modality) = &header.modality {
        meta = meta.with_modality(modality);
    }
    meta.patient = header.patient.clone();
    Ok(Loaded::new(Volume::new(header.dims, header.spacing, data)?, meta))
}

fn io_error(path: &Path) -> impl Fn(io::Error) -> VolumeError + '_ {
    move |source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Reads `count` samples from `reader`, positioned where the data (or its line skip) starts.
fn read_data(
    mut reader: BufReader<File>,
    data_path: &Path,
    header: &NrrdHeader,
    count: usize,
) -> Result<Vec<f32>, VolumeError> {
    let expected_bytes = count as u64 * header.scalar.size_bytes() as u64;
    let layout = format!("dims {} of {}", dims_text(&header.dims), header.scalar);
    let truncated = |kind, actual_bytes| VolumeError::Truncated {
        kind,
        path: data_path.to_path_buf(),
        expected_bytes,
        actual_bytes,
        layout: layout.clone(),
    };
    skip_lines(&mut reader, header.line_skip, data_path)?;
    match header.encoding {
        Encoding::Raw => {
            let io_err = io_error(data_path);
            let position = reader.stream_position().map_err(&io_err)?;
            let file_bytes = reader.get_ref().metadata().map_err(&io_err)?.len();
            let data_start = position.saturating_add(header.byte_skip);
            let actual_bytes = file_bytes.saturating_sub(data_start);
            // Checked against the real file size before anything proportional is allocated.
            if actual_bytes < expected_bytes {
                return Err(truncated("NRRD data in", actual_bytes));
            }
            if actual_bytes > expected_bytes {
                log::warn!(
                    "{}: ignoring {} bytes after the voxel data",
                    data_path.display(),
                    actual_bytes - expected_bytes
                );
            }
            reader.seek(SeekFrom::Start(data_start)).map_err(&io_err)?;
            let bar = crate::volume::read::progress_bar(expected_bytes, data_path);
            let (data, read) = read_samples(&mut bar.wrap_read(reader), count, header.scalar, header.endian, count)
                .map_err(&io_err)?;
            bar.finish_and_clear();
            if data.len() < count {
                return Err(truncated("NRRD data in", read));
            }
            Ok(data)
        }
        Encoding::Gzip => {
            let gzip_err = |e: io::Error| VolumeError::Data {
                path: data_path.to_path_buf(),
                message: format!("gzip decompression failed: {e}"),
            };
            let mut decoder = MultiGzDecoder::new(reader);
            // For compressed data the byte skip applies to the decompressed stream.
            let skipped = io::copy(&mut (&mut decoder).take(header.byte_skip), &mut io::sink()).map_err(gzip_err)?;
            if skipped < header.byte_skip {
                return Err(truncated("decompressed gzip data in", 0));
            }
            // One byte past the expected size is enough to notice trailing data, and a
            // header that lies about the size cannot make decompression run unbounded.
            let mut limited = decoder.take(expected_bytes + 1);
            let (data, read) = read_samples(&mut limited, count, header.scalar, header.endian, UNVERIFIED_RESERVE)
                .map_err(gzip_err)?;
            if data.len() < count {
                return Err(truncated("decompressed gzip data in", read));
            }
            let mut extra = [0u8; 1];
            if limited.read(&mut extra).map_err(gzip_err)? > 0 {
                log::warn!(
                    "{}: gzip data is longer than dims {} of {} need; ignoring the rest",
                    data_path.display(),
                    dims_text(&header.dims),
                    header.scalar
                );
            }
            Ok(data)
        }
        Encoding::Ascii => {
            let skipped =
                io::copy(&mut (&mut reader).take(header.byte_skip), &mut io::sink()).map_err(io_error(data_path))?;
            if skipped < header.byte_skip {
                return Err(truncated("NRRD data in", 0));
            }
            read_ascii(&mut reader, count, data_path, &header.dims)
        }
    }
}

fn skip_lines<R: BufRead>(reader: &mut R, lines: u64, path: &Path) -> Result<(), VolumeError> {
    for skipped in 0..lines {
        let mut line = Vec::new();
        let read = reader.read_until(b'\n', &mut line).map_err(io_error(path))?;
        if read == 0 {
            return Err(VolumeError::Data {
                path: path.to_path_buf(),
                message: format!("ended after {skipped} of the {lines} lines to skip"),
            });
        }
    }
    Ok(())
}

/// Parses whitespace- or comma-separated numbers until `count` are found.
fn read_ascii<R: BufRead>(
    reader: &mut R,
    count: usize,
    path: &Path,
    dims: &[usize; 3],
) -> Result<Vec<f32>, VolumeError> {
    let data_err = |message: String| VolumeError::Data {
        path: path.to_path_buf(),
        message,
    };
    let mut out = Vec::with_capacity(count.min(UNVERIFIED_RESERVE));
    let mut token = Vec::with_capacity(MAX_TOKEN_BYTES);
    let push_token = |token: &mut Vec<u8>, out: &mut Vec<f32>| -> Result<(), VolumeError> {
        if token.is_empty() {
            return Ok(());
        }
        let text = String::from_utf8_lossy(token);
        let value = text
            .parse::<f32>()
            .map_err(|_| data_err(format!("ascii value #{} '{text}' is not a number", out.len() + 1)))?;
        out.push(value);
        token.clear();
        Ok(())
    };
    while out.len() < count {
        let buf = reader.fill_buf().map_err(io_error(path))?;
        if buf.is_empty() {
            push_token(&mut token, &mut out)?;
            break;
        }
        let mut used = 0;
        for &byte in buf {
            used += 1;
            if byte.is_ascii_whitespace() || byte == b',' {
                push_token(&mut token, &mut out)?;
                if out.len() == count {
                    break;
                }
            } else if token.len() < MAX_TOKEN_BYTES {
                token.push(byte);
            } else {
                return Err(data_err(format!(
                    "ascii value #{} is longer than {MAX_TOKEN_BYTES} characters",
                    out.len() + 1
                )));
            }
        }
        reader.consume(used);
    }
    if out.len() < count {
        return Err(data_err(format!(
            "ascii data has {} values but dims {} need {count}",
            out.len(),
            dims_text(dims)
        )));
    }
    Ok(out)
}
