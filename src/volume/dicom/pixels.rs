//! The stored samples of one frame as numbers: native pixel data read directly (1-bit
//! segmentations, 8/16/32-bit integers, float and double pixel data), encapsulated pixel data
//! decoded by dicom-pixeldata's pure-Rust codecs. Bits above BitsStored are masked off and
//! signed values sign-extended from their top stored bit; colour images become luminance
//! (Rec. 601 weights, which is the Y of YBR). Rescale is applied by the caller.

use std::borrow::Cow;
use std::path::Path;

use dicom_dictionary_std::tags;
use dicom_pixeldata::PixelDecoder;

use super::frames::PixelFormat;
use super::header_error;
use super::parse::Object;
use crate::volume::VolumeError;

/// Luminance weights of R, G and B (ITU-R BT.601), the definition of Y in YBR_FULL.
const LUMA: [f32; 3] = [0.299, 0.587, 0.114];

/// The samples of frame `k`, one value per pixel (row by row).
pub(crate) fn frame_values(obj: &Object, format: &PixelFormat, k: usize, path: &Path) -> Result<Vec<f32>, VolumeError> {
    let pixels = obj
        .get(tags::PIXEL_DATA)
        .or_else(|| obj.get(tags::FLOAT_PIXEL_DATA))
        .or_else(|| obj.get(tags::DOUBLE_FLOAT_PIXEL_DATA))
        .ok_or_else(|| header_error(path, "no pixel data"))?;
    let pixel_count = format.rows * format.columns;
    if let Some(fragments) = pixels.value().fragments() {
        if obj.meta().transfer_syntax().trim_end_matches('\0') == RLE_LOSSLESS {
            // Decoded here: dicom-rs's RLE decoder handles only 8 and 16 bits (RT dose grids
            // are often 32-bit) and panics on a segment shorter than the image.
            let fragment = fragments
                .get(k)
                .ok_or_else(|| header_error(path, format!("RLE pixel data has no fragment for frame {}", k + 1)))?;
            let bytes_per_sample = usize::from(format.bits_allocated / 8);
            if !matches!(bytes_per_sample, 1 | 2 | 4) || format.bits_allocated % 8 != 0 {
                return Err(header_error(
                    path,
                    format!("RLE with BitsAllocated {}", format.bits_allocated),
                ));
            }
            let bytes = rle_frame(fragment, pixel_count, format.samples, bytes_per_sample)
                .map_err(|m| header_error(path, format!("RLE pixel data of frame {}: {m}", k + 1)))?;
            let interleaved = PixelFormat {
                planar: 0,
                ..format.clone()
            };
            return values(&bytes, &interleaved, 0, pixel_count, path);
        }
        if JPEG_2000.contains(&obj.meta().transfer_syntax().trim_end_matches('\0')) {
            for fragment in fragments {
                check_j2k_size(fragment, format).map_err(|m| header_error(path, m))?;
            }
        }
        let frame = u32::try_from(k).map_err(|_| header_error(path, "frame index out of range"))?;
        // A codec that panics on malformed data becomes an error naming the file.
        let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| obj.decode_pixel_data_frame(frame)))
            .map_err(|_| {
                header_error(
                    path,
                    format!(
                        "the {} decoder failed on this pixel data",
                        syntax_name(obj.meta().transfer_syntax())
                    ),
                )
            })?
            .map_err(|e| {
                header_error(
                    path,
                    format!(
                        "cannot decode {} pixel data: {}",
                        syntax_name(obj.meta().transfer_syntax()),
                        error_chain(&e)
                    ),
                )
            })?;
        // The codecs hand back interleaved RGB for colour and little-endian samples.
        let decoded_format = PixelFormat {
            bits_allocated: decoded.bits_allocated(),
            samples: usize::from(decoded.samples_per_pixel()),
            photometric: decoded.photometric_interpretation().as_str().to_string(),
            planar: 0,
            ..format.clone()
        };
        return values(decoded.data(), &decoded_format, 0, pixel_count, path);
    }
    let bytes: Cow<[u8]> = pixels
        .to_bytes()
        .map_err(|e| header_error(path, format!("pixel data: {e}")))?;
    values(&bytes, format, k, pixel_count, path)
}

const RLE_LOSSLESS: &str = "1.2.840.10008.1.2.5";

/// JPEG 2000 and High-Throughput JPEG 2000 syntaxes.
const JPEG_2000: [&str; 7] = [
    "1.2.840.10008.1.2.4.90",
    "1.2.840.10008.1.2.4.91",
    "1.2.840.10008.1.2.4.92",
    "1.2.840.10008.1.2.4.93",
    "1.2.840.10008.1.2.4.201",
    "1.2.840.10008.1.2.4.202",
    "1.2.840.10008.1.2.4.203",
];

