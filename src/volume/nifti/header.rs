//! The fixed binary NIfTI-1 (348-byte) and NIfTI-2 (540-byte) headers: layout, spacing,
//! rescale, and where the voxels lie (sform, else qform; RAS converted to LPS).

use std::path::Path;

use glam::{DMat3, DVec3};

use super::header_error;
use crate::volume::orient::PatientFrame;
use crate::volume::read::Layout;
use crate::volume::{Endian, ScalarType, VolumeError};

pub(super) const NIFTI1_HEADER_BYTES: usize = 348;
pub(super) const NIFTI2_HEADER_BYTES: usize = 540;

#[derive(Debug)]
pub(super) struct Header {
    pub layout: Layout,
    pub spacing: [f32; 3],
    pub vox_offset: u64,
    pub slope: f64,
    pub inter: f64,
    /// `.hdr`/`.img` pair (magic "ni1"/"ni2"): data in a separate file.
    pub pair: bool,
    pub version: u8,
    /// Volumes along the 4th axis; only the first is read.
    pub frames: u64,
    /// From the sform (sform_code > 0), else the qform (qform_code > 0).
    pub patient: Option<PatientFrame>,
}

/// sizeof_hdr and the byte order that makes it 348 or 540.
pub(super) fn sizeof_hdr(bytes: &[u8]) -> Option<(i32, Endian)> {
    let word: [u8; 4] = bytes.get(..4)?.try_into().ok()?;
    for (value, endian) in [
        (i32::from_le_bytes(word), Endian::Little),
        (i32::from_be_bytes(word), Endian::Big),
    ] {
        if value == 348 || value == 540 {
            return Some((value, endian));
        }
    }
    None
}

pub(super) struct Fields<'a> {
    bytes: &'a [u8],
    endian: Endian,
}

impl Fields<'_> {
    fn take<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut out = [0u8; N];
        out.copy_from_slice(&self.bytes[at..at + N]);
        out
    }
    fn i16(&self, at: usize) -> i16 {
        let b = self.take::<2>(at);
        if self.endian == Endian::Big {
            i16::from_be_bytes(b)
        } else {
            i16::from_le_bytes(b)
        }
    }
    fn i32(&self, at: usize) -> i32 {
        let b = self.take::<4>(at);
        if self.endian == Endian::Big {
            i32::from_be_bytes(b)
        } else {
            i32::from_le_bytes(b)
        }
    }
    fn i64(&self, at: usize) -> i64 {
        let b = self.take::<8>(at);
        if self.endian == Endian::Big {
            i64::from_be_bytes(b)
        } else {
            i64::from_le_bytes(b)
        }
    }
    fn f32(&self, at: usize) -> f64 {
        let b = self.take::<4>(at);
        f64::from(if self.endian == Endian::Big {
            f32::from_be_bytes(b)
        } else {
            f32::from_le_bytes(b)
        })
    }
    fn f64(&self, at: usize) -> f64 {
        let b = self.take::<8>(at);
        if self.endian == Endian::Big {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    }
}

