//! VTK XML ImageData (`.vti`): the first point-data array, inline base64 (`format="binary"`)
//! or appended (raw or base64), uncompressed or zlib-compressed (`vtkZLibDataCompressor`).
//! `format="ascii"` arrays are read too.

use std::io::Read;
use std::path::Path;

use base64::Engine as _;
use flate2::read::ZlibDecoder;

use super::meta::{Format, Loaded, VolumeMeta};
use super::read::{data_error, io_error, samples_from_bytes, Layout};
use super::{checked_voxel_count, Endian, ScalarType, Volume, VolumeError};

fn header_error(path: &Path, message: impl Into<String>) -> VolumeError {
    super::read::format_header_error(path, "VTK ImageData", message)
}

/// How one array's bytes are stored.
struct ArrayDesc {
    scalar: ScalarType,
    format: String,
    offset: u64,
    components: usize,
    /// Inline text (base64 or ascii), for non-appended arrays.
    text: String,
}

/// Loads a `.vti` file.
pub fn load_vti(path: &Path) -> Result<Loaded, VolumeError> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    // Appended raw data is not XML; parse only the markup before it.
    let appended_at = find(&bytes, b"<AppendedData");
    let markup_end = appended_at.unwrap_or(bytes.len());
    let mut markup = std::str::from_utf8(&bytes[..markup_end])
        .map_err(|_| header_error(path, "the XML part is not valid UTF-8"))?
        .to_string();
    if appended_at.is_some() {
        markup.push_str("</VTKFile>");
    }
    let doc = roxmltree::Document::parse(&markup).map_err(|e| header_error(path, format!("invalid XML: {e}")))?;
    let root = doc.root_element();
    if root.tag_name().name() != "VTKFile" || root.attribute("type") != Some("ImageData") {
        return Err(header_error(path, "not a VTKFile of type ImageData"));
    }
    let endian = match root.attribute("byte_order").unwrap_or("LittleEndian") {
        "LittleEndian" => Endian::Little,
        "BigEndian" => Endian::Big,
        other => return Err(header_error(path, format!("unknown byte_order '{other}'"))),
    };
    let header_type = match root.attribute("header_type").unwrap_or("UInt32") {
        "UInt32" => 4usize,
        "UInt64" => 8,
        other => return Err(header_error(path, format!("unknown header_type '{other}'"))),
    };
    let compressed = match root.attribute("compressor") {
        None | Some("") => false,
        Some("vtkZLibDataCompressor") => true,
        Some(other) => {
            return Err(header_error(
                path,
                format!("compressor '{other}' is not supported (only zlib)"),
            ))
        }
    };
    let image = root
        .children()
        .find(|n| n.has_tag_name("ImageData"))
        .ok_or_else(|| header_error(path, "no ImageData element"))?;
    let extent = parse_numbers::<i64>(image.attribute("WholeExtent").unwrap_or(""))
        .filter(|e| e.len() == 6)
        .ok_or_else(|| header_error(path, "WholeExtent must be six integers"))?;
    let mut dims = [0usize; 3];
    for axis in 0..3 {
        let n = extent[2 * axis + 1]
            .checked_sub(extent[2 * axis])
            .and_then(|d| d.checked_add(1));
        dims[axis] = n
            .filter(|n| *n >= 1)
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| header_error(path, format!("WholeExtent {extent:?} has an empty or inverted axis")))?;
    }
    checked_voxel_count(dims)?;
    let spacing_values = parse_numbers::<f32>(image.attribute("Spacing").unwrap_or("1 1 1"))
        .filter(|s| s.len() == 3)
        .ok_or_else(|| header_error(path, "Spacing must be three numbers"))?;
    let spacing = [0, 1, 2].map(|a| spacing_values[a].abs());
    let array = image
        .descendants()
        .find(|n| n.has_tag_name("DataArray") && n.ancestors().any(|a| a.has_tag_name("PointData")))
        .ok_or_else(|| header_error(path, "no point-data DataArray (cell data is not supported)"))?;
    let desc = ArrayDesc {
        scalar: parse_type(array.attribute("type").unwrap_or("")).ok_or_else(|| {
            header_error(
                path,
                format!(
                    "DataArray type '{}' is not supported",
                    array.attribute("type").unwrap_or("")
                ),
            )
        })?,
        format: array.attribute("format").unwrap_or("ascii").to_string(),
        offset: array
            .attribute("offset")
            .unwrap_or("0")
            .trim()
            .parse()
            .map_err(|_| header_error(path, "DataArray offset is not an integer"))?,
        components: array
            .attribute("NumberOfComponents")
            .unwrap_or("1")
            .trim()
            .parse()
            .map_err(|_| header_error(path, "NumberOfComponents is not an integer"))?,
        text: array.text().unwrap_or("").to_string(),
    };
    if desc.components != 1 {
        return Err(header_error(
            path,
            format!("{} components per point: only scalar arrays load", desc.components),
        ));
    }
    let layout = Layout {
        dims,
        scalar: desc.scalar,
        endian,
    };
    let (count, expected_bytes) = layout.sizes()?;
    let blob = match desc.format.as_str() {
        "ascii" => {
            let values: Vec<f32> = desc
                .text
                .split_whitespace()
                .take(count + 1)
                .map(|t| {
                    t.parse::<f32>()
                        .map_err(|_| data_error(path, format!("ascii value '{t}' is not a number")))
                })
                .collect::<Result<_, _>>()?;
            if values.len() != count {
                return Err(data_error(
                    path,
                    format!("ascii array has {} values but the extent needs {count}", values.len()),
                ));
            }
            return finish(layout, spacing, values);
        }
        "binary" => decode_base64_block(
            desc.text.as_bytes(),
            header_type,
            endian,
            compressed,
            expected_bytes,
            path,
        )?,
        "appended" => {
            let at = appended_at.ok_or_else(|| header_error(path, "format=\"appended\" but no AppendedData"))?;
            let tag_end =
                find(&bytes[at..], b">").ok_or_else(|| header_error(path, "unterminated AppendedData tag"))? + at;
            let tag = String::from_utf8_lossy(&bytes[at..tag_end]).to_string();
            let underscore = find(&bytes[tag_end..], b"_")
                .ok_or_else(|| header_error(path, "AppendedData has no '_' marker"))?
                + tag_end
                + 1;
            let start = usize::try_from(desc.offset)
                .ok()
                .and_then(|o| underscore.checked_add(o))
                .filter(|s| *s <= bytes.len())
                .ok_or_else(|| {
                    header_error(
                        path,
                        format!("DataArray offset {} lies past the end of the file", desc.offset),
                    )
                })?;
            if tag.contains("encoding=\"base64\"") {
                let end = find(&bytes[start..], b"<").map_or(bytes.len(), |e| e + start);
                decode_base64_block(
                    &bytes[start..end],
                    header_type,
                    endian,
                    compressed,
                    expected_bytes,
                    path,
                )?
            } else {
                read_block(&bytes[start..], header_type, endian, compressed, expected_bytes, path)?
            }
        }
        other => return Err(header_error(path, format!("DataArray format '{other}' is unknown"))),
    };
    let data = samples_from_bytes(&blob, path, layout, "VTK array in")?;
    finish(layout, spacing, data)
}

