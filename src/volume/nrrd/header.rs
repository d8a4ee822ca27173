//! Parsing of NRRD0001–0005 headers into the few fields a 3-D scalar volume needs.

use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::volume::orient::PatientFrame;
use crate::volume::{Endian, ScalarType, VolumeError};

/// Longest header line accepted; a binary file mistaken for NRRD fails fast instead of
/// being read whole in search of a newline.
const MAX_LINE_BYTES: u64 = 64 * 1024;

/// NRRD types that exist but have no [`ScalarType`] counterpart.
const UNSUPPORTED_TYPES: &[&str] = &[
    "longlong",
    "long long",
    "long long int",
    "signed long long",
    "signed long long int",
    "int64",
    "int64_t",
    "ulonglong",
    "unsigned long long",
    "unsigned long long int",
    "uint64",
    "uint64_t",
    "block",
];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Encoding {
    Raw,
    Gzip,
    Ascii,
}

#[derive(Clone, Debug)]
pub(super) struct NrrdHeader {
    pub scalar: ScalarType,
    pub dims: [usize; 3],
    pub endian: Endian,
    pub encoding: Encoding,
    pub spacing: [f32; 3],
    /// Detached data file, resolved against the header's directory; `None` when attached.
    pub data_file: Option<PathBuf>,
    pub line_skip: u64,
    pub byte_skip: u64,
    /// Value of a `modality:=` key/value pair (CT, MR, ...).
    pub modality: Option<String>,
    /// From `space`, `space directions` and `space origin` when the space is anatomical.
    pub patient: Option<PatientFrame>,
}

/// Fields as found, before checking that the required ones are present.
#[derive(Default)]
struct Fields {
    scalar: Option<ScalarType>,
    dimension: bool,
    sizes: Option<[usize; 3]>,
    endian: Option<Endian>,
    encoding: Option<Encoding>,
    spacings: Option<[f32; 3]>,
    directions: Option<[Option<[f64; 3]>; 3]>,
    space: Option<String>,
    origin: Option<[f64; 3]>,
    data_file: Option<PathBuf>,
    line_skip: u64,
    byte_skip: u64,
    modality: Option<String>,
}

/// Reads the header from `reader`, leaving it at the first byte after the blank line that
/// ends the header (where attached data starts). `path` is used for messages and to resolve
/// a detached data file.
pub(super) fn read_header<R: BufRead>(reader: &mut R, path: &Path) -> Result<NrrdHeader, VolumeError> {
    let header_err = |line: usize, message: String| VolumeError::Header {
        format: "NRRD",
        path: path.to_path_buf(),
        line: Some(line),
        message,
    };
    let magic = read_line(reader, path, 1)?.unwrap_or_default();
    let version_ok = magic
        .strip_prefix("NRRD000")
        .is_some_and(|v| matches!(v, "1" | "2" | "3" | "4" | "5"));
    if !version_ok {
        let shown: String = magic.chars().take(40).collect();
        return Err(header_err(
            1,
            format!("not a NRRD file: first line must be NRRD0001..NRRD0005, found '{shown}'"),
        ));
    }

    let mut fields = Fields::default();
    let mut line_no = 1;
    loop {
        line_no += 1;
        let Some(line) = read_line(reader, path, line_no)? else {
            break;
        };
        if line.is_empty() {
            break;
        }
        if line.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(header_err(line_no, format!("expected 'field: value', found '{line}'")));
        };
        // "key:=value" lines are free-form key/value pairs; only the modality means something here.
        if let Some(kv) = value.strip_prefix('=') {
            if key.trim().eq_ignore_ascii_case("modality") {
                fields.modality = Some(kv.trim().to_string());
            }
            continue;
        }
        parse_field(&mut fields, key.trim(), value.trim(), path).map_err(|e| match e {
            FieldError::Encoding(encoding) => VolumeError::UnsupportedEncoding {
                path: path.to_path_buf(),
                encoding,
            },
            FieldError::Invalid(message) => header_err(line_no, message),
        })?;
    }
    finish(fields, path)
}

enum FieldError {
    Encoding(String),
    Invalid(String),
}

impl From<String> for FieldError {
    fn from(message: String) -> FieldError {
        FieldError::Invalid(message)
    }
}

