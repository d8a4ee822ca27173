//! NIfTI-1 and NIfTI-2 volumes (`.nii`, `.nii.gz`, and `.hdr`/`.img` pairs), with the
//! scl_slope/scl_inter rescale applied. A small reader of the fixed binary header: the `nifti`
//! crate pulls in ndarray and nalgebra and reads NIfTI-1 only.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use flate2::read::MultiGzDecoder;

use super::meta::{Format, Loaded, VolumeMeta};
use super::read::{io_error, rescale, samples_from_file, samples_from_stream, Layout};
use super::{Endian, ScalarType, Volume, VolumeError};

const NIFTI1_HEADER_BYTES: usize = 348;
const NIFTI2_HEADER_BYTES: usize = 540;

#[derive(Debug)]
struct Header {
    layout: Layout,
    spacing: [f32; 3],
    vox_offset: u64,
    slope: f64,
    inter: f64,
    /// `.hdr`/`.img` pair (magic "ni1"/"ni2"): data in a separate file.
    pair: bool,
    version: u8,
    /// Volumes along the 4th axis; only the first is read.
    frames: u64,
}

/// Loads a `.nii`, `.nii.gz` or `.hdr` (with its `.img`) file.
pub fn load_nifti(path: &Path) -> Result<Loaded, VolumeError> {
    let gz = is_gzip(path)?;
    let file = File::open(path).map_err(io_error(path))?;
    let mut reader: Box<dyn Read> = if gz {
        Box::new(MultiGzDecoder::new(BufReader::new(file)))
    } else {
        Box::new(BufReader::new(file))
    };
    let mut bytes = vec![0u8; NIFTI2_HEADER_BYTES];
    let got = read_up_to(&mut reader, &mut bytes[..NIFTI1_HEADER_BYTES], path)?;
    if got < NIFTI1_HEADER_BYTES {
        return Err(header_error(
            path,
            format!("file has {got} bytes, shorter than a NIfTI header"),
        ));
    }
    let mut header_len = NIFTI1_HEADER_BYTES;
    if sizeof_hdr(&bytes) == Some((540, Endian::Little)) || sizeof_hdr(&bytes) == Some((540, Endian::Big)) {
        let more = read_up_to(&mut reader, &mut bytes[NIFTI1_HEADER_BYTES..], path)?;
        if more < NIFTI2_HEADER_BYTES - NIFTI1_HEADER_BYTES {
            return Err(header_error(path, "file ends inside the NIfTI-2 header"));
        }
        header_len = NIFTI2_HEADER_BYTES;
    }
    let header = parse_header(&bytes[..header_len], path)?;
    let mut meta = VolumeMeta::new(Format::Nifti, Some(header.layout.scalar));
    meta.notes.push(format!("NIfTI-{}", header.version));
    if header.frames > 1 {
        meta.notes
            .push(format!("{} volumes along t; loaded the first", header.frames));
    }
    let mut data = if header.pair {
        let img = pair_data_path(path)?;
        if is_gzip(&img)? {
            let file = BufReader::new(File::open(&img).map_err(io_error(&img))?);
            samples_from_stream(
                MultiGzDecoder::new(file),
                &img,
                header.layout,
                "decompressed NIfTI data in",
            )?
        } else {
            samples_from_file(&img, header.vox_offset, header.layout, "NIfTI data in")?
        }
    } else if gz {
        let skip = header
            .vox_offset
            .checked_sub(header_len as u64)
            .ok_or_else(|| header_error(path, format!("vox_offset {} lies inside the header", header.vox_offset)))?;
        let skipped = std::io::copy(&mut (&mut reader).take(skip), &mut std::io::sink())
            .map_err(|e| header_error(path, format!("gzip decompression failed: {e}")))?;
        if skipped < skip {
            return Err(header_error(path, "file ends before vox_offset"));
        }
        samples_from_stream(reader, path, header.layout, "decompressed NIfTI data in")?
    } else {
        drop(reader);
        samples_from_file(path, header.vox_offset, header.layout, "NIfTI data in")?
    };
    if rescale(&mut data, header.slope, header.inter) {
        meta.notes
            .push(format!("rescaled: value × {} + {}", header.slope, header.inter));
    }
    Ok(Loaded::new(
        Volume::new(header.layout.dims, header.spacing, data)?,
        meta,
    ))
}

fn header_error(path: &Path, message: impl Into<String>) -> VolumeError {
    super::read::format_header_error(path, "NIfTI", message)
}

fn is_gzip(path: &Path) -> Result<bool, VolumeError> {
    let mut magic = [0u8; 2];
    let mut file = File::open(path).map_err(io_error(path))?;
    let got = read_up_to(&mut file, &mut magic, path)?;
    Ok(got == 2 && magic == [0x1f, 0x8b])
}

fn read_up_to<R: Read + ?Sized>(reader: &mut R, buf: &mut [u8], path: &Path) -> Result<usize, VolumeError> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(header_error(path, format!("cannot read the header: {e}"))),
        }
    }
    Ok(filled)
}

