//! DICOM series from a directory: every Part-10 file of one series, sorted by position along
//! the slice normal, rescaled (slope/intercept) and spaced from the slice positions. Tilted
//! (gantry-tilt) acquisitions, whose slices are shifted in-plane along the stack, are
//! resampled onto a straight grid. Uncompressed transfer syntaxes only (implicit and
//! explicit VR little endian, explicit VR big endian); a small reader of exactly the
//! elements needed, so malformed files are bounded by one slice and easy to fuzz.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::meta::{Format, Loaded, VolumeMeta};
use super::read::{data_error, io_error};
use super::{checked_voxel_count, decode::decode_samples, Endian, ScalarType, Volume, VolumeError};

/// Largest single DICOM file read into memory.
const MAX_FILE_BYTES: u64 = 1 << 30;
/// Relative spread of slice gaps above which a warning is logged (irregular stacks).
const GAP_TOLERANCE: f64 = 0.01;

fn header_error(path: &Path, message: impl Into<String>) -> VolumeError {
    super::read::format_header_error(path, "DICOM", message)
}

/// The elements of one slice that building a volume needs.
#[derive(Clone, Debug, Default)]
pub(crate) struct Slice {
    pub path: PathBuf,
    pub rows: usize,
    pub columns: usize,
    pub bits_allocated: u16,
    pub signed: bool,
    pub samples_per_pixel: u16,
    pub frames: usize,
    pub pixel_spacing: Option<[f64; 2]>,
    pub position: Option<DVec3>,
    pub orientation: Option<[DVec3; 2]>,
    pub slope: f64,
    pub intercept: f64,
    pub modality: String,
    pub series: String,
    pub instance: i64,
    pub slice_thickness: Option<f64>,
    pub endian: Endian,
    pub pixels: Vec<u8>,
}

const SYNTAX_IMPLICIT_LE: &str = "1.2.840.10008.1.2";
const SYNTAX_EXPLICIT_LE: &str = "1.2.840.10008.1.2.1";
const SYNTAX_EXPLICIT_BE: &str = "1.2.840.10008.1.2.2";

struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    explicit: bool,
    endian: Endian,
}

impl Cursor<'_> {
    fn u16(&mut self) -> Option<u16> {
        let b: [u8; 2] = self.bytes.get(self.at..self.at + 2)?.try_into().ok()?;
        self.at += 2;
        Some(if self.endian == Endian::Big {
            u16::from_be_bytes(b)
        } else {
            u16::from_le_bytes(b)
        })
    }
    fn u32(&mut self) -> Option<u32> {
        let b: [u8; 4] = self.bytes.get(self.at..self.at + 4)?.try_into().ok()?;
        self.at += 4;
        Some(if self.endian == Endian::Big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }
    /// Reads the next element header: (group, element, VR, length); length `None` is undefined.
    fn element(&mut self) -> Option<(u16, u16, [u8; 2], Option<u32>)> {
        let group = self.u16()?;
        let element = self.u16()?;
        // Item and delimitation tags never carry a VR.
        if group == 0xFFFE || !self.explicit {
            let len = self.u32()?;
            return Some((group, element, *b"UN", (len != u32::MAX).then_some(len)));
        }
        let vr: [u8; 2] = self.bytes.get(self.at..self.at + 2)?.try_into().ok()?;
        self.at += 2;
        let long = matches!(
            &vr,
            b"OB" | b"OD" | b"OF" | b"OL" | b"OV" | b"OW" | b"SQ" | b"SV" | b"UC" | b"UN" | b"UR" | b"UT" | b"UV"
        );
        let len = if long {
            self.at += 2;
            self.u32()?
        } else {
            u32::from(self.u16()?)
        };
        Some((group, element, vr, (len != u32::MAX).then_some(len)))
    }
    fn take(&mut self, len: u32) -> Option<&[u8]> {
        let end = self.at.checked_add(len as usize)?;
        let out = self.bytes.get(self.at..end)?;
        self.at = end;
        Some(out)
    }
    /// Skips an undefined-length sequence (or item) up to its delimiter; depth bounds nesting.
    fn skip_undefined(&mut self, depth: usize) -> Option<()> {
        if depth > 16 {
            return None;
        }
        loop {
            let (group, element, _, len) = self.element()?;
            if group == 0xFFFE && (element == 0xE0DD || element == 0xE00D) {
                return Some(());
            }
            match len {
                Some(len) => {
                    self.take(len)?;
                }
                None => self.skip_undefined(depth + 1)?,
            }
        }
    }
}

