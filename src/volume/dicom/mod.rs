//! DICOM: every image a scanner or planning system exports, through dicom-rs.
//!
//! - **Files**: Part-10 files with or without the preamble, bare data sets without a meta group,
//!   every transfer syntax dicom-rs reads, and every pixel encoding its pure-Rust codecs decode
//!   (native, deflate, RLE, JPEG baseline/extended/lossless, JPEG 2000); see [`parse`] and
//!   [`pixels`].
//! - **Objects**: single-frame slices, enhanced multi-frame objects (functional groups), RT
//!   dose grids, segmentations (1-bit), colour images (as luminance) and cine loops; see
//!   [`frames`]. Objects without pixel data fail with what they are ("this DICOM object holds
//!   no image: Structured Report (…)").
//! - **Series**: a folder, the folder of one file, or a DICOMDIR is grouped by
//!   SeriesInstanceUID ([`scan`]); one series is chosen (by number or UID when there are
//!   several) and assembled into a volume with its patient frame ([`assemble`]).

mod assemble;
mod frames;
mod parse;
mod pixels;
mod scan;
#[cfg(test)]
mod tests;

use std::path::Path;

pub use scan::SeriesInfo;

use super::meta::Loaded;
use super::VolumeError;

fn header_error(path: &Path, message: impl Into<String>) -> VolumeError {
    super::read::format_header_error(path, "DICOM", message)
}

/// True when the file at `path` starts like DICOM (a "DICM" marker or a bare data set).
pub fn is_dicom_file(path: &Path) -> bool {
    let mut head = Vec::with_capacity(132);
    std::fs::File::open(path)
        .and_then(|f| std::io::Read::read_to_end(&mut std::io::Read::take(f, 132), &mut head))
        .is_ok_and(|_| parse::looks_like_dicom(&head))
}

/// The image series found at `path` (a folder, a DICOMDIR or one file's folder), numbered
/// from 1 in the order of their Series Number.
pub fn list_series(path: &Path) -> Result<Vec<SeriesInfo>, VolumeError> {
    Ok(checked_scan(path)?.series)
}

/// Loads one series from `path`: the series of the file when `path` is a file, the only one
/// of a folder or DICOMDIR, or the one `series` names (its number in [`list_series`] or its
/// UID) when there are several.
pub fn open_dicom(path: &Path, series: Option<&str>) -> Result<Loaded, VolumeError> {
    let scan = checked_scan(path)?;
    let wanted = series.map(str::to_string).or_else(|| scan.preselected.clone());
    let chosen = match wanted {
        Some(key) => scan
            .series
            .iter()
            .find(|s| s.uid == key || key.parse::<usize>().is_ok_and(|n| n == s.number))
            .ok_or_else(|| VolumeError::DicomSeries {
                path: path.to_path_buf(),
                message: format!("no series '{key}'; there are:\n{}", series_table(&scan.series)),
            })?,
        None if scan.series.len() == 1 => &scan.series[0],
        None => {
            return Err(VolumeError::SeveralSeries {
                path: path.to_path_buf(),
                listing: series_table(&scan.series),
            })
        }
    };
    let mut loaded = assemble::load_series(&chosen.files, path)?;
    if scan.series.len() > 1 {
        loaded.meta.notes.push(format!(
            "series {} of {} ({}): {}",
            chosen.number,
            scan.series.len(),
            chosen.uid,
            if chosen.description.is_empty() {
                "no description"
            } else {
                &chosen.description
            }
        ));
    }
    if !scan.unreadable.is_empty() {
        let (_, why) = &scan.unreadable[0];
        let note = format!(
            "{} unreadable DICOM file(s) skipped (first: {why})",
            scan.unreadable.len()
        );
        log::warn!("{note}");
        loaded.meta.notes.push(note);
    }
    Ok(loaded)
}

/// A scan that found at least one image series; otherwise the clearest error: what the
/// objects are when none holds an image, or why the first file could not be read.
fn checked_scan(path: &Path) -> Result<scan::Scan, VolumeError> {
    let scan = scan::scan(path)?;
    if !scan.series.is_empty() {
        return Ok(scan);
    }
    if let Some((p, kind)) = scan.non_image.first() {
        let others = scan.non_image.len() - 1;
        let more = if others > 0 {
            format!(" (and {others} more objects without images)")
        } else {
            String::new()
        };
        return Err(header_error(
            p,
            format!("this DICOM object holds no image: {kind}{more}"),
        ));
    }
    if let Some((_, why)) = scan.unreadable.first() {
        return Err(VolumeError::DicomSeries {
            path: path.to_path_buf(),
            message: format!(
                "no readable image ({} unreadable files; first: {why})",
                scan.unreadable.len()
            ),
        });
    }
    Err(header_error(
        path,
        format!("no DICOM files found ({} other files)", scan.not_dicom),
    ))
}

/// The listing of [`list_series`] as text: one line per series.
pub fn series_table(series: &[SeriesInfo]) -> String {
    let mut out = String::from("  #  modality  dims          slices  description  (UID)\n");
    for s in series {
        out.push_str(&format!(
            "  {:<2} {:<9} {:<13} {:<7} {}  ({})\n",
            s.number,
            if s.modality.is_empty() { "?" } else { &s.modality },
            format!("{}×{}×{}", s.columns, s.rows, s.frames),
            s.frames,
            if s.description.is_empty() { "-" } else { &s.description },
            s.uid
        ));
    }
    out
}
