//! One series into one volume: every frame of every file decoded and rescaled, sorted along
//! the slice normal, placed on a regular grid and given its patient frame.
//!
//! - Slices positioned irregularly (a missing slice, varying gaps) are resampled along the
//!   normal onto the median gap, with a note.
//! - Tilted (gantry-tilt) stacks, whose slices shift in-plane along the stack, are moved back
//!   onto a straight grid.
//! - Frames of one multi-frame object sharing a position (echoes, time points) keep the first;
//!   in a segmentation they are merged into a label map (the segment number where set).
//! - Frames without positions (cine loops) are stacked in order with unit spacing.

use std::path::{Path, PathBuf};

use glam::DVec3;
use rayon::prelude::*;

use super::frames::{image_info, FrameGeometry, ImageInfo};
use super::header_error;
use super::parse::read_file;
use super::pixels::frame_values;
use crate::volume::meta::{Format, Loaded, Units, VolumeMeta};
use crate::volume::orient::PatientFrame;
use crate::volume::read::data_error;
use crate::volume::{checked_voxel_count, ScalarType, Volume, VolumeError};

/// Relative spread of slice gaps above which the stack is resampled onto a regular grid.
const GAP_TOLERANCE: f64 = 0.01;
/// In-plane shift (pixels) below which a slice is not resampled for tilt.
const MIN_SHIFT_PX: f64 = 0.01;
/// Segmentation Storage: frames are bit masks of numbered segments.
const SEGMENTATION: &str = "1.2.840.10008.5.1.4.1.1.66.4";

/// One decoded frame with where it lies.
struct Slice {
    geometry: FrameGeometry,
    values: Vec<f32>,
    /// (instance number, frame index): the order when positions are missing.
    order: (i64, usize),
    file: usize,
}

/// Loads the files of one series as a volume.
pub(crate) fn load_series(files: &[PathBuf], root: &Path) -> Result<Loaded, VolumeError> {
    let decoded: Vec<(ImageInfo, Vec<Slice>)> = files
        .par_iter()
        .enumerate()
        .map(|(file, path)| decode_file(path, file))
        .collect::<Result<_, _>>()?;
    let (first, _) = decoded.first().ok_or_else(|| header_error(root, "empty series"))?;
    let first = first.clone();
    let f = &first.format;
    for (info, _) in &decoded {
        if (info.format.rows, info.format.columns) != (f.rows, f.columns) {
            return Err(header_error(
                &info.path,
                format!(
                    "image is {}×{} but the series is {}×{}",
                    info.format.columns, info.format.rows, f.columns, f.rows
                ),
            ));
        }
    }
    let multi_frame = decoded.len() == 1 && first.frames.len() > 1;
    let slices: Vec<Slice> = decoded.into_iter().flat_map(|(_, s)| s).collect();
    let mut meta = VolumeMeta::new(Format::Dicom, scalar_of(&first)).with_modality(&first.modality);
    if let Some(units) = &first.units {
        meta.units = Units::Named(units.clone());
    }
    if first.frames.len() > 1 {
        meta.notes
            .push(format!("{} frames: {}", first.frames.len(), first.layout));
    }
    if f.samples == 3 {
        meta.notes.push(format!(
            "colour ({}) shown as luminance (0.299 R + 0.587 G + 0.114 B)",
            f.photometric
        ));
    }
    if f.bits_allocated == 1 {
        meta.notes
            .push("1-bit frames: values 0 and 1 (segment numbers in a segmentation)".into());
    }
    let rescaled = slices
        .iter()
        .any(|s| s.geometry.slope != 1.0 || s.geometry.intercept != 0.0);
    if rescaled {
        meta.notes.push(if first.units.is_some() {
            "Dose Grid Scaling applied".into()
        } else {
            "rescale slope/intercept applied".into()
        });
    }
    build(slices, &first, multi_frame, meta, root)
}

fn scalar_of(info: &ImageInfo) -> Option<ScalarType> {
    let f = &info.format;
    Some(match (f.float_bits, f.bits_allocated, f.signed) {
        (Some(32), _, _) => ScalarType::F32,
        (Some(_), _, _) => ScalarType::F64,
        (None, 1 | 8, false) => ScalarType::U8,
        (None, 8, true) => ScalarType::I8,
        (None, 16, false) => ScalarType::U16,
        (None, 16, true) => ScalarType::I16,
        (None, 32, false) => ScalarType::U32,
        (None, 32, true) => ScalarType::I32,
        _ => return None,
    })
}