/// The image a JPEG 2000 codestream declares in its SIZ marker must fit the DICOM image:
/// dicom-rs writes the decoded components into a buffer of Rows × Columns × samples without
/// checking, and panics on a larger codestream (found by fuzzing).
fn check_j2k_size(fragment: &[u8], f: &PixelFormat) -> Result<(), String> {
    // SOC then SIZ; a JP2 wrapper puts the codestream a little later.
    let head = &fragment[..fragment.len().min(4096)];
    let Some(at) = head.windows(4).position(|w| w == [0xFF, 0x4F, 0xFF, 0x51]) else {
        return Ok(());
    };
    let word = |o: usize| -> Option<u32> {
        let b = fragment.get(at + 4 + o..at + 8 + o)?;
        Some(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (Some(x), Some(y), Some(x0), Some(y0)) = (word(4), word(8), word(12), word(16)) else {
        return Err("JPEG 2000 SIZ marker is truncated".into());
    };
    let components = fragment
        .get(at + 40..at + 42)
        .map(|b| usize::from(u16::from_be_bytes([b[0], b[1]])))
        .ok_or("JPEG 2000 SIZ marker is truncated")?;
    let (w, h) = (x.saturating_sub(x0) as usize, y.saturating_sub(y0) as usize);
    if w * h > f.rows * f.columns || components > f.samples {
        return Err(format!(
            "the JPEG 2000 codestream holds {w}×{h} pixels of {components} components, but the image is {}×{} of {}",
            f.columns, f.rows, f.samples
        ));
    }
    Ok(())
}

/// Decodes one RLE Lossless frame (DICOM PS3.5 Annex G) into interleaved little-endian
/// samples: a 64-byte header of segment offsets, then one PackBits segment per byte plane,
/// most significant byte first, for each sample.
fn rle_frame(fragment: &[u8], pixels: usize, samples: usize, bytes_per_sample: usize) -> Result<Vec<u8>, String> {
    let word = |i: usize| -> Option<usize> {
        let b = fragment.get(4 * i..4 * i + 4)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    let segments = word(0).ok_or("no RLE header")?;
    let planes = samples * bytes_per_sample;
    if segments != planes || planes > 15 {
        return Err(format!("{segments} segments where {planes} byte planes are expected"));
    }
    let mut out = vec![0u8; pixels * planes];
    for s in 0..segments {
        let start = word(1 + s).ok_or("truncated RLE header")?;
        let end = if s + 1 < segments {
            word(2 + s).ok_or("truncated RLE header")?
        } else {
            fragment.len()
        };
        let data = fragment
            .get(start..end.max(start))
            .ok_or("segment offset past the end")?;
        let (sample, byte) = (s / bytes_per_sample, bytes_per_sample - 1 - s % bytes_per_sample);
        let mut at = 0;
        let mut i = 0;
        let mut put = |i: &mut usize, v: u8| {
            if *i < pixels {
                out[(*i * samples + sample) * bytes_per_sample + byte] = v;
            }
            *i += 1;
        };
        while at < data.len() && i < pixels {
            let n = data[at] as i8;
            at += 1;
            if n >= 0 {
                let run = data
                    .get(at..at + n as usize + 1)
                    .ok_or("literal run past the segment")?;
                for &v in run {
                    put(&mut i, v);
                }
                at += n as usize + 1;
            } else if n != -128 {
                let v = *data.get(at).ok_or("repeat run past the segment")?;
                at += 1;
                for _ in 0..(1 - n as isize) {
                    put(&mut i, v);
                }
            }
        }
        if i < pixels {
            return Err(format!("segment {} decodes to {i} of {pixels} bytes", s + 1));
        }
    }
    Ok(out)
}

/// An error with its sources: "outer: inner: innermost".
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let s_text = s.to_string();
        if !text.contains(&s_text) {
            text.push_str(": ");
            text.push_str(&s_text);
        }
        source = s.source();
    }
    text
}

fn syntax_name(uid: &str) -> String {
    use dicom_transfer_syntax_registry::TransferSyntaxIndex;
    let uid = uid.trim_end_matches('\0');
    match dicom_transfer_syntax_registry::TransferSyntaxRegistry.get(uid) {
        Some(ts) => format!("{} ({uid})", ts.name()),
        None => uid.to_string(),
    }
}

/// Frame `k` of native samples in `bytes` (little endian, as dicom-rs holds them in memory).
fn values(bytes: &[u8], f: &PixelFormat, k: usize, pixel_count: usize, path: &Path) -> Result<Vec<f32>, VolumeError> {
    // Native 4:2:2 stores two samples per pixel (Y1 Y2 Cb Cr for each pair).
    let subsampled = f.samples == 3 && f.photometric == "YBR_FULL_422";
    let samples_per_frame = pixel_count * if subsampled { 2 } else { f.samples };
    let bits = usize::from(f.bits_allocated);
    // Bits of a frame; 1-bit frames follow one another without padding.
    let frame_bits = samples_per_frame * bits;
    let start_bit = k * frame_bits;
    let end_byte = (start_bit + frame_bits).div_ceil(8);
    if end_byte > bytes.len() {
        return Err(VolumeError::Truncated {
            kind: "DICOM pixel data in",
            path: path.to_path_buf(),
            expected_bytes: end_byte as u64,
            actual_bytes: bytes.len() as u64,
            layout: format!(
                "frame {} of {}×{}, {} sample(s) of {} bits",
                k + 1,
                f.columns,
                f.rows,
                f.samples,
                f.bits_allocated
            ),
        });
    }
    let raw: Vec<f32> = match (bits, f.float_bits) {
        (1, _) => (0..samples_per_frame)
            .map(|i| {
                let bit = start_bit + i;
                f32::from((bytes[bit / 8] >> (bit % 8)) & 1)
            })
            .collect(),
        (32, Some(_)) => bytes[start_bit / 8..end_byte]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        (64, _) => bytes[start_bit / 8..end_byte]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])) as f32)
            .collect(),
        (8 | 16 | 32, None) => {
            let width = bits / 8;
            let stored = u32::from(f.bits_stored.clamp(1, f.bits_allocated));
            let shift = u32::from(f.high_bit + 1).saturating_sub(stored).min(31);
            let mask = if stored >= 32 { u32::MAX } else { (1u32 << stored) - 1 };
            bytes[start_bit / 8..end_byte]
                .chunks_exact(width)
                .map(|c| {
                    let word = match c {
                        [a] => u32::from(*a),
                        [a, b] => u32::from(u16::from_le_bytes([*a, *b])),
                        [a, b, c, d] => u32::from_le_bytes([*a, *b, *c, *d]),
                        _ => 0,
                    };
                    let v = (word >> shift) & mask;
                    if f.signed && stored < 32 && v & (1 << (stored - 1)) != 0 {
                        // Two's complement: extend the top stored bit.
                        (v as i64 - (1i64 << stored)) as f32
                    } else if f.signed && stored == 32 {
                        v as i32 as f32
                    } else {
                        v as f32
                    }
                })
                .collect()
        }
        _ => {
            return Err(header_error(
                path,
                format!("BitsAllocated {} is not supported (1, 8, 16, 32)", f.bits_allocated),
            ))
        }
    };
    Ok(if f.samples == 3 {
        luminance(&raw, f, pixel_count)
    } else {
        raw
    })
}

