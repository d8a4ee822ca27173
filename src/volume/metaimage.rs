//! MetaImage volumes (ITK): `.mha` with attached data, `.mhd` with a separate data file;
//! raw or zlib-compressed (`CompressedData = True`). ITK's physical space is LPS: the
//! `TransformMatrix` (the direction of each axis in turn) and `Offset` give the patient frame;
//! without a matrix, `AnatomicalOrientation` does (ITK's codes name where each axis starts:
//! "RAI" runs right to left, anterior to posterior, inferior to superior).

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use flate2::read::ZlibDecoder;

use glam::DVec3;

use super::meta::{Format, Loaded, VolumeMeta};
use super::orient::PatientFrame;
use super::read::{io_error, samples_from_file, samples_from_stream, Layout};
use super::{Endian, ScalarType, Volume, VolumeError};

/// Longest header accepted; a binary file mistaken for a header fails fast.
const MAX_HEADER_BYTES: u64 = 1 << 20;

struct Header {
    layout: Layout,
    spacing: [f32; 3],
    compressed: bool,
    /// `None`: data follows the header in the same file.
    data_file: Option<PathBuf>,
    /// Bytes to skip in the data file; `None` for "-1" (data at the end of the file).
    header_size: Option<u64>,
    modality: Option<String>,
    patient: Option<PatientFrame>,
}

/// Loads a `.mha` or `.mhd` file.
pub fn load_metaimage(path: &Path) -> Result<Loaded, VolumeError> {
    let file = File::open(path).map_err(io_error(path))?;
    let mut reader = BufReader::new(file);
    let header = read_header(&mut reader, path)?;
    let (_, expected_bytes) = header.layout.sizes()?;
    let mut meta = VolumeMeta::new(Format::MetaImage, Some(header.layout.scalar));
    if let Some(m) = &header.modality {
        meta = meta.with_modality(m);
    }
    meta.patient = header.patient.clone();
    let data = match (&header.data_file, header.compressed) {
        (None, false) => {
            let offset = reader.stream_position().map_err(io_error(path))?;
            samples_from_file(path, offset, header.layout, "MetaImage data in")?
        }
        (None, true) => samples_from_stream(ZlibDecoder::new(reader), path, header.layout, "zlib data in")?,
        (Some(data_path), compressed) => {
            let file_bytes = std::fs::metadata(data_path).map_err(io_error(data_path))?.len();
            let offset = match header.header_size {
                Some(skip) => skip,
                None if compressed => {
                    return Err(header_error(
                        path,
                        "HeaderSize = -1 cannot be used with compressed data",
                    ))
                }
                None => file_bytes.saturating_sub(expected_bytes),
            };
            if compressed {
                let mut file = BufReader::new(File::open(data_path).map_err(io_error(data_path))?);
                file.seek(SeekFrom::Start(offset)).map_err(io_error(data_path))?;
                samples_from_stream(ZlibDecoder::new(file), data_path, header.layout, "zlib data in")?
            } else {
                samples_from_file(data_path, offset, header.layout, "MetaImage data in")?
            }
        }
    };
    Ok(Loaded::new(
        Volume::new(header.layout.dims, header.spacing, data)?,
        meta,
    ))
}

fn header_error(path: &Path, message: impl Into<String>) -> VolumeError {
    super::read::format_header_error(path, "MetaImage", message)
}

