//! The binary blocks of VTK XML arrays: a size header and raw data, or for zlib data a block
//! table (count, block size, last block size, compressed sizes) and the compressed blocks;
//! appended raw or base64-encoded, with the header encoded separately from the data.

use std::io::Read;
use std::path::Path;

use base64::Engine as _;
use flate2::read::ZlibDecoder;

use crate::volume::read::data_error;
use crate::volume::{Endian, VolumeError};

fn header_word(bytes: &[u8], at: usize, size: usize, endian: Endian) -> Option<u64> {
    let b = bytes.get(at..at + size)?;
    Some(match (size, endian) {
        (4, Endian::Little) => u64::from(u32::from_le_bytes(b.try_into().ok()?)),
        (4, Endian::Big) => u64::from(u32::from_be_bytes(b.try_into().ok()?)),
        (_, Endian::Little) => u64::from_le_bytes(b.try_into().ok()?),
        (_, Endian::Big) => u64::from_be_bytes(b.try_into().ok()?),
    })
}

/// An uncompressed array's size header must cover the extent.
fn check_array_size(size: u64, expected_bytes: u64, path: &Path) -> Result<(), VolumeError> {
    if size < expected_bytes {
        return Err(data_error(
            path,
            format!("VTK array holds {size} bytes but the extent needs {expected_bytes}"),
        ));
    }
    Ok(())
}

fn truncated(path: &Path, what: &str) -> VolumeError {
    data_error(path, format!("VTK data block ends inside its {what}"))
}

/// Reads one binary block: a size header followed by the data, or for zlib data a block
/// table (count, block size, last block size, compressed sizes) followed by the blocks.
pub(super) fn read_block(
    bytes: &[u8],
    word: usize,
    endian: Endian,
    compressed: bool,
    expected_bytes: u64,
    path: &Path,
) -> Result<Vec<u8>, VolumeError> {
    if !compressed {
        let size = header_word(bytes, 0, word, endian).ok_or_else(|| truncated(path, "size header"))?;
        check_array_size(size, expected_bytes, path)?;
        let data = bytes.get(word..).unwrap_or(&[]);
        let n = (expected_bytes as usize).min(data.len());
        return Ok(data[..n].to_vec());
    }
    let (blocks, block_size, _last, sizes) = block_table(bytes, word, endian, path)?;
    inflate_blocks(bytes, word * (3 + blocks), &sizes, block_size, expected_bytes, path)
}

fn block_table(
    bytes: &[u8],
    word: usize,
    endian: Endian,
    path: &Path,
) -> Result<(usize, u64, u64, Vec<u64>), VolumeError> {
    let w = |i: usize| header_word(bytes, i * word, word, endian).ok_or_else(|| truncated(path, "block table"));
    let blocks = w(0)?;
    // Each block needs at least one header word, so a count beyond the input is a lie.
    if blocks > (bytes.len() / word) as u64 {
        return Err(truncated(path, "block table"));
    }
    let blocks = blocks as usize;
    let sizes = (0..blocks).map(|i| w(3 + i)).collect::<Result<Vec<_>, _>>()?;
    Ok((blocks, w(1)?, w(2)?, sizes))
}

/// Inflates the zlib blocks of `sizes` bytes each that follow one another in `data` from byte
/// `start` on.
fn inflate_blocks(
    data: &[u8],
    start: usize,
    sizes: &[u64],
    block_size: u64,
    expected_bytes: u64,
    path: &Path,
) -> Result<Vec<u8>, VolumeError> {
    let mut out = Vec::with_capacity((expected_bytes as usize).min(crate::volume::read::UNVERIFIED_RESERVE * 4));
    let mut at = start;
    for &size in sizes {
        let end = at
            .checked_add(size as usize)
            .filter(|e| *e <= data.len())
            .ok_or_else(|| truncated(path, "compressed blocks"))?;
        inflate_into(&data[at..end], block_size, expected_bytes, &mut out, path)?;
        at = end;
    }
    Ok(out)
}

/// Inflates one zlib block, never producing more than `block_size` bytes nor more in total
/// than the array needs.
fn inflate_into(
    block: &[u8],
    block_size: u64,
    expected: u64,
    out: &mut Vec<u8>,
    path: &Path,
) -> Result<(), VolumeError> {
    let room = expected.saturating_sub(out.len() as u64).min(block_size.max(1));
    ZlibDecoder::new(block)
        .take(room)
        .read_to_end(out)
        .map_err(|e| data_error(path, format!("zlib decompression failed: {e}")))?;
    Ok(())
}

/// Base64 text of one block. VTK encodes the header separately from the data, so the header
/// is decoded from its own padded group first.
pub(super) fn decode_base64_block(
    text: &[u8],
    word: usize,
    endian: Endian,
    compressed: bool,
    expected_bytes: u64,
    path: &Path,
) -> Result<Vec<u8>, VolumeError> {
    let clean: Vec<u8> = text.iter().copied().filter(|b| !b.is_ascii_whitespace()).collect();
    let b64 = |chunk: &[u8]| {
        base64::engine::general_purpose::STANDARD
            .decode(chunk)
            .map_err(|e| data_error(path, format!("invalid base64: {e}")))
    };
    let header_chars = |bytes: usize| bytes.div_ceil(3).saturating_mul(4);
    let first = header_chars(word * if compressed { 3 } else { 1 });
    let head = b64(clean.get(..first).ok_or_else(|| truncated(path, "header"))?)?;
    if !compressed {
        let size = header_word(&head, 0, word, endian).ok_or_else(|| truncated(path, "size header"))?;
        check_array_size(size, expected_bytes, path)?;
        // Bound the text decoded to what the array needs.
        let data_chars = header_chars(expected_bytes as usize).min(clean.len() - first);
        let mut data = b64(&clean[first..first + data_chars])?;
        data.truncate(expected_bytes as usize);
        return Ok(data);
    }
    let blocks = header_word(&head, 0, word, endian).ok_or_else(|| truncated(path, "block table"))?;
    if blocks > clean.len() as u64 {
        return Err(truncated(path, "block table"));
    }
    let table_chars = header_chars(word * (3 + blocks as usize));
    let table = b64(clean.get(..table_chars).ok_or_else(|| truncated(path, "block table"))?)?;
    let (_, block_size, _, sizes) = block_table(&table, word, endian, path)?;
    let total = sizes.iter().fold(0u64, |sum, &s| sum.saturating_add(s));
    let data_chars = header_chars(usize::try_from(total).unwrap_or(usize::MAX));
    let payload = b64(clean
        .get(table_chars..table_chars.saturating_add(data_chars))
        .ok_or_else(|| truncated(path, "compressed blocks"))?)?;
    inflate_blocks(&payload, 0, &sizes, block_size, expected_bytes, path)
}