fn finish(layout: Layout, spacing: [f32; 3], data: Vec<f32>) -> Result<Loaded, VolumeError> {
    Ok(Loaded::new(
        Volume::new(layout.dims, spacing, data)?,
        VolumeMeta::new(Format::Vti, Some(layout.scalar)),
    ))
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

fn parse_numbers<T: std::str::FromStr>(text: &str) -> Option<Vec<T>> {
    text.split_whitespace().map(|t| t.parse().ok()).collect()
}

fn parse_type(name: &str) -> Option<ScalarType> {
    Some(match name {
        "UInt8" | "unsigned_char" => ScalarType::U8,
        "Int8" | "char" => ScalarType::I8,
        "UInt16" | "unsigned_short" => ScalarType::U16,
        "Int16" | "short" => ScalarType::I16,
        "UInt32" | "unsigned_int" => ScalarType::U32,
        "Int32" | "int" => ScalarType::I32,
        "Float32" | "float" => ScalarType::F32,
        "Float64" | "double" => ScalarType::F64,
        _ => return None,
    })
}

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
fn read_block(
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
    let mut out = Vec::with_capacity((expected_bytes as usize).min(super::read::UNVERIFIED_RESERVE * 4));
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
fn decode_base64_block(
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

#[cfg(test)]
mod tests {
    use std::io::Write;

    use flate2::write::ZlibEncoder;
    use flate2::Compression;

    use super::super::test_support::{encode_values, test_values, ScratchDir};
    use super::*;

    fn type_name(s: ScalarType) -> &'static str {
        match s {
            ScalarType::U8 => "UInt8",
            ScalarType::I8 => "Int8",
            ScalarType::U16 => "UInt16",
            ScalarType::I16 => "Int16",
            ScalarType::U32 => "UInt32",
            ScalarType::I32 => "Int32",
            ScalarType::F32 => "Float32",
            ScalarType::F64 => "Float64",
        }
    }

    fn word(v: u64, w: usize, endian: Endian) -> Vec<u8> {
        match (w, endian) {
            (4, Endian::Little) => (v as u32).to_le_bytes().to_vec(),
            (4, Endian::Big) => (v as u32).to_be_bytes().to_vec(),
            (_, Endian::Little) => v.to_le_bytes().to_vec(),
            (_, Endian::Big) => v.to_be_bytes().to_vec(),
        }
    }

    /// (header, data) of one VTK block, split into two zlib blocks when compressed.
    fn block(data: &[u8], w: usize, endian: Endian, compressed: bool) -> (Vec<u8>, Vec<u8>) {
        if !compressed {
            return (word(data.len() as u64, w, endian), data.to_vec());
        }
        let block_size = data.len().div_ceil(2).max(1);
        let chunks: Vec<Vec<u8>> = data
            .chunks(block_size)
            .map(|c| {
                let mut z = ZlibEncoder::new(Vec::new(), Compression::fast());
                z.write_all(c).unwrap();
                z.finish().unwrap()
            })
            .collect();
        let last = data.len() - block_size * (chunks.len() - 1);
        let mut header = word(chunks.len() as u64, w, endian);
        header.extend(word(block_size as u64, w, endian));
        header.extend(word(last as u64, w, endian));
        for c in &chunks {
            header.extend(word(c.len() as u64, w, endian));
        }
        (header, chunks.concat())
    }

    fn vti(
        scalar: ScalarType,
        n: usize,
        endian: Endian,
        w: usize,
        compressed: bool,
        mode: &str,
        data: &[u8],
    ) -> Vec<u8> {
        let order = if endian == Endian::Big {
            "BigEndian"
        } else {
            "LittleEndian"
        };
        let header_type = if w == 8 { "UInt64" } else { "UInt32" };
        let compressor = if compressed {
            " compressor=\"vtkZLibDataCompressor\""
        } else {
            ""
        };
        let (head, body) = block(data, w, endian, compressed);
        let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
        let format = if mode == "binary" { "binary" } else { "appended" };
        let inline = if mode == "binary" {
            format!("{}{}", b64(&head), b64(&body))
        } else {
            String::new()
        };
        let mut out = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"{order}\" \
             header_type=\"{header_type}\"{compressor}>\n<ImageData WholeExtent=\"0 {} 0 0 0 0\" Origin=\"0 0 0\" \
             Spacing=\"0.5 1 4\">\n<Piece Extent=\"0 {} 0 0 0 0\"><PointData Scalars=\"v\">\
             <DataArray type=\"{}\" Name=\"v\" format=\"{format}\" offset=\"0\">{inline}</DataArray>\
             </PointData></Piece></ImageData>\n",
            n - 1,
            n - 1,
            type_name(scalar)
        )
        .into_bytes();
        match mode {
            "raw" => {
                out.extend(b"<AppendedData encoding=\"raw\">\n_");
                out.extend(&head);
                out.extend(&body);
                out.extend(b"\n</AppendedData>\n</VTKFile>\n");
            }
            "base64" => {
                out.extend(b"<AppendedData encoding=\"base64\">\n_");
                out.extend(format!("{}{}", b64(&head), b64(&body)).as_bytes());
                out.extend(b"\n</AppendedData>\n</VTKFile>\n");
            }
            _ => out.extend(b"</VTKFile>\n"),
        }
        out
    }

    #[test]
    fn round_trips_types_byte_orders_encodings_and_zlib() {
        let dir = ScratchDir::new("vti");
        for scalar in ScalarType::ALL {
            for endian in [Endian::Little, Endian::Big] {
                for w in [4usize, 8] {
                    for compressed in [false, true] {
                        for mode in ["raw", "base64", "binary"] {
                            let values = test_values(scalar);
                            let data = encode_values(&values, scalar, endian);
                            let name = format!("{scalar}-{endian:?}-{w}-{compressed}-{mode}.vti");
                            let p = dir.write(&name, &vti(scalar, values.len(), endian, w, compressed, mode, &data));
                            let l = load_vti(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
                            let expected: Vec<f32> = values.iter().map(|&v| v as f32).collect();
                            assert_eq!(l.volume.data, expected, "{name}");
                            assert_eq!(l.volume.spacing, [0.5, 1.0, 4.0]);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn malformed_files_fail_clearly() {
        let dir = ScratchDir::new("vti-bad");
        let data = encode_values(&[1.0; 8], ScalarType::F32, Endian::Little);
        let good = vti(ScalarType::F32, 8, Endian::Little, 4, false, "raw", &data);
        let text = String::from_utf8_lossy(&good).to_string();
        let cut = good.len() - 30;
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            ("truncated", good[..cut].to_vec(), "need 32 bytes"),
            (
                "absurd",
                text.replace(
                    "WholeExtent=\"0 7 0 0 0 0\"",
                    "WholeExtent=\"0 999999 0 999999 0 999999\"",
                )
                .into_bytes(),
                "exceed the limit",
            ),
            (
                "type",
                text.replace("Float32", "Complex").into_bytes(),
                "type 'Complex'",
            ),
            (
                "lying-size",
                {
                    let mut b = good.clone();
                    let at = find(&b, b"\n_").unwrap() + 2;
                    b[at..at + 4].copy_from_slice(&8u32.to_le_bytes());
                    b
                },
                "holds 8 bytes",
            ),
            (
                "compressor",
                text.replace(
                    "header_type=\"UInt32\"",
                    "header_type=\"UInt32\" compressor=\"vtkLZ4DataCompressor\"",
                )
                .into_bytes(),
                "LZ4",
            ),
            (
                "not-xml",
                b"<VTKFile type=\"ImageData\"><ImageData".to_vec(),
                "invalid XML",
            ),
            (
                "extent",
                text.replace("WholeExtent=\"0 7", "WholeExtent=\"5 2").into_bytes(),
                "inverted",
            ),
            ("garbage", vec![0xFFu8; 64], "UTF-8"),
        ];
        for (name, bytes, expected) in cases {
            let p = dir.write(&format!("{name}.vti"), &bytes);
            let err = load_vti(&p).expect_err(name).to_string();
            assert!(err.contains(expected), "{name}: '{err}' should mention '{expected}'");
        }
        // A zlib block table claiming an absurd block count.
        let z = vti(ScalarType::F32, 8, Endian::Little, 4, true, "raw", &data);
        let mut b = z.clone();
        let at = find(&b, b"\n_").unwrap() + 2;
        b[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = load_vti(&dir.write("blocks.vti", &b)).expect_err("blocks").to_string();
        assert!(err.contains("block table"), "{err}");
    }
}