fn read_header<R: BufRead>(reader: &mut R, path: &Path) -> Result<Header, VolumeError> {
    let mut ndims = None;
    let mut dims = None;
    let mut spacing = [1.0f32; 3];
    let mut scalar = None;
    let mut endian = Endian::Little;
    let mut compressed = false;
    let mut channels = 1usize;
    let mut header_size = Some(0u64);
    let mut modality = None;
    let mut matrix: Option<Vec<f64>> = None;
    let mut offset: Option<Vec<f64>> = None;
    let mut anatomical: Option<String> = None;
    let mut data_file: Option<Option<PathBuf>> = None;
    let mut consumed = 0u64;
    let mut line_no = 0;
    while data_file.is_none() {
        line_no += 1;
        let mut bytes = Vec::new();
        let read = reader
            .by_ref()
            .take(MAX_HEADER_BYTES - consumed)
            .read_until(b'\n', &mut bytes)
            .map_err(io_error(path))?;
        consumed += read as u64;
        if read == 0 {
            return Err(header_error(
                path,
                if consumed >= MAX_HEADER_BYTES {
                    "header longer than 1 MiB (is this a MetaImage file?)"
                } else {
                    "header ends without ElementDataFile"
                },
            ));
        }
        let line = String::from_utf8(bytes).map_err(|_| header_error(path, format!("line {line_no} is not text")))?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(header_error(
                path,
                format!("line {line_no}: expected 'Key = Value', found '{line}'"),
            ));
        };
        let (key, value) = (key.trim(), value.trim());
        let bad = |what: &str| header_error(path, format!("line {line_no}: {key} = '{value}': {what}"));
        match key.to_ascii_lowercase().as_str() {
            "ndims" => ndims = Some(value.parse::<usize>().map_err(|_| bad("not an integer"))?),
            "dimsize" => {
                let v: Vec<usize> = parse_all(value).ok_or_else(|| bad("expected non-negative integers"))?;
                dims = Some(v);
            }
            "elementspacing" | "elementsize" => {
                let v: Vec<f32> = parse_all(value).ok_or_else(|| bad("expected numbers"))?;
                for (s, v) in spacing.iter_mut().zip(v) {
                    *s = v.abs();
                }
            }
            "elementtype" => scalar = Some(parse_element_type(value).ok_or_else(|| bad("unsupported element type"))?),
            "elementbyteordermsb" | "binarydatabyteordermsb" => {
                endian = if parse_bool(value).ok_or_else(|| bad("expected True or False"))? {
                    Endian::Big
                } else {
                    Endian::Little
                }
            }
            "compresseddata" => compressed = parse_bool(value).ok_or_else(|| bad("expected True or False"))?,
            "elementnumberofchannels" => channels = value.parse().map_err(|_| bad("not an integer"))?,
            "headersize" => {
                header_size = match value.parse::<i64>().map_err(|_| bad("not an integer"))? {
                    -1 => None,
                    n if n >= 0 => Some(n as u64),
                    _ => return Err(bad("must be -1 or ≥ 0")),
                }
            }
            "modality" => modality = Some(value.to_string()),
            "transformmatrix" | "rotation" | "orientation" => {
                matrix = Some(parse_all(value).ok_or_else(|| bad("expected numbers"))?)
            }
            "offset" | "origin" | "position" => offset = Some(parse_all(value).ok_or_else(|| bad("expected numbers"))?),
            "anatomicalorientation" => anatomical = Some(value.to_ascii_uppercase()),
            "elementdatafile" => {
                data_file = Some(if value.eq_ignore_ascii_case("LOCAL") {
                    None
                } else if value.eq_ignore_ascii_case("LIST") || value.contains('%') {
                    return Err(bad("multi-file data is not supported; use a single data file"));
                } else {
                    Some(path.parent().unwrap_or(Path::new("")).join(value))
                })
            }
            _ => {}
        }
    }
    let ndims = ndims.ok_or_else(|| header_error(path, "missing NDims"))?;
    let dims = dims.ok_or_else(|| header_error(path, "missing DimSize"))?;
    if dims.len() != ndims {
        return Err(header_error(
            path,
            format!("DimSize has {} entries but NDims is {ndims}", dims.len()),
        ));
    }
    // 2-D images load as one slice; trailing axes of size 1 are dropped.
    let dims: [usize; 3] = match dims.as_slice() {
        [x, y] => [*x, *y, 1],
        [x, y, z, rest @ ..] if rest.iter().all(|&d| d == 1) => [*x, *y, *z],
        _ => {
            return Err(header_error(
                path,
                format!("NDims {ndims} with DimSize {dims:?}: only 3-D volumes load"),
            ))
        }
    };
    if channels != 1 {
        return Err(header_error(
            path,
            format!("{channels} channels per voxel: only scalar volumes load"),
        ));
    }
    let scalar = scalar.ok_or_else(|| header_error(path, "missing ElementType"))?;
    let patient = patient_frame(ndims, matrix.as_deref(), offset.as_deref(), anatomical.as_deref());
    Ok(Header {
        layout: Layout { dims, scalar, endian },
        spacing,
        compressed,
        data_file: data_file.flatten(),
        header_size,
        modality,
        patient,
    })
}

/// The patient frame of a 3-D image: the TransformMatrix (axis after axis, LPS) with the
/// Offset, or else the AnatomicalOrientation code. An identity matrix with a code that says
/// otherwise follows the code (older writers left the matrix at identity).
fn patient_frame(
    ndims: usize,
    matrix: Option<&[f64]>,
    offset: Option<&[f64]>,
    code: Option<&str>,
) -> Option<PatientFrame> {
    if ndims != 3 {
        return None;
    }
    let origin = match offset {
        Some([x, y, z]) => DVec3::new(*x, *y, *z),
        _ => DVec3::ZERO,
    };
    let from_code = code.and_then(|c| {
        let axes: Vec<DVec3> = c
            .chars()
            .map(|l| match l {
                // The letter names where the axis starts.
                'R' => Some(DVec3::X),
                'L' => Some(-DVec3::X),
                'A' => Some(DVec3::Y),
                'P' => Some(-DVec3::Y),
                'I' => Some(DVec3::Z),
                'S' => Some(-DVec3::Z),
                _ => None,
            })
            .collect::<Option<_>>()?;
        PatientFrame::new(axes.try_into().ok()?, origin, "MetaImage AnatomicalOrientation")
    });
    let from_matrix = match matrix {
        Some(&[a, b, c, d, e, f, g, h, i]) => PatientFrame::new(
            [DVec3::new(a, b, c), DVec3::new(d, e, f), DVec3::new(g, h, i)],
            origin,
            "MetaImage TransformMatrix",
        ),
        _ => None,
    };
    let identity = [DVec3::X, DVec3::Y, DVec3::Z];
    match (from_matrix, from_code) {
        (Some(m), Some(c)) if m.axes == identity => Some(c),
        (Some(m), _) => Some(m),
        (None, c) => c,
    }
}