fn text(value: &[u8]) -> String {
    String::from_utf8_lossy(value)
        .trim_matches(|c: char| c == '\0' || c.is_whitespace())
        .to_string()
}

fn numbers(value: &[u8]) -> Vec<f64> {
    text(value).split('\\').filter_map(|t| t.trim().parse().ok()).collect()
}

/// Parses one Part-10 file (preamble, "DICM", meta group, data set up to the pixel data).
pub(crate) fn parse_slice(bytes: &[u8], path: &Path) -> Result<Slice, VolumeError> {
    if bytes.len() < 132 || &bytes[128..132] != b"DICM" {
        return Err(header_error(
            path,
            "no 'DICM' marker at byte 128: not a DICOM Part-10 file",
        ));
    }
    let bad = |what: &str| header_error(path, format!("malformed element {what}"));
    let mut cur = Cursor {
        bytes,
        at: 132,
        explicit: true,
        endian: Endian::Little,
    };
    let mut syntax = String::new();
    // File meta group: always explicit VR little endian.
    loop {
        let save = cur.at;
        let Some((group, element, _, len)) = cur.element() else {
            return Err(bad("in the file meta group"));
        };
        if group != 0x0002 {
            cur.at = save;
            break;
        }
        let value = cur
            .take(len.ok_or_else(|| bad("with undefined length in the meta group"))?)
            .ok_or_else(|| bad("past the end of the file"))?;
        if element == 0x0010 {
            syntax = text(value);
        }
    }
    match syntax.as_str() {
        SYNTAX_IMPLICIT_LE => cur.explicit = false,
        SYNTAX_EXPLICIT_LE => {}
        SYNTAX_EXPLICIT_BE => cur.endian = Endian::Big,
        other => {
            return Err(header_error(
                path,
                format!("transfer syntax '{other}' is compressed or unknown; only uncompressed syntaxes (implicit/explicit VR little endian, explicit VR big endian) are supported"),
            ))
        }
    }
    let mut s = Slice {
        path: path.to_path_buf(),
        slope: 1.0,
        frames: 1,
        samples_per_pixel: 1,
        endian: cur.endian,
        ..Slice::default()
    };
    loop {
        let Some((group, element, _, len)) = cur.element() else {
            return Err(header_error(path, "file ends before the pixel data"));
        };
        let Some(len) = len else {
            if (group, element) == (0x7FE0, 0x0010) {
                return Err(header_error(
                    path,
                    "encapsulated (compressed) pixel data is not supported",
                ));
            }
            cur.skip_undefined(0)
                .ok_or_else(|| bad("in an undefined-length sequence"))?;
            continue;
        };
        let value = cur
            .take(len)
            .ok_or_else(|| bad(&format!("({group:04X},{element:04X}) past the end of the file")))?;
        let us = |v: &[u8]| -> u16 {
            let b = [v.first().copied().unwrap_or(0), v.get(1).copied().unwrap_or(0)];
            if s.endian == Endian::Big {
                u16::from_be_bytes(b)
            } else {
                u16::from_le_bytes(b)
            }
        };
        match (group, element) {
            (0x0008, 0x0060) => s.modality = text(value),
            (0x0018, 0x0050) => s.slice_thickness = numbers(value).first().copied(),
            (0x0020, 0x000E) => s.series = text(value),
            (0x0020, 0x0013) => s.instance = numbers(value).first().map_or(0, |v| *v as i64),
            (0x0020, 0x0032) => {
                if let [x, y, z] = numbers(value)[..] {
                    s.position = Some(DVec3::new(x, y, z));
                }
            }
            (0x0020, 0x0037) => {
                if let [a, b, c, d, e, f] = numbers(value)[..] {
                    s.orientation = Some([DVec3::new(a, b, c), DVec3::new(d, e, f)]);
                }
            }
            (0x0028, 0x0002) => s.samples_per_pixel = us(value),
            (0x0028, 0x0008) => s.frames = numbers(value).first().map_or(1, |v| *v as usize),
            (0x0028, 0x0010) => s.rows = usize::from(us(value)),
            (0x0028, 0x0011) => s.columns = usize::from(us(value)),
            (0x0028, 0x0030) => {
                if let [r, c] = numbers(value)[..] {
                    s.pixel_spacing = Some([r, c]);
                }
            }
            (0x0028, 0x0100) => s.bits_allocated = us(value),
            (0x0028, 0x0103) => s.signed = us(value) == 1,
            (0x0028, 0x1052) => s.intercept = numbers(value).first().copied().unwrap_or(0.0),
            (0x0028, 0x1053) => s.slope = numbers(value).first().copied().unwrap_or(1.0),
            (0x7FE0, 0x0010) => {
                s.pixels = value.to_vec();
                break;
            }
            _ => {}
        }
    }
    if s.samples_per_pixel != 1 {
        return Err(header_error(
            path,
            format!("{} samples per pixel: only greyscale images load", s.samples_per_pixel),
        ));
    }
    if s.frames != 1 {
        return Err(header_error(
            path,
            format!("{} frames in one file: only single-frame series load", s.frames),
        ));
    }
    if s.rows == 0 || s.columns == 0 {
        return Err(header_error(path, "missing or zero Rows/Columns"));
    }
    let scalar = s.scalar().ok_or_else(|| {
        header_error(
            path,
            format!("BitsAllocated {} is not supported (8, 16, 32)", s.bits_allocated),
        )
    })?;
    let need = s.rows as u64 * s.columns as u64 * scalar.size_bytes() as u64;
    if (s.pixels.len() as u64) < need {
        return Err(VolumeError::Truncated {
            kind: "DICOM pixel data in",
            path: path.to_path_buf(),
            expected_bytes: need,
            actual_bytes: s.pixels.len() as u64,
            layout: format!("{}×{} of {scalar}", s.columns, s.rows),
        });
    }
    Ok(s)
}

