//! What one DICOM image object says about its frames: pixel format, and for each frame its
//! position, orientation, pixel spacing and rescale. Single-frame files carry these at the top
//! level; enhanced multi-frame objects (CT, MR, PET, segmentations) in the shared and
//! per-frame functional groups; RT dose grids as one position plus the Grid Frame Offset
//! Vector, with the Dose Grid Scaling as the slope.

use std::path::PathBuf;

use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry};
use dicom_core::{Tag, VR};
use dicom_dictionary_std::{tags, StandardDataDictionary};
use dicom_object::InMemDicomObject;
use glam::DVec3;

/// Largest frame count of one object.
const MAX_FRAMES: usize = 1 << 16;

/// How the samples of an image are stored.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct PixelFormat {
    pub rows: usize,
    pub columns: usize,
    pub samples: usize,
    pub bits_allocated: u16,
    pub bits_stored: u16,
    pub high_bit: u16,
    pub signed: bool,
    pub photometric: String,
    /// 1: colour planes one after another (RRR…GGG…BBB) instead of interleaved.
    pub planar: u16,
    /// Float (7FE0,0008) or double float (7FE0,0009) pixel data.
    pub float_bits: Option<u16>,
}

/// Where one frame lies and how its stored values become physical ones.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct FrameGeometry {
    pub position: Option<DVec3>,
    pub orientation: Option<[DVec3; 2]>,
    /// Spacing between rows, then between columns (DICOM order), in mm.
    pub pixel_spacing: Option<[f64; 2]>,
    pub slope: f64,
    pub intercept: f64,
    /// Segmentations: the segment this frame's bits belong to.
    pub segment: Option<i64>,
}

/// One image object: its format, identity and frames.
#[derive(Clone, Debug)]
pub(crate) struct ImageInfo {
    pub path: PathBuf,
    pub format: PixelFormat,
    pub frames: Vec<FrameGeometry>,
    pub modality: String,
    pub series_uid: String,
    pub series_description: String,
    pub series_number: Option<i64>,
    pub instance: i64,
    pub sop_class: String,
    pub slice_thickness: Option<f64>,
    /// Spacing Between Slices (0018,0088), for frames stacked without positions.
    pub spacing_between: Option<f64>,
    /// "Gy" for an RT dose grid, when the file names its units.
    pub units: Option<String>,
    /// How the frames were placed, for the notes (enhanced functional groups, RT dose, …).
    pub layout: &'static str,
}

/// The value of an element some writers stored with VR UN (unknown): text for string VRs,
/// little-endian words for US/SS/UL/SL, following the dictionary.
fn unknown_value(obj: &InMemDicomObject, tag: Tag) -> Option<Result<String, Vec<i64>>> {
    let e = obj.get(tag)?;
    if e.vr() != VR::UN {
        return None;
    }
    let bytes = e.to_bytes().ok()?;
    let vr = StandardDataDictionary.by_tag(tag)?.vr().relaxed();
    Some(match vr {
        VR::US => Err(bytes
            .chunks_exact(2)
            .map(|c| i64::from(u16::from_le_bytes([c[0], c[1]])))
            .collect()),
        VR::SS => Err(bytes
            .chunks_exact(2)
            .map(|c| i64::from(i16::from_le_bytes([c[0], c[1]])))
            .collect()),
        VR::UL => Err(bytes
            .chunks_exact(4)
            .map(|c| i64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]])))
            .collect()),
        VR::SL => Err(bytes
            .chunks_exact(4)
            .map(|c| i64::from(i32::from_le_bytes([c[0], c[1], c[2], c[3]])))
            .collect()),
        _ => Ok(String::from_utf8_lossy(&bytes).into_owned()),
    })
}

pub(crate) fn text(obj: &InMemDicomObject, tag: Tag) -> Option<String> {
    let t = match unknown_value(obj, tag) {
        Some(Ok(t)) => t,
        Some(Err(_)) => return None,
        None => obj.get(tag)?.to_str().ok()?.into_owned(),
    };
    let t = t.trim_matches(|c: char| c == '\0' || c.is_whitespace());
    (!t.is_empty()).then(|| t.to_string())
}

pub(crate) fn floats(obj: &InMemDicomObject, tag: Tag) -> Option<Vec<f64>> {
    let values = match unknown_value(obj, tag) {
        Some(Ok(t)) => t
            .trim_matches(|c: char| c == '\0' || c.is_whitespace())
            .split('\\')
            .map(|v| v.trim().parse::<f64>().ok())
            .collect::<Option<Vec<f64>>>()?,
        Some(Err(words)) => words.into_iter().map(|w| w as f64).collect(),
        None => obj.get(tag)?.to_multi_float64().ok()?,
    };
    (!values.is_empty()).then_some(values)
}