fn parse_all<T: std::str::FromStr>(value: &str) -> Option<Vec<T>> {
    value.split_whitespace().map(|t| t.parse().ok()).collect()
}

fn parse_bool(value: &str) -> Option<bool> {
    match value.to_ascii_lowercase().as_str() {
        "true" | "1" => Some(true),
        "false" | "0" => Some(false),
        _ => None,
    }
}

fn parse_element_type(value: &str) -> Option<ScalarType> {
    Some(match value.to_ascii_uppercase().as_str() {
        "MET_UCHAR" => ScalarType::U8,
        "MET_CHAR" => ScalarType::I8,
        "MET_USHORT" => ScalarType::U16,
        "MET_SHORT" => ScalarType::I16,
        "MET_UINT" | "MET_ULONG" => ScalarType::U32,
        "MET_INT" | "MET_LONG" => ScalarType::I32,
        "MET_FLOAT" => ScalarType::F32,
        "MET_DOUBLE" => ScalarType::F64,
        _ => return None,
    })
}

/// The MetaImage name of a scalar type (for writers in tests and tools).
pub fn element_type_name(scalar: ScalarType) -> &'static str {
    match scalar {
        ScalarType::U8 => "MET_UCHAR",
        ScalarType::I8 => "MET_CHAR",
        ScalarType::U16 => "MET_USHORT",
        ScalarType::I16 => "MET_SHORT",
        ScalarType::U32 => "MET_UINT",
        ScalarType::I32 => "MET_INT",
        ScalarType::F32 => "MET_FLOAT",
        ScalarType::F64 => "MET_DOUBLE",
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use flate2::write::ZlibEncoder;
    use flate2::Compression;

    use super::super::meta::Units;
    use super::super::test_support::{encode_values, test_values, ScratchDir};
    use super::*;

    fn header(dims: &str, scalar: ScalarType, endian: Endian, extra: &str, data_file: &str) -> String {
        format!(
            "ObjectType = Image\nNDims = 3\nDimSize = {dims}\nElementSpacing = 0.5 0.75 2\n\
             ElementByteOrderMSB = {}\n{extra}ElementType = {}\nElementDataFile = {data_file}\n",
            if endian == Endian::Big { "True" } else { "False" },
            element_type_name(scalar)
        )
    }

    #[test]
    fn round_trips_every_type_endianness_and_layout() {
        let dir = ScratchDir::new("mha");
        for scalar in ScalarType::ALL {
            for endian in [Endian::Little, Endian::Big] {
                let values = test_values(scalar);
                let dims = format!("{} 1 1", values.len());
                let data = encode_values(&values, scalar, endian);
                let expected: Vec<f32> = values.iter().map(|&v| v as f32).collect();
                // Attached, raw.
                let mut bytes = header(&dims, scalar, endian, "", "LOCAL").into_bytes();
                bytes.extend(&data);
                let p = dir.write(&format!("{scalar}-{endian:?}.mha"), &bytes);
                let l = load_metaimage(&p).unwrap_or_else(|e| panic!("{scalar} {endian:?}: {e}"));
                assert_eq!(l.volume.data, expected, "{scalar} {endian:?}");
                assert_eq!(l.volume.spacing, [0.5, 0.75, 2.0]);
                assert_eq!(l.meta.scalar, Some(scalar));
                // Attached, zlib.
                let mut z = ZlibEncoder::new(Vec::new(), Compression::fast());
                z.write_all(&data).unwrap();
                let mut bytes = header(&dims, scalar, endian, "CompressedData = True\n", "LOCAL").into_bytes();
                bytes.extend(z.finish().unwrap());
                let p = dir.write(&format!("{scalar}-{endian:?}-z.mha"), &bytes);
                assert_eq!(load_metaimage(&p).expect("zlib").volume.data, expected);
                // Detached with a header to skip.
                let raw_name = format!("{scalar}-{endian:?}.raw");
                let mut raw = vec![7u8; 5];
                raw.extend(&data);
                dir.write(&raw_name, &raw);
                let text = header(&dims, scalar, endian, "HeaderSize = 5\n", &raw_name);
                let p = dir.write(&format!("{scalar}-{endian:?}.mhd"), text.as_bytes());
                assert_eq!(load_metaimage(&p).expect("mhd").volume.data, expected);
                // HeaderSize = -1: data at the end.
                let text = header(&dims, scalar, endian, "HeaderSize = -1\n", &raw_name);
                let p = dir.write(&format!("{scalar}-{endian:?}-end.mhd"), text.as_bytes());
                assert_eq!(load_metaimage(&p).expect("mhd -1").volume.data, expected);
            }
        }
    }

    #[test]
    fn ct_modality_means_hounsfield() {
        let dir = ScratchDir::new("mha-ct");
        let mut bytes = header(
            "2 1 1",
            ScalarType::I16,
            Endian::Little,
            "Modality = MET_MOD_CT\n",
            "LOCAL",
        )
        .into_bytes();
        bytes.extend(encode_values(&[-1000.0, 400.0], ScalarType::I16, Endian::Little));
        let l = load_metaimage(&dir.write("ct.mha", &bytes)).expect("load");
        assert_eq!(l.meta.units, Units::Hounsfield);
        assert_eq!(l.default_window(), super::super::meta::CT_WINDOW);
    }

    #[test]
    fn malformed_files_fail_clearly() {
        let dir = ScratchDir::new("mha-bad");
        let le = Endian::Little;
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            (
                "truncated",
                [
                    header("4 4 4", ScalarType::U16, le, "", "LOCAL").as_bytes(),
                    &[0u8; 100],
                ]
                .concat(),
                "need 128 bytes",
            ),
            (
                "absurd",
                header("1000000 1000000 1000000", ScalarType::U8, le, "", "LOCAL").into_bytes(),
                "exceed the limit",
            ),
            (
                "type",
                header("1 1 1", ScalarType::U8, le, "", "LOCAL")
                    .replace("MET_UCHAR", "MET_FLOAT_ARRAY")
                    .into_bytes(),
                "unsupported element type",
            ),
            (
                "ndims",
                header("2 2", ScalarType::U8, le, "", "LOCAL").into_bytes(),
                "DimSize has 2 entries",
            ),
            (
                "noend",
                b"NDims = 3\nDimSize = 1 1 1\n".to_vec(),
                "without ElementDataFile",
            ),
            ("garbage", vec![0xFF; 300], "not text"),
            (
                "zlib",
                [
                    header("4 4 4", ScalarType::U8, le, "CompressedData = True\n", "LOCAL").as_bytes(),
                    &[1u8, 2, 3, 4][..],
                ]
                .concat(),
                "zlib",
            ),
            (
                "missing",
                header("4 4 4", ScalarType::U8, le, "", "nowhere.raw").into_bytes(),
                "nowhere.raw",
            ),
        ];
        for (name, bytes, expected) in cases {
            let p = dir.write(&format!("{name}.mha"), &bytes);
            let err = load_metaimage(&p).expect_err(name).to_string();
            let err = format!(
                "{err} {}",
                std::error::Error::source(&load_metaimage(&p).unwrap_err())
                    .map(|s| s.to_string())
                    .unwrap_or_default()
            );
            assert!(err.contains(expected), "{name}: '{err}' should mention '{expected}'");
        }
    }

    #[test]
    fn transform_matrix_or_anatomical_orientation_give_the_patient_frame() {
        let dir = ScratchDir::new("mha-orient");
        let data = [0u8; 8];
        let cases = [
            // ITK writes both: the matrix (axis after axis) wins.
            (
                "TransformMatrix = 0 1 0 -1 0 0 0 0 1\nOffset = 1 2 3\nAnatomicalOrientation = PLI\n",
                Some("PRS"),
                "MetaImage TransformMatrix",
            ),
            // No matrix: ITK's code names where each axis starts.
            (
                "AnatomicalOrientation = RAI\n",
                Some("LPS"),
                "MetaImage AnatomicalOrientation",
            ),
            (
                "AnatomicalOrientation = LPS\n",
                Some("RAI"),
                "MetaImage AnatomicalOrientation",
            ),
            ("", None, ""),
        ];
        for (extra, codes, source) in cases {
            let mut bytes = header("2 2 2", ScalarType::U8, Endian::Little, extra, "LOCAL").into_bytes();
            bytes.extend(data);
            let l = load_metaimage(&dir.write("o.mha", &bytes)).expect(extra);
            let frame = l.meta.patient;
            assert_eq!(frame.as_ref().map(|f| f.axis_codes()).as_deref(), codes, "{extra}");
            if let Some(f) = frame {
                assert_eq!(f.source, source);
            }
        }
    }
}