pub(super) fn parse_header(bytes: &[u8], path: &Path) -> Result<Header, VolumeError> {
    let Some((size, endian)) = sizeof_hdr(bytes) else {
        return Err(header_error(
            path,
            "sizeof_hdr is neither 348 (NIfTI-1) nor 540 (NIfTI-2): not a NIfTI file",
        ));
    };
    let f = Fields { bytes, endian };
    let (version, dim, datatype, pixdim, vox_offset, slope, inter, magic) = if size == 348 {
        let dim: Vec<i64> = (0..8).map(|i| i64::from(f.i16(40 + 2 * i))).collect();
        let pixdim: Vec<f64> = (0..8).map(|i| f.f32(76 + 4 * i)).collect();
        let magic = &bytes[344..348];
        (1u8, dim, f.i16(70), pixdim, f.f32(108), f.f32(112), f.f32(116), magic)
    } else {
        let dim: Vec<i64> = (0..8).map(|i| f.i64(16 + 8 * i)).collect();
        let pixdim: Vec<f64> = (0..8).map(|i| f.f64(104 + 8 * i)).collect();
        let magic = &bytes[4..8];
        (
            2u8,
            dim,
            f.i16(12),
            pixdim,
            f.i64(168) as f64,
            f.f64(176),
            f.f64(184),
            magic,
        )
    };
    let pair = match magic {
        [b'n', b'+', v, 0] if *v == b'0' + version => false,
        [b'n', b'i', v, 0] if *v == b'0' + version => true,
        _ => return Err(header_error(path, format!("bad magic {magic:?} for NIfTI-{version}"))),
    };
    let ndim = dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(header_error(path, format!("dim[0] = {ndim} must be 1..7")));
    }
    let mut sizes = [1usize; 3];
    let mut frames = 1u64;
    for axis in 1..=ndim as usize {
        let d = dim[axis];
        if d < 1 {
            return Err(header_error(path, format!("dim[{axis}] = {d} must be ≥ 1")));
        }
        if axis <= 3 {
            sizes[axis - 1] =
                usize::try_from(d).map_err(|_| header_error(path, format!("dim[{axis}] = {d} is too large")))?;
        } else if axis == 4 {
            frames = d as u64;
        } else if d != 1 {
            return Err(header_error(
                path,
                format!("dim[{axis}] = {d}: vector or 5-D data cannot be loaded"),
            ));
        }
    }
    let scalar = match datatype {
        2 => ScalarType::U8,
        4 => ScalarType::I16,
        8 => ScalarType::I32,
        16 => ScalarType::F32,
        64 => ScalarType::F64,
        256 => ScalarType::I8,
        512 => ScalarType::U16,
        768 => ScalarType::U32,
        other => {
            return Err(header_error(
                path,
                format!("datatype {other} is not supported (supported: u8, i8, u16, i16, u32, i32, f32, f64)"),
            ))
        }
    };
    let mut spacing = [1.0f32; 3];
    for axis in 0..3 {
        let s = pixdim[axis + 1].abs() as f32;
        if s.is_finite() && s > 0.0 {
            spacing[axis] = s;
        }
    }
    if !(vox_offset.is_finite() && vox_offset >= 0.0) {
        return Err(header_error(path, format!("vox_offset {vox_offset} is invalid")));
    }
    let header_bytes = bytes.len() as f64;
    if !pair && vox_offset < header_bytes {
        return Err(header_error(
            path,
            format!("vox_offset {vox_offset} lies inside the {header_bytes}-byte header"),
        ));
    }
    Ok(Header {
        layout: Layout {
            dims: sizes,
            scalar,
            endian,
        },
        spacing,
        vox_offset: vox_offset as u64,
        slope,
        inter,
        pair,
        version,
        frames,
        patient: patient_frame(&f, version, pixdim[0]),
    })
}

/// Byte offsets of the orientation fields: (qform_code, sform_code, quatern_b, qoffset_x,
/// srow_x) and whether the numbers are f64 (NIfTI-2) or f32 (NIfTI-1).
fn orientation_offsets(version: u8) -> ([usize; 5], bool) {
    if version == 1 {
        ([252, 254, 256, 268, 280], false)
    } else {
        ([344, 348, 352, 376, 400], true)
    }
}

/// The sform when sform_code > 0, else the qform when qform_code > 0 (NIfTI's own order of
/// preference, also nibabel's and 3D Slicer's); `None` for files that say nothing (method 1).
fn patient_frame(f: &Fields, version: u8, qfac: f64) -> Option<PatientFrame> {
    let ([q_code, s_code, quatern, qoffset, srow], wide) = orientation_offsets(version);
    let code = |at| if version == 1 { i32::from(f.i16(at)) } else { f.i32(at) };
    let number = |at: usize, i: usize| if wide { f.f64(at + 8 * i) } else { f.f32(at + 4 * i) };
    if code(s_code) > 0 {
        // Rows of the 3×4 affine: axis i of the grid is column i, the origin column 3.
        let size = if wide { 8 } else { 4 };
        let row = |r: usize| [0, 1, 2, 3].map(|i| number(srow + r * 4 * size, i));
        let rows = [row(0), row(1), row(2)];
        let axis = |i: usize| DVec3::new(rows[0][i], rows[1][i], rows[2][i]);
        return PatientFrame::from_ras([axis(0), axis(1), axis(2)], axis(3), "NIfTI sform");
    }
    if code(q_code) > 0 {
        let (b, c, d) = (number(quatern, 0), number(quatern, 1), number(quatern, 2));
        let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
        // The rotation of the unit quaternion (a, b, c, d), NIfTI-1 header comments.
        let r = DMat3::from_cols_array_2d(&[
            [
                a * a + b * b - c * c - d * d,
                2.0 * (b * c + a * d),
                2.0 * (b * d - a * c),
            ],
            [
                2.0 * (b * c - a * d),
                a * a + c * c - b * b - d * d,
                2.0 * (c * d + a * b),
            ],
            [
                2.0 * (b * d + a * c),
                2.0 * (c * d - a * b),
                a * a + d * d - c * c - b * b,
            ],
        ]);
        // pixdim[0] (qfac) of −1 flips the third axis; 0 counts as 1.
        let qfac = if qfac < 0.0 { -1.0 } else { 1.0 };
        let origin = DVec3::new(number(qoffset, 0), number(qoffset, 1), number(qoffset, 2));
        return PatientFrame::from_ras([r.x_axis, r.y_axis, r.z_axis * qfac], origin, "NIfTI qform");
    }
    None
}