fn pair_data_path(path: &Path) -> Result<PathBuf, VolumeError> {
    let name = path.to_string_lossy();
    let candidates = [
        path.with_extension("img"),
        PathBuf::from(name.replace(".hdr.gz", ".img.gz")),
    ];
    candidates
        .into_iter()
        .find(|p| p.exists())
        .ok_or_else(|| header_error(path, "header of a .hdr/.img pair, but the .img file is missing"))
}

/// sizeof_hdr and the byte order that makes it 348 or 540.
fn sizeof_hdr(bytes: &[u8]) -> Option<(i32, Endian)> {
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

struct Fields<'a> {
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

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header, VolumeError> {
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
    })
}

/// Writes a single-file NIfTI volume of f32 or i16 samples (tests and tools). `version` 1 or 2.
#[cfg(test)]
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

#[cfg(test)]
mod tests {
    use std::io::Write;

    use flate2::write::GzEncoder;
    use flate2::Compression;

    use super::super::test_support::{encode_values, test_values, ScratchDir};
    use super::*;

    const DATATYPES: [(ScalarType, i16); 8] = [
        (ScalarType::U8, 2),
        (ScalarType::I8, 256),
        (ScalarType::U16, 512),
        (ScalarType::I16, 4),
        (ScalarType::U32, 768),
        (ScalarType::I32, 8),
        (ScalarType::F32, 16),
        (ScalarType::F64, 64),
    ];

    fn gzip(bytes: &[u8]) -> Vec<u8> {
        let mut e = GzEncoder::new(Vec::new(), Compression::fast());
        e.write_all(bytes).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn round_trips_both_versions_every_type_endianness_and_gzip() {
        let dir = ScratchDir::new("nifti");
        for version in [1u8, 2] {
            for (scalar, code) in DATATYPES {
                for endian in [Endian::Little, Endian::Big] {
                    let values = test_values(scalar);
                    let data = encode_values(&values, scalar, endian);
                    let bytes = write_nifti_bytes(
                        version,
                        [values.len(), 1, 1],
                        [0.9, 0.9, 3.0],
                        code,
                        &data,
                        [0.0, 0.0],
                        endian,
                    );
                    let expected: Vec<f32> = values.iter().map(|&v| v as f32).collect();
                    for gz in [false, true] {
                        let name = format!("v{version}-{scalar}-{endian:?}.nii{}", if gz { ".gz" } else { "" });
                        let p = dir.write(&name, &if gz { gzip(&bytes) } else { bytes.clone() });
                        let l = load_nifti(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
                        assert_eq!(l.volume.data, expected, "{name}");
                        assert_eq!(l.volume.spacing, [0.9, 0.9, 3.0], "{name}");
                        assert_eq!(l.meta.scalar, Some(scalar));
                    }
                }
            }
        }
    }

    #[test]
    fn slope_and_intercept_are_applied() {
        let dir = ScratchDir::new("nifti-scl");
        let data = encode_values(&[0.0, 1.0, 1000.0, 3000.0], ScalarType::I16, Endian::Little);
        for version in [1u8, 2] {
            let bytes = write_nifti_bytes(version, [2, 2, 1], [1.0; 3], 4, &data, [0.5, -1024.0], Endian::Little);
            let l = load_nifti(&dir.write(&format!("s{version}.nii"), &bytes)).expect("load");
            assert_eq!(l.volume.data, vec![-1024.0, -1023.5, -524.0, 476.0]);
        }
    }

    #[test]
    fn malformed_files_fail_clearly() {
        let dir = ScratchDir::new("nifti-bad");
        let good = write_nifti_bytes(1, [4, 4, 4], [1.0; 3], 16, &[0u8; 256], [0.0, 0.0], Endian::Little);
        let mut absurd = good.clone();
        for i in 0..3 {
            absurd[42 + 2 * i..44 + 2 * i].copy_from_slice(&30000i16.to_le_bytes());
        }
        let mut absurd2 = write_nifti_bytes(2, [4, 4, 4], [1.0; 3], 16, &[], [0.0, 0.0], Endian::Little);
        for i in 0..3 {
            absurd2[24 + 8 * i..32 + 8 * i].copy_from_slice(&1_000_000i64.to_le_bytes());
        }
        let mut rgb = good.clone();
        rgb[70..72].copy_from_slice(&128i16.to_le_bytes());
        let mut magic = good.clone();
        magic[344..348].copy_from_slice(b"xyz\0");
        let mut negative = good.clone();
        negative[44..46].copy_from_slice(&(-5i16).to_le_bytes());
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            ("truncated", good[..300].to_vec(), "shorter than a NIfTI header"),
            ("short-data", good[..400].to_vec(), "need 256 bytes"),
            ("absurd", absurd, "exceed the limit"),
            ("absurd2", absurd2, "exceed the limit"),
            ("datatype", rgb, "datatype 128"),
            ("magic", magic, "bad magic"),
            ("negative", negative, "dim[2] = -5"),
            ("garbage", vec![0x42; 600], "not a NIfTI file"),
            ("gz-truncated", gzip(&good)[..40].to_vec(), "NIfTI"),
        ];
        for (name, bytes, expected) in cases {
            let p = dir.write(&format!("{name}.nii"), &bytes);
            let err = load_nifti(&p).expect_err(name).to_string();
            assert!(err.contains(expected), "{name}: '{err}' should mention '{expected}'");
        }
    }
}
