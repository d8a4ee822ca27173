//! Writing volumes as NRRD0004 float files that round-trip exactly through the reader.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use flate2::write::GzEncoder;
use flate2::Compression;

use crate::volume::{Volume, VolumeError};

/// Samples converted per write; bounds the scratch buffer independent of the volume size.
const CHUNK_SAMPLES: usize = 1 << 16;

/// Writes `vol` as a single NRRD file: type float, little endian, raw or gzip encoding.
pub fn write_nrrd(path: &Path, vol: &Volume, gzip: bool) -> Result<(), VolumeError> {
    write_to(path, vol, gzip).map_err(|source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn write_to(path: &Path, vol: &Volume, gzip: bool) -> io::Result<()> {
    let mut out = BufWriter::new(File::create(path)?);
    out.write_all(header_text(vol, gzip).as_bytes())?;
    if gzip {
        let mut encoder = GzEncoder::new(out, Compression::default());
        write_samples(&mut encoder, &vol.data)?;
        encoder.finish()?.flush()
    } else {
        write_samples(&mut out, &vol.data)?;
        out.flush()
    }
}

fn header_text(vol: &Volume, gzip: bool) -> String {
    let [nx, ny, nz] = vol.dims;
    // f32's Display prints the shortest text that parses back to the same value.
    let [sx, sy, sz] = vol.spacing;
    let encoding = if gzip { "gzip" } else { "raw" };
    format!(
        "NRRD0004\n\
         # Complete NRRD file format specification at:\n\
         # http://teem.sourceforge.net/nrrd/format.html\n\
         content: caustica volume\n\
         type: float\n\
         dimension: 3\n\
         sizes: {nx} {ny} {nz}\n\
         spacings: {sx} {sy} {sz}\n\
         endian: little\n\
         encoding: {encoding}\n\
         \n"
    )
}

fn write_samples<W: Write>(out: &mut W, data: &[f32]) -> io::Result<()> {
    let mut bytes = Vec::with_capacity(CHUNK_SAMPLES.min(data.len()) * 4);
    for chunk in data.chunks(CHUNK_SAMPLES) {
        bytes.clear();
        bytes.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
        out.write_all(&bytes)?;
    }
    Ok(())
}