pub(crate) fn int(obj: &InMemDicomObject, tag: Tag) -> Option<i64> {
    match unknown_value(obj, tag) {
        Some(Ok(t)) => t
            .trim_matches(|c: char| c == '\0' || c.is_whitespace())
            .split('\\')
            .next()?
            .trim()
            .parse()
            .ok(),
        Some(Err(words)) => words.first().copied(),
        None => obj.get(tag)?.to_int::<i64>().ok(),
    }
}

/// The first item of sequence `tag`.
fn item(obj: &InMemDicomObject, tag: Tag) -> Option<&InMemDicomObject> {
    obj.get(tag)?.items()?.first()
}

fn vec3(v: &[f64]) -> Option<DVec3> {
    match v {
        [x, y, z] => Some(DVec3::new(*x, *y, *z)),
        _ => None,
    }
}

fn orientation(v: &[f64]) -> Option<[DVec3; 2]> {
    match v {
        [a, b, c, d, e, f] => Some([DVec3::new(*a, *b, *c), DVec3::new(*d, *e, *f)]),
        _ => None,
    }
}

/// Reads the image description of a parsed object that holds pixel data.
pub(crate) fn image_info(obj: &InMemDicomObject, path: PathBuf) -> Result<ImageInfo, String> {
    let u16_of = |tag: Tag| int(obj, tag).and_then(|v| u16::try_from(v).ok());
    let rows = u16_of(tags::ROWS).ok_or("missing Rows")? as usize;
    let columns = u16_of(tags::COLUMNS).ok_or("missing Columns")? as usize;
    if rows == 0 || columns == 0 {
        return Err(format!("image of {columns}×{rows} pixels"));
    }
    let float_bits = if obj.get(tags::FLOAT_PIXEL_DATA).is_some() {
        Some(32)
    } else if obj.get(tags::DOUBLE_FLOAT_PIXEL_DATA).is_some() {
        Some(64)
    } else {
        None
    };
    let bits_allocated = u16_of(tags::BITS_ALLOCATED)
        .or(float_bits)
        .ok_or("missing BitsAllocated")?;
    let bits_stored = u16_of(tags::BITS_STORED).unwrap_or(bits_allocated);
    let format = PixelFormat {
        rows,
        columns,
        samples: u16_of(tags::SAMPLES_PER_PIXEL).unwrap_or(1) as usize,
        bits_allocated,
        bits_stored,
        high_bit: u16_of(tags::HIGH_BIT).unwrap_or(bits_stored.saturating_sub(1)),
        signed: u16_of(tags::PIXEL_REPRESENTATION) == Some(1),
        photometric: text(obj, tags::PHOTOMETRIC_INTERPRETATION).unwrap_or_else(|| "MONOCHROME2".into()),
        planar: u16_of(tags::PLANAR_CONFIGURATION).unwrap_or(0),
        float_bits,
    };
    if !matches!(format.samples, 1 | 3) {
        return Err(format!("{} samples per pixel (1 or 3 load)", format.samples));
    }
    if !matches!(format.bits_allocated, 1 | 8 | 16 | 32 | 64) || format.bits_stored == 0 {
        return Err(format!(
            "BitsAllocated {} with BitsStored {} is not supported (1, 8, 16, 32)",
            format.bits_allocated, format.bits_stored
        ));
    }
    let count = int(obj, tags::NUMBER_OF_FRAMES).unwrap_or(1).max(1);
    let count = usize::try_from(count)
        .ok()
        .filter(|c| *c <= MAX_FRAMES)
        .ok_or_else(|| format!("NumberOfFrames {count} is out of range"))?;
    let top = top_geometry(obj);
    let shared = item(obj, tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE);
    let per_frame = obj
        .get(tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE)
        .and_then(|e| e.items())
        .unwrap_or(&[]);
    let offsets = floats(obj, tags::GRID_FRAME_OFFSET_VECTOR);
    let (frames, layout) = if shared.is_some() || !per_frame.is_empty() {
        let frames = (0..count)
            .map(|k| functional_geometry(per_frame.get(k), shared, &top))
            .collect();
        (frames, "enhanced multi-frame (functional groups)")
    } else if let (Some(offsets), true) = (offsets.as_ref(), count > 1) {
        if offsets.len() != count {
            return Err(format!(
                "GridFrameOffsetVector has {} entries for {count} frames",
                offsets.len()
            ));
        }
        (dose_geometry(&top, offsets), "RT dose grid (Grid Frame Offset Vector)")
    } else if count > 1 {
        // Cine, ultrasound loops, multi-frame secondary captures: frames without positions.
        let frame = FrameGeometry {
            position: None,
            ..top.clone()
        };
        (vec![frame; count], "frames without positions")
    } else {
        (vec![top.clone()], "single frame")
    };
    let mut info = ImageInfo {
        path,
        format,
        frames,
        modality: text(obj, tags::MODALITY).unwrap_or_default(),
        series_uid: text(obj, tags::SERIES_INSTANCE_UID).unwrap_or_default(),
        series_description: text(obj, tags::SERIES_DESCRIPTION).unwrap_or_default(),
        series_number: int(obj, tags::SERIES_NUMBER),
        instance: int(obj, tags::INSTANCE_NUMBER).unwrap_or(0),
        sop_class: text(obj, tags::SOP_CLASS_UID).unwrap_or_default(),
        slice_thickness: floats(obj, tags::SLICE_THICKNESS).and_then(|v| v.first().copied()),
        spacing_between: floats(obj, tags::SPACING_BETWEEN_SLICES).and_then(|v| v.first().copied()),
        units: None,
        layout,
    };
    if let Some(scaling) = floats(obj, tags::DOSE_GRID_SCALING).and_then(|v| v.first().copied()) {
        for f in &mut info.frames {
            f.slope *= scaling;
        }
        info.units = text(obj, tags::DOSE_UNITS).map(|u| match u.as_str() {
            "GY" => "Gy".to_string(),
            other => other.to_string(),
        });
    }
    Ok(info)
}