/// Reads one file and decodes all its frames (rescale applied).
fn decode_file(path: &Path, file: usize) -> Result<(ImageInfo, Vec<Slice>), VolumeError> {
    let parsed = read_file(path, false)?;
    let info = image_info(&parsed.object, path.to_path_buf()).map_err(|m| header_error(path, m))?;
    let mut slices = Vec::with_capacity(info.frames.len());
    for (k, g) in info.frames.iter().enumerate() {
        let mut values = frame_values(&parsed.object, &info.format, k, path)?;
        let (slope, intercept) = (g.slope, g.intercept);
        if slope.is_finite() && slope != 0.0 && intercept.is_finite() && (slope != 1.0 || intercept != 0.0) {
            for v in &mut values {
                *v = (f64::from(*v) * slope + intercept) as f32;
            }
        }
        if info.sop_class == SEGMENTATION {
            if let Some(label) = g.segment {
                for v in &mut values {
                    *v *= label as f32;
                }
            }
        }
        slices.push(Slice {
            geometry: g.clone(),
            values,
            order: (info.instance, k),
            file,
        });
    }
    Ok((info, slices))
}

fn build(
    mut slices: Vec<Slice>,
    first: &ImageInfo,
    multi_frame: bool,
    mut meta: VolumeMeta,
    root: &Path,
) -> Result<Loaded, VolumeError> {
    let (rows, columns) = (first.format.rows, first.format.columns);
    let orientation = slices[0].geometry.orientation;
    if let Some(o) = orientation {
        if slices.iter().any(|s| {
            s.geometry
                .orientation
                .is_some_and(|q| q[0].dot(o[0]) < 0.999 || q[1].dot(o[1]) < 0.999)
        }) {
            return Err(header_error(
                root,
                "the images of the series lie in different orientations (a localizer?): not one volume",
            ));
        }
    }
    let [row_dir, col_dir] = orientation.unwrap_or([DVec3::X, DVec3::Y]);
    let normal = row_dir.cross(col_dir);
    if normal.length().is_nan() || normal.length() <= 0.5 {
        return Err(header_error(&first.path, "ImageOrientationPatient is degenerate"));
    }
    let normal = normal.normalize();
    let [row_spacing, col_spacing] = slices[0].geometry.pixel_spacing.unwrap_or([1.0, 1.0]);
    let positioned = slices.iter().all(|s| s.geometry.position.is_some()) && slices.len() > 1;
    let depth = |s: &Slice| s.geometry.position.unwrap_or_default().dot(normal);
    let z_spacing;
    if positioned {
        slices.sort_by(|a, b| depth(a).total_cmp(&depth(b)).then(a.order.cmp(&b.order)));
        slices = merge_shared_positions(slices, first, multi_frame, &mut meta, root, depth)?;
        z_spacing = if slices.len() > 1 {
            median_gap(&slices, depth)
        } else {
            first.slice_thickness.unwrap_or(1.0)
        };
    } else {
        slices.sort_by_key(|s| (s.order, s.file));
        let given = first
            .spacing_between
            .or(first.slice_thickness)
            .filter(|s| s.is_finite() && *s > 0.0);
        z_spacing = given.unwrap_or(row_spacing.min(col_spacing));
        if slices.len() > 1 {
            meta.notes.push(match given {
                Some(s) => format!("images have no positions: stacked in order, {s} mm apart"),
                None => "images have no positions: stacked in order, one pixel size apart".into(),
            });
        }
    }
    // Tilt: in-plane offset of each slice from the first one's axis, moved back onto it.
    let origin = slices[0].geometry.position.unwrap_or_default();
    let mut max_shift = 0.0f64;
    for s in &mut slices {
        let offset = s.geometry.position.unwrap_or(origin) - origin;
        let shift = [offset.dot(row_dir) / col_spacing, offset.dot(col_dir) / row_spacing];
        max_shift = max_shift.max(shift[0].abs()).max(shift[1].abs());
        if shift[0].abs() > MIN_SHIFT_PX || shift[1].abs() > MIN_SHIFT_PX {
            s.values = shift_slice(&s.values, columns, rows, shift[0], shift[1]);
        }
    }
    if max_shift > MIN_SHIFT_PX {
        meta.notes.push(format!(
            "tilted acquisition: slices resampled by up to {max_shift:.1} pixels onto a straight grid"
        ));
    }
    let framed = orientation.is_some() && (positioned || slices.len() == 1);
    let data = if positioned {
        regular_stack(&slices, z_spacing, depth, &mut meta)?
    } else {
        slices.into_iter().flat_map(|s| s.values).collect()
    };
    let plane = rows * columns;
    let dims = [columns, rows, data.len() / plane];
    checked_voxel_count(dims)?;
    let spacing = [col_spacing as f32, row_spacing as f32, z_spacing as f32];
    if framed {
        meta.patient = PatientFrame::new([row_dir, col_dir, normal], origin, "DICOM ImageOrientationPatient");
    }
    let volume = Volume::new(dims, spacing, data).map_err(|e| match e {
        VolumeError::InvalidSpacing(s) => data_error(
            root,
            format!("invalid spacing {s:?} from PixelSpacing and slice positions"),
        ),
        other => other,
    })?;
    Ok(Loaded::new(volume, meta))
}

