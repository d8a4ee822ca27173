//! Writes single-file NIfTI volumes for the tests.

use crate::volume::Endian;

/// Writes a single-file NIfTI volume of f32 or i16 samples (tests and tools). `version` 1 or 2.
pub(crate) fn write_nifti_bytes(
    version: u8,
    dims: [usize; 3],
    spacing: [f32; 3],
    datatype: i16,
    data: &[u8],
    slope_inter: [f64; 2],
    endian: Endian,
) -> Vec<u8> {
    let big = endian == Endian::Big;
    macro_rules! put {
        ($buf:expr, $at:expr, $v:expr) => {{
            let b = if big { $v.to_be_bytes() } else { $v.to_le_bytes() };
            $buf[$at..$at + b.len()].copy_from_slice(&b);
        }};
    }
    let mut h;
    if version == 1 {
        h = vec![0u8; 352];
        put!(h, 0, 348i32);
        put!(h, 40, 3i16);
        for (i, d) in dims.iter().enumerate() {
            put!(h, 42 + 2 * i, *d as i16);
        }
        put!(h, 70, datatype);
        put!(h, 76, 1.0f32);
        for (i, s) in spacing.iter().enumerate() {
            put!(h, 80 + 4 * i, *s);
        }
        put!(h, 108, 352.0f32);
        put!(h, 112, slope_inter[0] as f32);
        put!(h, 116, slope_inter[1] as f32);
        h[344..348].copy_from_slice(b"n+1\0");
    } else {
        h = vec![0u8; 544];
        put!(h, 0, 540i32);
        h[4..12].copy_from_slice(b"n+2\0\r\n\x1a\n");
        put!(h, 12, datatype);
        put!(h, 16, 3i64);
        for (i, d) in dims.iter().enumerate() {
            put!(h, 24 + 8 * i, *d as i64);
        }
        put!(h, 104, 1.0f64);
        for (i, s) in spacing.iter().enumerate() {
            put!(h, 112 + 8 * i, f64::from(*s));
        }
        put!(h, 168, 544i64);
        put!(h, 176, slope_inter[0]);
        put!(h, 184, slope_inter[1]);
    }
    h.extend_from_slice(data);
    h
}

/// Sets the sform of a header written by [`write_nifti_bytes`] (little endian): rows of the
/// 3×4 voxel-to-RAS affine.
pub(crate) fn set_sform(bytes: &mut [u8], version: u8, rows: [[f64; 4]; 3]) {
    if version == 1 {
        bytes[254..256].copy_from_slice(&1i16.to_le_bytes());
        for (r, row) in rows.iter().enumerate() {
            for (i, v) in row.iter().enumerate() {
                let at = 280 + 16 * r + 4 * i;
                bytes[at..at + 4].copy_from_slice(&(*v as f32).to_le_bytes());
            }
        }
    } else {
        bytes[348..352].copy_from_slice(&1i32.to_le_bytes());
        for (r, row) in rows.iter().enumerate() {
            for (i, v) in row.iter().enumerate() {
                let at = 400 + 32 * r + 8 * i;
                bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
            }
        }
    }
}

/// Sets the qform of a NIfTI-1 header written by [`write_nifti_bytes`] (little endian):
/// quaternion (b, c, d), offset and qfac.
pub(crate) fn set_qform(bytes: &mut [u8], bcd: [f32; 3], offset: [f32; 3], qfac: f32) {
    bytes[252..254].copy_from_slice(&1i16.to_le_bytes());
    bytes[76..80].copy_from_slice(&qfac.to_le_bytes());
    for (i, v) in bcd.iter().chain(&offset).enumerate() {
        bytes[256 + 4 * i..260 + 4 * i].copy_from_slice(&v.to_le_bytes());
    }
}
