//! Decoding of binary samples of any [`ScalarType`] into f32, in bounded chunks.

use std::io::{self, Read};

use super::raw::{Endian, ScalarType};

/// Samples decoded per read; bounds the scratch buffer independent of the volume size.
const CHUNK_SAMPLES: usize = 1 << 16;

/// Decodes whole samples from `bytes` into f32; a trailing partial sample is ignored.
pub fn decode_samples(bytes: &[u8], scalar: ScalarType, endian: Endian) -> Vec<f32> {
    let mut out = Vec::with_capacity(bytes.len() / scalar.size_bytes());
    decode_into(bytes, scalar, endian, &mut out);
    out
}

/// Reads and decodes up to `count` samples in bounded chunks, stopping early at end of input.
/// Returns the samples and the number of bytes consumed; callers compare against `count`.
/// `reserve` is the capacity allocated up front: pass `count` only when the input size has
/// already been checked, so unverified streams grow memory only as data actually arrives.
pub(crate) fn read_samples<R: Read>(
    reader: &mut R,
    count: usize,
    scalar: ScalarType,
    endian: Endian,
    reserve: usize,
) -> io::Result<(Vec<f32>, u64)> {
    let size = scalar.size_bytes();
    let mut out = Vec::with_capacity(reserve.min(count));
    let mut buf = vec![0u8; CHUNK_SAMPLES * size];
    let mut bytes_read = 0u64;
    let mut remaining = count;
    while remaining > 0 {
        let want = remaining.min(CHUNK_SAMPLES) * size;
        let got = read_full(reader, &mut buf[..want])?;
        bytes_read += got as u64;
        decode_into(&buf[..got - got % size], scalar, endian, &mut out);
        remaining -= got / size;
        if got < want {
            break;
        }
    }
    Ok((out, bytes_read))
}

/// Fills `buf` unless the input ends first; returns the bytes read.
fn read_full<R: Read>(reader: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

fn decode_into(bytes: &[u8], scalar: ScalarType, endian: Endian, out: &mut Vec<f32>) {
    match scalar {
        ScalarType::U8 => extend::<1>(bytes, endian, out, |a| f32::from(a[0]), |a| f32::from(a[0])),
        ScalarType::I8 => extend::<1>(
            bytes,
            endian,
            out,
            |a| f32::from(i8::from_le_bytes(a)),
            |a| f32::from(i8::from_be_bytes(a)),
        ),
        ScalarType::U16 => extend::<2>(
            bytes,
            endian,
            out,
            |a| f32::from(u16::from_le_bytes(a)),
            |a| f32::from(u16::from_be_bytes(a)),
        ),
        ScalarType::I16 => extend::<2>(
            bytes,
            endian,
            out,
            |a| f32::from(i16::from_le_bytes(a)),
            |a| f32::from(i16::from_be_bytes(a)),
        ),
        ScalarType::U32 => extend::<4>(
            bytes,
            endian,
            out,
            |a| u32::from_le_bytes(a) as f32,
            |a| u32::from_be_bytes(a) as f32,
        ),
        ScalarType::I32 => extend::<4>(
            bytes,
            endian,
            out,
            |a| i32::from_le_bytes(a) as f32,
            |a| i32::from_be_bytes(a) as f32,
        ),
        ScalarType::F32 => extend::<4>(bytes, endian, out, f32::from_le_bytes, f32::from_be_bytes),
        ScalarType::F64 => extend::<8>(
            bytes,
            endian,
            out,
            |a| f64::from_le_bytes(a) as f32,
            |a| f64::from_be_bytes(a) as f32,
        ),
    }
}

fn extend<const N: usize>(
    bytes: &[u8],
    endian: Endian,
    out: &mut Vec<f32>,
    from_le: fn([u8; N]) -> f32,
    from_be: fn([u8; N]) -> f32,
) {
    let convert = match endian {
        Endian::Little => from_le,
        Endian::Big => from_be,
    };
    out.extend(bytes.chunks_exact(N).map(|chunk| {
        let mut sample = [0u8; N];
        sample.copy_from_slice(chunk);
        convert(sample)
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_ignores_partial_trailing_sample() {
        let out = decode_samples(&[1, 0, 2, 0, 9], ScalarType::U16, Endian::Little);
        assert_eq!(out, vec![1.0, 2.0]);
        let out = decode_samples(&[1, 0], ScalarType::U16, Endian::Big);
        assert_eq!(out, vec![256.0]);
    }

    #[test]
    fn read_samples_spans_chunks_and_stops_at_end_of_input() {
        let count = CHUNK_SAMPLES * 2 + 10;
        let bytes: Vec<u8> = (0..count as u32).flat_map(|v| v.to_be_bytes()).collect();
        let mut reader = &bytes[..];
        let (data, read) = read_samples(&mut reader, count, ScalarType::U32, Endian::Big, 0).expect("read");
        assert_eq!(read, bytes.len() as u64);
        assert!(data.iter().enumerate().all(|(i, &v)| v == i as f32));

        let mut short = &bytes[..bytes.len() - 6];
        let (data, read) = read_samples(&mut short, count, ScalarType::U32, Endian::Big, count).expect("read");
        assert_eq!(data.len(), count - 2);
        assert_eq!(read, bytes.len() as u64 - 6);
    }
}