fn parse_field(fields: &mut Fields, key: &str, value: &str, path: &Path) -> Result<(), FieldError> {
    match key.to_ascii_lowercase().as_str() {
        "type" => fields.scalar = Some(parse_type(value)?),
        "dimension" => {
            let dimension: usize = parse_number(value, "dimension")?;
            if dimension != 3 {
                return Err(
                    format!("dimension {dimension} is not supported: only 3-D scalar volumes can be loaded").into(),
                );
            }
            fields.dimension = true;
        }
        "sizes" => {
            let sizes = parse_list(value, "sizes", |t| parse_number::<usize>(t, "sizes"))?;
            fields.sizes = Some(sizes);
        }
        "endian" => {
            fields.endian = Some(match value.to_ascii_lowercase().as_str() {
                "little" => Endian::Little,
                "big" => Endian::Big,
                _ => return Err(format!("unknown endian '{value}' (expected little or big)").into()),
            })
        }
        "encoding" => {
            fields.encoding = Some(match value.to_ascii_lowercase().as_str() {
                "raw" => Encoding::Raw,
                "gzip" | "gz" => Encoding::Gzip,
                "ascii" | "text" | "txt" => Encoding::Ascii,
                _ => return Err(FieldError::Encoding(value.to_string())),
            })
        }
        "spacings" => fields.spacings = Some(parse_list(value, "spacings", parse_spacing)?),
        "space directions" => fields.directions = Some(parse_directions(value)?),
        "space" => fields.space = Some(value.to_ascii_lowercase()),
        "space origin" => {
            let [origin] = parse_vectors::<1>(value, "space origin")?;
            fields.origin = Some(origin.ok_or_else(|| "space origin: expected a vector, not 'none'".to_string())?);
        }
        "data file" | "datafile" => fields.data_file = parse_data_file(value, path)?,
        "line skip" | "lineskip" => fields.line_skip = parse_number(value, "line skip")?,
        "byte skip" | "byteskip" => {
            if value.starts_with('-') {
                return Err(format!("byte skip {value} is not supported: only non-negative byte skips are").into());
            }
            fields.byte_skip = parse_number(value, "byte skip")?;
        }
        "content" | "space dimension" | "space units" | "kinds" | "centers" | "centerings" | "labels" | "units"
        | "min" | "max" | "old min" | "oldmin" | "old max" | "oldmax" | "measurement frame" | "thicknesses"
        | "axis mins" | "axismins" | "axis maxs" | "axismaxs" | "sample units" | "sampleunits" | "number"
        | "block size" | "blocksize" => {}
        other => log::warn!("{}: ignoring unknown NRRD field '{other}'", path.display()),
    }
    Ok(())
}

fn finish(fields: Fields, path: &Path) -> Result<NrrdHeader, VolumeError> {
    let missing = |name: &str| VolumeError::Header {
        format: "NRRD",
        path: path.to_path_buf(),
        line: None,
        message: format!("missing required field '{name}'"),
    };
    let scalar = fields.scalar.ok_or_else(|| missing("type"))?;
    if !fields.dimension {
        return Err(missing("dimension"));
    }
    let dims = fields.sizes.ok_or_else(|| missing("sizes"))?;
    let encoding = fields.encoding.ok_or_else(|| missing("encoding"))?;
    let endian = match fields.endian {
        Some(endian) => endian,
        None => {
            if scalar.size_bytes() > 1 && encoding != Encoding::Ascii {
                log::warn!("{}: no 'endian' field, assuming little", path.display());
            }
            Endian::Little
        }
    };
    let norms = fields
        .directions
        .map(|d| d.map(|v| v.map_or(1.0, |v| DVec3::from(v).length() as f32)));
    let spacing = norms.or(fields.spacings).unwrap_or([1.0; 3]);
    let patient = match (fields.space.as_deref(), fields.directions) {
        (Some(space), Some([Some(x), Some(y), Some(z)])) => {
            let origin = DVec3::from(fields.origin.unwrap_or([0.0; 3]));
            let axes = [x, y, z].map(DVec3::from);
            match space {
                "left-posterior-superior" | "lps" => PatientFrame::new(axes, origin, "NRRD space directions"),
                "right-anterior-superior" | "ras" => PatientFrame::from_ras(axes, origin, "NRRD space directions"),
                "left-anterior-superior" | "las" => {
                    let lps = |v: DVec3| DVec3::new(v.x, -v.y, v.z);
                    PatientFrame::new(axes.map(lps), lps(origin), "NRRD space directions")
                }
                _ => None,
            }
        }
        _ => None,
    };
    Ok(NrrdHeader {
        scalar,
        dims,
        endian,
        encoding,
        spacing,
        data_file: fields.data_file,
        line_skip: fields.line_skip,
        byte_skip: fields.byte_skip,
        modality: fields.modality,
        patient,
    })
}