fn top_geometry(obj: &InMemDicomObject) -> FrameGeometry {
    let spacing = floats(obj, tags::PIXEL_SPACING)
        .or_else(|| floats(obj, tags::IMAGER_PIXEL_SPACING))
        .or_else(|| ultrasound_spacing(obj));
    FrameGeometry {
        position: floats(obj, tags::IMAGE_POSITION_PATIENT).and_then(|v| vec3(&v)),
        orientation: floats(obj, tags::IMAGE_ORIENTATION_PATIENT).and_then(|v| orientation(&v)),
        pixel_spacing: spacing.and_then(|v| match v[..] {
            [r, c] => Some([r, c]),
            _ => None,
        }),
        slope: floats(obj, tags::RESCALE_SLOPE)
            .and_then(|v| v.first().copied())
            .unwrap_or(1.0),
        intercept: floats(obj, tags::RESCALE_INTERCEPT)
            .and_then(|v| v.first().copied())
            .unwrap_or(0.0),
        segment: None,
    }
}

/// Ultrasound regions give their pixel size in cm (Physical Delta X/Y, units code 3 = cm).
fn ultrasound_spacing(obj: &InMemDicomObject) -> Option<Vec<f64>> {
    let region = item(obj, tags::SEQUENCE_OF_ULTRASOUND_REGIONS)?;
    let cm = |tag| {
        floats(region, tag)
            .and_then(|v| v.first().copied())
            .map(|v| v.abs() * 10.0)
    };
    if int(region, tags::PHYSICAL_UNITS_X_DIRECTION) != Some(3) {
        return None;
    }
    Some(vec![cm(tags::PHYSICAL_DELTA_Y)?, cm(tags::PHYSICAL_DELTA_X)?])
}

/// A frame's geometry from its per-frame group, then the shared group, then the top level.
fn functional_geometry(
    frame: Option<&InMemDicomObject>,
    shared: Option<&InMemDicomObject>,
    top: &FrameGeometry,
) -> FrameGeometry {
    let find = |sequence: Tag, tag: Tag| {
        [frame, shared]
            .into_iter()
            .flatten()
            .find_map(|group| floats(item(group, sequence)?, tag))
    };
    let first = |v: Vec<f64>| v.first().copied();
    FrameGeometry {
        position: find(tags::PLANE_POSITION_SEQUENCE, tags::IMAGE_POSITION_PATIENT)
            .and_then(|v| vec3(&v))
            .or(top.position),
        orientation: find(tags::PLANE_ORIENTATION_SEQUENCE, tags::IMAGE_ORIENTATION_PATIENT)
            .and_then(|v| orientation(&v))
            .or(top.orientation),
        pixel_spacing: find(tags::PIXEL_MEASURES_SEQUENCE, tags::PIXEL_SPACING)
            .and_then(|v| match v[..] {
                [r, c] => Some([r, c]),
                _ => None,
            })
            .or(top.pixel_spacing),
        slope: find(tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE, tags::RESCALE_SLOPE)
            .and_then(first)
            .unwrap_or(top.slope),
        intercept: find(tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE, tags::RESCALE_INTERCEPT)
            .and_then(first)
            .unwrap_or(top.intercept),
        segment: frame
            .and_then(|f| item(f, tags::SEGMENT_IDENTIFICATION_SEQUENCE))
            .and_then(|s| int(s, tags::REFERENCED_SEGMENT_NUMBER)),
    }
}

/// RT dose: frame k lies (offset[k] − offset[0]) mm along the normal from the image position;
/// the vector may be relative (starting at 0) or absolute (starting at the first position).
fn dose_geometry(top: &FrameGeometry, offsets: &[f64]) -> Vec<FrameGeometry> {
    let normal = top.orientation.map(|[r, c]| r.cross(c).normalize_or_zero());
    offsets
        .iter()
        .map(|o| FrameGeometry {
            position: match (top.position, normal) {
                (Some(p), Some(n)) => Some(p + n * (o - offsets[0])),
                _ => None,
            },
            ..top.clone()
        })
        .collect()
}