impl Slice {
    fn scalar(&self) -> Option<ScalarType> {
        Some(match (self.bits_allocated, self.signed) {
            (8, false) => ScalarType::U8,
            (8, true) => ScalarType::I8,
            (16, false) => ScalarType::U16,
            (16, true) => ScalarType::I16,
            (32, false) => ScalarType::U32,
            (32, true) => ScalarType::I32,
            _ => return None,
        })
    }
}

/// Loads the DICOM series in `dir` (the largest series when several are present).
pub fn load_dicom_dir(dir: &Path) -> Result<Loaded, VolumeError> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(io_error(dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    entries.sort();
    let mut by_series: BTreeMap<String, Vec<Slice>> = BTreeMap::new();
    let mut skipped = 0usize;
    for path in entries {
        let len = std::fs::metadata(&path).map_err(io_error(&path))?.len();
        if len > MAX_FILE_BYTES {
            return Err(header_error(&path, format!("file of {len} bytes is larger than 1 GiB")));
        }
        let bytes = std::fs::read(&path).map_err(io_error(&path))?;
        if bytes.get(128..132) != Some(b"DICM") {
            skipped += 1;
            continue;
        }
        // A broken file in a series is an error: silently dropping a slice would distort the volume.
        let slice = parse_slice(&bytes, &path)?;
        by_series.entry(slice.series.clone()).or_default().push(slice);
    }
    let series_count = by_series.len();
    let Some((_, slices)) = by_series.into_iter().max_by_key(|(_, v)| v.len()) else {
        return Err(header_error(
            dir,
            format!("no DICOM files in the directory ({skipped} other files)"),
        ));
    };
    let mut loaded = assemble(slices, dir)?;
    if series_count > 1 {
        let note = format!("{series_count} series in the directory; loaded the largest");
        log::warn!("{}: {note}", dir.display());
        loaded.meta.notes.push(note);
    }
    Ok(loaded)
}

/// Sorts slices along the normal, checks they form one grid, and builds the volume.
pub(crate) fn assemble(mut slices: Vec<Slice>, dir: &Path) -> Result<Loaded, VolumeError> {
    let first = slices.first().ok_or_else(|| header_error(dir, "empty series"))?.clone();
    let (rows, columns) = (first.rows, first.columns);
    let dims = [columns, rows, slices.len()];
    let count = checked_voxel_count(dims)?;
    for s in &slices {
        if (s.rows, s.columns, s.bits_allocated, s.signed) != (rows, columns, first.bits_allocated, first.signed) {
            return Err(header_error(
                &s.path,
                format!("slice is {}×{} but the series is {columns}×{rows}", s.columns, s.rows),
            ));
        }
    }
    let [row_dir, col_dir] = first.orientation.unwrap_or([DVec3::X, DVec3::Y]);
    let normal = row_dir.cross(col_dir);
    if normal.length().is_nan() || normal.length() <= 0.5 {
        return Err(header_error(&first.path, "ImageOrientationPatient is degenerate"));
    }
    let normal = normal.normalize();
    let have_positions = slices.iter().all(|s| s.position.is_some());
    if have_positions {
        slices.sort_by(|a, b| {
            let da = a.position.unwrap_or_default().dot(normal);
            let db = b.position.unwrap_or_default().dot(normal);
            da.total_cmp(&db)
        });
    } else {
        slices.sort_by_key(|s| s.instance);
    }
    let [row_spacing, col_spacing] = first.pixel_spacing.unwrap_or([1.0, 1.0]);
    let mut meta = VolumeMeta::new(Format::Dicom, first.scalar()).with_modality(&first.modality);
    let z_spacing = if have_positions && slices.len() > 1 {
        let depths: Vec<f64> = slices
            .iter()
            .map(|s| s.position.unwrap_or_default().dot(normal))
            .collect();
        let gaps: Vec<f64> = depths.windows(2).map(|w| w[1] - w[0]).collect();
        if gaps.iter().any(|g| *g <= 1e-6) {
            return Err(header_error(
                dir,
                "two slices share one position: the series has duplicates",
            ));
        }
        let mean = (depths[depths.len() - 1] - depths[0]) / gaps.len() as f64;
        if gaps.iter().any(|g| ((g - mean) / mean).abs() > GAP_TOLERANCE) {
            let note = format!(
                "slice gaps vary between {:.3} and {:.3}; using their mean {mean:.3}",
                gaps.iter().copied().fold(f64::INFINITY, f64::min),
                gaps.iter().copied().fold(0.0, f64::max)
            );
            log::warn!("{}: {note}", dir.display());
            meta.notes.push(note);
        }
        mean
    } else {
        first.slice_thickness.unwrap_or(1.0)
    };
    let scalar = first
        .scalar()
        .ok_or_else(|| header_error(&first.path, "unsupported bits"))?;
    let plane = rows * columns;
    let mut data = Vec::with_capacity(count);
    let origin = first.position.unwrap_or_default();
    let mut max_shift = 0.0f64;
    let mut rescaled = false;
    for s in &slices {
        let mut values = decode_samples(&s.pixels[..plane * scalar.size_bytes()], scalar, s.endian);
        rescaled |= super::read::rescale(&mut values, s.slope, s.intercept);
        // In-plane offset of this slice from the stack's axis: non-zero for gantry tilt.
        let offset = s.position.unwrap_or(origin) - origin;
        let shift_x = offset.dot(row_dir) / col_spacing;
        let shift_y = offset.dot(col_dir) / row_spacing;
        max_shift = max_shift.max(shift_x.abs()).max(shift_y.abs());
        if shift_x.abs() > 0.01 || shift_y.abs() > 0.01 {
            values = shift_slice(&values, columns, rows, shift_x, shift_y);
        }
        data.extend(values);
    }
    if max_shift > 0.01 {
        let note = format!("tilted acquisition: slices resampled by up to {max_shift:.1} pixels onto a straight grid");
        meta.notes.push(note);
    }
    if rescaled {
        meta.notes.push("rescale slope/intercept applied".into());
    }
    let spacing = [col_spacing as f32, row_spacing as f32, z_spacing as f32];
    let volume = Volume::new(dims, spacing, data).map_err(|e| match e {
        VolumeError::InvalidSpacing(s) => data_error(
            dir,
            format!("invalid spacing {s:?} from PixelSpacing and slice positions"),
        ),
        other => other,
    })?;
    Ok(Loaded::new(volume, meta))
}

/// Moves a slice whose origin lies `shift` pixels from the stack's axis back onto it: samples
/// at (x − shift_x, y − shift_y), bilinear, with the slice minimum (air) outside.
fn shift_slice(values: &[f32], w: usize, h: usize, shift_x: f64, shift_y: f64) -> Vec<f32> {
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

#[cfg(test)]
mod tests;