/// Reads one line without its terminator; `None` at end of input.
fn read_line<R: BufRead>(reader: &mut R, path: &Path, line_no: usize) -> Result<Option<String>, VolumeError> {
    let mut bytes = Vec::new();
    let read = reader
        .by_ref()
        .take(MAX_LINE_BYTES)
        .read_until(b'\n', &mut bytes)
        .map_err(|source| VolumeError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    if read == 0 {
        return Ok(None);
    }
    let header_err = |message: &str| VolumeError::Header {
        format: "NRRD",
        path: path.to_path_buf(),
        line: Some(line_no),
        message: message.to_string(),
    };
    if bytes.last() != Some(&b'\n') && read as u64 == MAX_LINE_BYTES {
        return Err(header_err("line longer than 64 KiB (is this a NRRD file?)"));
    }
    let text = String::from_utf8(bytes).map_err(|_| header_err("line is not valid text"))?;
    Ok(Some(text.trim_end_matches(['\n', '\r']).to_string()))
}

fn parse_type(value: &str) -> Result<ScalarType, String> {
    value.parse::<ScalarType>().map_err(|_| {
        let key = value.to_ascii_lowercase();
        if UNSUPPORTED_TYPES.contains(&key.as_str()) {
            format!("type '{value}' is not supported (64-bit integers and blocks cannot be loaded)")
        } else {
            format!("unknown type '{value}'")
        }
    })
}

fn parse_number<T: std::str::FromStr>(token: &str, field: &str) -> Result<T, String> {
    token
        .parse::<T>()
        .map_err(|_| format!("{field}: '{token}' is not a valid non-negative integer"))
}

fn parse_list<T>(value: &str, field: &str, parse: impl Fn(&str) -> Result<T, String>) -> Result<[T; 3], String> {
    let tokens: Vec<&str> = value.split_whitespace().collect();
    let [a, b, c] = tokens.as_slice() else {
        return Err(format!(
            "{field} has {} entries but the volume has 3 axes",
            tokens.len()
        ));
    };
    Ok([parse(a)?, parse(b)?, parse(c)?])
}

/// NRRD writes "nan" for an unknown spacing; that axis then gets unit spacing.
fn parse_spacing(token: &str) -> Result<f32, String> {
    let spacing: f32 = token
        .parse()
        .map_err(|_| format!("spacings: '{token}' is not a number"))?;
    if spacing.is_nan() {
        return Ok(1.0);
    }
    // A negative spacing only flips the axis direction; its magnitude is the voxel size.
    let size = spacing.abs();
    if !size.is_finite() || size == 0.0 {
        return Err(format!("spacings: '{token}' must be finite and non-zero"));
    }
    Ok(size)
}

/// "(1,0,0) (0,0.5,0) (0,0,2)" → one vector per axis (its length is the voxel size); "none"
/// axes have none.
fn parse_directions(value: &str) -> Result<[Option<[f64; 3]>; 3], String> {
    let vectors = parse_vectors::<3>(value, "space directions")?;
    for v in vectors.iter().flatten() {
        let norm = DVec3::from(*v).length() as f32;
        if !norm.is_finite() || norm == 0.0 {
            return Err(format!("space directions: {v:?} must be a finite non-zero vector"));
        }
    }
    Ok(vectors)
}

/// `N` vectors "(x,y,z)" or "none", separated by spaces.
fn parse_vectors<const N: usize>(value: &str, field: &str) -> Result<[Option<[f64; 3]>; N], String> {
    let mut vectors = Vec::new();
    let mut rest = value.trim_start();
    while !rest.is_empty() {
        if let Some(after) = rest.strip_prefix("none") {
            vectors.push(None);
            rest = after.trim_start();
            continue;
        }
        let Some(inner_and_rest) = rest.strip_prefix('(') else {
            return Err(format!("{field}: expected '(' or 'none' at '{rest}'"));
        };
        let Some((inner, after)) = inner_and_rest.split_once(')') else {
            return Err(format!("{field}: missing ')'"));
        };
        let components = inner
            .split(',')
            .map(|c| {
                c.trim()
                    .parse::<f64>()
                    .map_err(|_| format!("{field}: '{}' is not a number", c.trim()))
            })
            .collect::<Result<Vec<f64>, String>>()?;
        let [x, y, z] = components[..] else {
            return Err(format!("{field}: ({inner}) must have 3 components"));
        };
        vectors.push(Some([x, y, z]));
        rest = after.trim_start();
    }
    let count = vectors.len();
    vectors
        .try_into()
        .map_err(|_| format!("{field} has {count} entries but the volume has {N} axes"))
}

fn parse_data_file(value: &str, header_path: &Path) -> Result<Option<PathBuf>, String> {
    if value.eq_ignore_ascii_case("LOCAL") {
        return Ok(None);
    }
    let tokens: Vec<&str> = value.split_whitespace().collect();
    let multi_file = tokens.first().is_some_and(|t| *t == "LIST")
        || (tokens.len() >= 4 && tokens[0].contains('%') && tokens[1..4].iter().all(|t| t.parse::<i64>().is_ok()));
    if multi_file {
        return Err("multi-file 'data file' forms are not supported; use a single file".into());
    }
    let dir = header_path.parent().unwrap_or(Path::new(""));
    Ok(Some(dir.join(value)))
}