/// Frames sharing a position: an error between files (duplicated images), merged as a label
/// map in a segmentation, the first kept otherwise (echoes or time points of one object).
fn merge_shared_positions(
    slices: Vec<Slice>,
    first: &ImageInfo,
    multi_frame: bool,
    meta: &mut VolumeMeta,
    root: &Path,
    depth: impl Fn(&Slice) -> f64,
) -> Result<Vec<Slice>, VolumeError> {
    let mut out: Vec<Slice> = Vec::with_capacity(slices.len());
    let mut dropped = 0usize;
    let segmentation = first.sop_class == SEGMENTATION;
    for s in slices {
        match out.last_mut() {
            Some(last) if (depth(&s) - depth(last)).abs() <= 1e-4 => {
                if segmentation {
                    for (a, b) in last.values.iter_mut().zip(&s.values) {
                        *a = a.max(*b);
                    }
                } else if multi_frame {
                    dropped += 1;
                } else {
                    return Err(header_error(
                        root,
                        "two images share one position: the series has duplicates (pick the files of one acquisition)",
                    ));
                }
            }
            _ => out.push(s),
        }
    }
    if dropped > 0 {
        meta.notes.push(format!(
            "{dropped} frames share positions with others (echoes or time points): kept the first at each position"
        ));
    }
    Ok(out)
}

fn median_gap(slices: &[Slice], depth: impl Fn(&Slice) -> f64) -> f64 {
    let mut gaps: Vec<f64> = slices.windows(2).map(|w| depth(&w[1]) - depth(&w[0])).collect();
    gaps.sort_by(f64::total_cmp);
    gaps[gaps.len() / 2]
}

/// The slices on a regular grid along the normal: as they are when the gaps are even;
/// otherwise interpolated linearly onto planes `spacing` apart (a missing slice is filled from
/// its neighbours).
fn regular_stack(
    slices: &[Slice],
    spacing: f64,
    depth: impl Fn(&Slice) -> f64,
    meta: &mut VolumeMeta,
) -> Result<Vec<f32>, VolumeError> {
    let depths: Vec<f64> = slices.iter().map(&depth).collect();
    let gaps: Vec<f64> = depths.windows(2).map(|w| w[1] - w[0]).collect();
    let even = gaps.iter().all(|g| ((g - spacing) / spacing).abs() <= GAP_TOLERANCE);
    if even {
        return Ok(slices.iter().flat_map(|s| s.values.iter().copied()).collect());
    }
    let span = depths[depths.len() - 1] - depths[0];
    let planes = (span / spacing).round() as usize + 1;
    let (lo, hi) = gaps
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), g| (lo.min(*g), hi.max(*g)));
    let widest = gaps
        .iter()
        .enumerate()
        .fold((0, 0.0), |best, (i, g)| if *g > best.1 { (i, *g) } else { best });
    let mut note =
        format!("slice gaps vary between {lo:.3} and {hi:.3} mm; resampled onto {planes} slices {spacing:.3} mm apart");
    if widest.1 > 1.5 * spacing {
        note.push_str(&format!(
            " (a slice seems to be missing between {:.2} and {:.2} mm along the stack)",
            depths[widest.0] - depths[0],
            depths[widest.0 + 1] - depths[0]
        ));
    }
    log::warn!("{note}");
    meta.notes.push(note);
    checked_voxel_count([slices[0].values.len(), planes, 1])?;
    let mut out = Vec::with_capacity(planes * slices[0].values.len());
    let mut j = 0;
    for k in 0..planes {
        let z = depths[0] + k as f64 * spacing;
        while j + 2 < depths.len() && depths[j + 1] < z {
            j += 1;
        }
        let (a, b) = (&slices[j], &slices[(j + 1).min(slices.len() - 1)]);
        let width = depths[(j + 1).min(slices.len() - 1)] - depths[j];
        let t = if width > 0.0 {
            ((z - depths[j]) / width).clamp(0.0, 1.0) as f32
        } else {
            0.0
        };
        out.extend(a.values.iter().zip(&b.values).map(|(x, y)| x + (y - x) * t));
    }
    Ok(out)
}

/// Moves a slice whose origin lies `shift` pixels from the stack's axis back onto it: samples
/// at (x − shift_x, y − shift_y), bilinear, with the slice minimum (air) outside.
pub(crate) fn shift_slice(values: &[f32], w: usize, h: usize, shift_x: f64, shift_y: f64) -> Vec<f32> {
    let outside = values.iter().copied().fold(f32::INFINITY, f32::min);
    let at = |x: i64, y: i64| {
        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
            outside
        } else {
            values[y as usize * w + x as usize]
        }
    };
    let mut out = Vec::with_capacity(values.len());
    for y in 0..h {
        for x in 0..w {
            let sx = x as f64 - shift_x;
            let sy = y as f64 - shift_y;
            let (x0, y0) = (sx.floor(), sy.floor());
            let (fx, fy) = ((sx - x0) as f32, (sy - y0) as f32);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
            let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
            out.push(top * (1.0 - fy) + bottom * fy);
        }
    }
    out
}
