//! NIfTI-1 and NIfTI-2 volumes (`.nii`, `.nii.gz`, and `.hdr`/`.img` pairs), with the
//! scl_slope/scl_inter rescale applied and the sform or qform as the patient frame. A small
//! reader of the fixed binary header ([`header`]): the `nifti` crate pulls in ndarray and
//! nalgebra and reads NIfTI-1 only.

mod header;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod write;

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use flate2::read::MultiGzDecoder;

use self::header::{parse_header, sizeof_hdr, NIFTI1_HEADER_BYTES, NIFTI2_HEADER_BYTES};
use super::meta::{Format, Loaded, VolumeMeta};
use super::read::{io_error, rescale, samples_from_file, samples_from_stream};
use super::{Endian, Volume, VolumeError};

/// Loads a `.nii`, `.nii.gz` or `.hdr` (with its `.img`) file.
pub fn load_nifti(path: &Path) -> Result<Loaded, VolumeError> {
    let gz = is_gzip(path)?;
    let file = File::open(path).map_err(io_error(path))?;
    let mut reader: Box<dyn Read> = if gz {
        Box::new(MultiGzDecoder::new(BufReader::new(file)))
    } else {
        Box::new(BufReader::new(file))
    };
    let mut bytes = vec![0u8; NIFTI2_HEADER_BYTES];
    let got = read_up_to(&mut reader, &mut bytes[..NIFTI1_HEADER_BYTES], path)?;
    if got < NIFTI1_HEADER_BYTES {
        return Err(header_error(
            path,
            format!("file has {got} bytes, shorter than a NIfTI header"),
        ));
    }
    let mut header_len = NIFTI1_HEADER_BYTES;
    if sizeof_hdr(&bytes) == Some((540, Endian::Little)) || sizeof_hdr(&bytes) == Some((540, Endian::Big)) {
        let more = read_up_to(&mut reader, &mut bytes[NIFTI1_HEADER_BYTES..], path)?;
        if more < NIFTI2_HEADER_BYTES - NIFTI1_HEADER_BYTES {
            return Err(header_error(path, "file ends inside the NIfTI-2 header"));
        }
        header_len = NIFTI2_HEADER_BYTES;
    }
    let header = parse_header(&bytes[..header_len], path)?;
    let mut meta = VolumeMeta::new(Format::Nifti, Some(header.layout.scalar));
    meta.notes.push(format!("NIfTI-{}", header.version));
    meta.patient = header.patient.clone();
    if header.frames > 1 {
        meta.notes
            .push(format!("{} volumes along t; loaded the first", header.frames));
    }
    let mut data = if header.pair {
        let img = pair_data_path(path)?;
        if is_gzip(&img)? {
            let file = BufReader::new(File::open(&img).map_err(io_error(&img))?);
            samples_from_stream(
                MultiGzDecoder::new(file),
                &img,
                header.layout,
                "decompressed NIfTI data in",
            )?
        } else {
            samples_from_file(&img, header.vox_offset, header.layout, "NIfTI data in")?
        }
    } else if gz {
        let skip = header
            .vox_offset
            .checked_sub(header_len as u64)
            .ok_or_else(|| header_error(path, format!("vox_offset {} lies inside the header", header.vox_offset)))?;
        let skipped = std::io::copy(&mut (&mut reader).take(skip), &mut std::io::sink())
            .map_err(|e| header_error(path, format!("gzip decompression failed: {e}")))?;
        if skipped < skip {
            return Err(header_error(path, "file ends before vox_offset"));
        }
        samples_from_stream(reader, path, header.layout, "decompressed NIfTI data in")?
    } else {
        drop(reader);
        samples_from_file(path, header.vox_offset, header.layout, "NIfTI data in")?
    };
    if rescale(&mut data, header.slope, header.inter) {
        meta.notes
            .push(format!("rescaled: value × {} + {}", header.slope, header.inter));
    }
    Ok(Loaded::new(
        Volume::new(header.layout.dims, header.spacing, data)?,
        meta,
    ))
}

pub(super) fn header_error(path: &Path, message: impl Into<String>) -> VolumeError {
    super::read::format_header_error(path, "NIfTI", message)
}

fn is_gzip(path: &Path) -> Result<bool, VolumeError> {
    let mut magic = [0u8; 2];
    let mut file = File::open(path).map_err(io_error(path))?;
    let got = read_up_to(&mut file, &mut magic, path)?;
    Ok(got == 2 && magic == [0x1f, 0x8b])
}

fn read_up_to<R: Read + ?Sized>(reader: &mut R, buf: &mut [u8], path: &Path) -> Result<usize, VolumeError> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(header_error(path, format!("cannot read the header: {e}"))),
        }
    }
    Ok(filled)
}

fn pair_data_path(path: &Path) -> Result<PathBuf, VolumeError> {
    let name = path.to_string_lossy();
    let candidates = [
        path.with_extension("img"),
        PathBuf::from(name.replace(".hdr.gz", ".img.gz")),
    ];
    candidates
        .into_iter()
        .find(|p| p.exists())
        .ok_or_else(|| header_error(path, "header of a .hdr/.img pair, but the .img file is missing"))
}