/// One luminance value per pixel of three-sample data.
fn luminance(raw: &[f32], f: &PixelFormat, n: usize) -> Vec<f32> {
    let ybr = f.photometric.starts_with("YBR");
    if f.photometric == "YBR_FULL_422" {
        // Each pair of pixels is stored as Y1 Y2 Cb Cr: the Ys are the luminance.
        return raw.chunks(4).flat_map(|c| c.iter().take(2).copied()).take(n).collect();
    }
    let sample = |pixel: usize, channel: usize| {
        if f.planar == 1 {
            raw[channel * n + pixel]
        } else {
            raw[pixel * 3 + channel]
        }
    };
    (0..n)
        .map(|p| {
            if ybr {
                sample(p, 0)
            } else {
                (0..3).map(|c| LUMA[c] * sample(p, c)).sum()
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::rle_frame;

    fn fragment(segments: &[&[u8]]) -> Vec<u8> {
        let mut header = [0u32; 16];
        header[0] = segments.len() as u32;
        let mut at = 64u32;
        for (i, s) in segments.iter().enumerate() {
            header[1 + i] = at;
            at += s.len() as u32;
        }
        let mut out: Vec<u8> = header.iter().flat_map(|w| w.to_le_bytes()).collect();
        out.extend(segments.concat());
        out
    }

    #[test]
    fn rle_segments_decode_most_significant_byte_first() {
        // Two pixels of 16 bits: 0x0102 and 0x0304. High bytes: literal run "1 3"; low
        // bytes: "2", then "4" as a repeat run of one.
        let f = fragment(&[&[1, 1, 3], &[0, 2, 0, 4]]);
        assert_eq!(rle_frame(&f, 2, 1, 2).unwrap(), vec![2, 1, 4, 3]);
        // Repeat runs: -3 repeats the next byte four times.
        let f = fragment(&[&[(-3i8) as u8, 9]]);
        assert_eq!(rle_frame(&f, 4, 1, 1).unwrap(), vec![9; 4]);
    }

    #[test]
    fn malformed_rle_fails_without_panicking() {
        // Short segment, literal past the end, wrong segment count, offsets past the end.
        assert!(rle_frame(&fragment(&[&[0, 7]]), 3, 1, 1)
            .unwrap_err()
            .contains("decodes to 1 of 3"));
        assert!(rle_frame(&fragment(&[&[5, 1]]), 3, 1, 1).is_err());
        assert!(rle_frame(&fragment(&[&[0, 1]]), 1, 1, 2)
            .unwrap_err()
            .contains("segments"));
        let mut f = fragment(&[&[0, 1]]);
        f[4..8].copy_from_slice(&9999u32.to_le_bytes());
        assert!(rle_frame(&f, 1, 1, 1).is_err());
        assert!(rle_frame(&[1, 0], 1, 1, 1).is_err());
    }
}
