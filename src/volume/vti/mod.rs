//! VTK XML ImageData (`.vti`): the first point-data array, inline base64 (`format="binary"`)
//! or appended (raw or base64), uncompressed or zlib-compressed (`vtkZLibDataCompressor`;
//! the binary blocks are in [`blocks`]). `format="ascii"` arrays are read too.
//!
//! VTK has no anatomical convention. A `Direction` other than the identity is taken as the
//! direction of each axis in LPS (ITK's and 3D Slicer's convention for files), with `Origin`;
//! the identity, which VTK 9 writes for every image, says nothing about a patient.

mod blocks;
#[cfg(test)]
mod tests;

use std::path::Path;

use glam::DVec3;

use self::blocks::{decode_base64_block, read_block};
use super::meta::{Format, Loaded, VolumeMeta};
use super::orient::PatientFrame;
use super::read::{data_error, io_error, samples_from_bytes, Layout};
use super::{checked_voxel_count, Endian, ScalarType, Volume, VolumeError};

pub(super) fn header_error(path: &Path, message: impl Into<String>) -> VolumeError {
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
    let patient = patient_frame(image.attribute("Direction"), image.attribute("Origin"), path)?;
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
            return finish(layout, spacing, values, patient);
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
    finish(layout, spacing, data, patient)
}

fn finish(
    layout: Layout,
    spacing: [f32; 3],
    data: Vec<f32>,
    patient: Option<PatientFrame>,
) -> Result<Loaded, VolumeError> {
    let mut meta = VolumeMeta::new(Format::Vti, Some(layout.scalar));
    meta.patient = patient;
    Ok(Loaded::new(Volume::new(layout.dims, spacing, data)?, meta))
}

/// The patient frame of a non-identity `Direction` (row-major 3×3: axis i is column i).
fn patient_frame(
    direction: Option<&str>,
    origin: Option<&str>,
    path: &Path,
) -> Result<Option<PatientFrame>, VolumeError> {
    let Some(direction) = direction else {
        return Ok(None);
    };
    let d = parse_numbers::<f64>(direction)
        .filter(|d| d.len() == 9)
        .ok_or_else(|| header_error(path, "Direction must be nine numbers"))?;
    let axes = [0, 1, 2].map(|i| DVec3::new(d[i], d[3 + i], d[6 + i]));
    if axes == [DVec3::X, DVec3::Y, DVec3::Z] {
        return Ok(None);
    }
    let origin = match origin.and_then(parse_numbers::<f64>).as_deref() {
        Some(&[x, y, z]) => DVec3::new(x, y, z),
        _ => DVec3::ZERO,
    };
    PatientFrame::new(axes, origin, "VTK ImageData Direction")
        .map(Some)
        .ok_or_else(|| header_error(path, format!("Direction {direction} is degenerate")))
}

pub(super) fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
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
