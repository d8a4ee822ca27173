//! Headerless raw voxel files and the scalar type and byte order descriptions they need.

use std::fmt;
use std::fs::File;
use std::io::{BufReader, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::str::FromStr;

use super::decode::read_samples;
use super::{checked_voxel_count, dims_text, Format, Loaded, Volume, VolumeError, VolumeMeta};

pub use super::decode::decode_samples;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScalarType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl ScalarType {
    pub const ALL: [ScalarType; 8] = [
        ScalarType::U8,
        ScalarType::I8,
        ScalarType::U16,
        ScalarType::I16,
        ScalarType::U32,
        ScalarType::I32,
        ScalarType::F32,
        ScalarType::F64,
    ];

    pub fn size_bytes(self) -> usize {
        match self {
            ScalarType::U8 | ScalarType::I8 => 1,
            ScalarType::U16 | ScalarType::I16 => 2,
            ScalarType::U32 | ScalarType::I32 | ScalarType::F32 => 4,
            ScalarType::F64 => 8,
        }
    }

    /// Short canonical name, the same spelling serde uses.
    pub fn name(self) -> &'static str {
        match self {
            ScalarType::U8 => "u8",
            ScalarType::I8 => "i8",
            ScalarType::U16 => "u16",
            ScalarType::I16 => "i16",
            ScalarType::U32 => "u32",
            ScalarType::I32 => "i32",
            ScalarType::F32 => "f32",
            ScalarType::F64 => "f64",
        }
    }
}

impl fmt::Display for ScalarType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ScalarType {
    type Err = VolumeError;

    /// Accepts the short names, C type names and every NRRD spelling, case-insensitively.
    fn from_str(s: &str) -> Result<ScalarType, VolumeError> {
        let key = s.split_whitespace().collect::<Vec<_>>().join(" ").to_ascii_lowercase();
        let scalar = match key.as_str() {
            "u8" | "uint8" | "uint8_t" | "uchar" | "unsigned char" => ScalarType::U8,
            "i8" | "int8" | "int8_t" | "schar" | "signed char" => ScalarType::I8,
            "u16" | "uint16" | "uint16_t" | "ushort" | "unsigned short" | "unsigned short int" => ScalarType::U16,
            "i16" | "int16" | "int16_t" | "short" | "short int" | "signed short" | "signed short int" => {
                ScalarType::I16
            }
            "u32" | "uint32" | "uint32_t" | "uint" | "unsigned int" => ScalarType::U32,
            "i32" | "int32" | "int32_t" | "int" | "signed int" => ScalarType::I32,
            "f32" | "float" | "float32" => ScalarType::F32,
            "f64" | "double" | "float64" => ScalarType::F64,
            _ => return Err(VolumeError::UnsupportedType(s.trim().to_string())),
        };
        Ok(scalar)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Endian {
    #[default]
    Little,
    Big,
}

/// Everything needed to read a raw file, which carries no header of its own.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RawDesc {
    pub path: PathBuf,
    pub dims: [usize; 3],
    pub scalar: ScalarType,
    #[serde(default)]
    pub endian: Endian,
    #[serde(default = "one3")]
    pub spacing: [f32; 3],
    /// Bytes to skip at the start of the file before the first sample.
    #[serde(default)]
    pub header_bytes: u64,
}

fn one3() -> [f32; 3] {
    [1.0; 3]
}

/// What a sidecar file (`head.raw.json` or `head.json` next to `head.raw`) says about a raw
/// file: the fields of [`RawDesc`] without the path, e.g.
/// `{"dims": [256, 256, 108], "scalar": "i16", "spacing": [0.96, 0.96, 1.5], "modality": "CT"}`.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSidecar {
    pub dims: [usize; 3],
    pub scalar: ScalarType,
    #[serde(default)]
    pub endian: Endian,
    #[serde(default = "one3")]
    pub spacing: [f32; 3],
    #[serde(default)]
    pub header_bytes: u64,
    #[serde(default)]
    pub modality: Option<String>,
}

/// The sidecar of a raw file, if one exists: `NAME.json` beside `NAME`, or `STEM.json`.
pub fn sidecar_path(path: &Path) -> Option<PathBuf> {
    let mut appended = path.as_os_str().to_owned();
    appended.push(".json");
    [PathBuf::from(appended), path.with_extension("json")]
        .into_iter()
        .find(|p| p.is_file() && p != path)
}

/// Reads a raw file described by a JSON sidecar.
pub fn load_raw_with_sidecar(path: &Path, sidecar: &Path) -> Result<Loaded, VolumeError> {
    let text = std::fs::read_to_string(sidecar).map_err(|source| VolumeError::Io {
        path: sidecar.to_path_buf(),
        source,
    })?;
    let side: RawSidecar = serde_json::from_str(&text).map_err(|e| VolumeError::Header {
        format: "raw sidecar",
        path: sidecar.to_path_buf(),
        line: Some(e.line()),
        message: e.to_string(),
    })?;
    let desc = RawDesc {
        path: path.to_path_buf(),
        dims: side.dims,
        scalar: side.scalar,
        endian: side.endian,
        spacing: side.spacing,
        header_bytes: side.header_bytes,
    };
    let mut meta = VolumeMeta::new(Format::Raw, Some(desc.scalar));
    if let Some(m) = &side.modality {
        meta = meta.with_modality(m);
    }
    Ok(Loaded::new(load_raw(&desc)?, meta))
}

/// Reads a raw file. The file must hold exactly `header_bytes` plus the samples `dims` need.
pub fn load_raw(desc: &RawDesc) -> Result<Volume, VolumeError> {
    load_raw_data(desc).map_err(|e| e.in_file(&desc.path, "raw"))
}

fn load_raw_data(desc: &RawDesc) -> Result<Volume, VolumeError> {
    let count = checked_voxel_count(desc.dims)?;
    let expected_bytes = count as u64 * desc.scalar.size_bytes() as u64;
    let io_err = |source| VolumeError::Io {
        path: desc.path.clone(),
        source,
    };
    let file = File::open(&desc.path).map_err(io_err)?;
    let file_bytes = file.metadata().map_err(io_err)?.len();
    let actual_bytes = file_bytes.saturating_sub(desc.header_bytes);
    let layout = || {
        let mut text = format!("dims {} of {}", dims_text(&desc.dims), desc.scalar);
        if desc.header_bytes > 0 {
            text += &format!(" after a {}-byte header", desc.header_bytes);
        }
        text
    };
    if actual_bytes < expected_bytes {
        return Err(VolumeError::Truncated {
            kind: "raw file",
            path: desc.path.clone(),
            expected_bytes,
            actual_bytes,
            layout: layout(),
        });
    }
    if actual_bytes > expected_bytes {
        return Err(VolumeError::ExtraData {
            kind: "raw file",
            path: desc.path.clone(),
            expected_bytes,
            actual_bytes,
            layout: layout(),
        });
    }
    let mut reader = BufReader::new(file);
    reader.seek(SeekFrom::Start(desc.header_bytes)).map_err(io_err)?;
    let bar = super::read::progress_bar(expected_bytes, &desc.path);
    let mut reader = bar.wrap_read(reader);
    let (data, bytes_read) = read_samples(&mut reader, count, desc.scalar, desc.endian, count).map_err(io_err)?;
    bar.finish_and_clear();
    if data.len() < count {
        // The file shrank between the size check and the read.
        return Err(VolumeError::Truncated {
            kind: "raw file",
            path: desc.path.clone(),
            expected_bytes,
            actual_bytes: bytes_read,
            layout: layout(),
        });
    }
    Volume::new(desc.dims, desc.spacing, data)
}

#[cfg(test)]
mod tests {
    use super::super::test_support::{encode_values, test_values, ScratchDir};
    use super::*;

    fn desc(path: PathBuf, dims: [usize; 3], scalar: ScalarType) -> RawDesc {
        RawDesc {
            path,
            dims,
            scalar,
            endian: Endian::Little,
            spacing: [1.0, 1.0, 2.5],
            header_bytes: 0,
        }
    }

    #[test]
    fn round_trips_every_type_and_endianness() {
        let dir = ScratchDir::new("raw-roundtrip");
        for scalar in ScalarType::ALL {
            for endian in [Endian::Little, Endian::Big] {
                let values = test_values(scalar);
                let mut bytes = vec![0xAB; 3];
                bytes.extend(encode_values(&values, scalar, endian));
                let path = dir.write(&format!("{scalar}-{endian:?}.raw"), &bytes);
                let mut d = desc(path, [values.len(), 1, 1], scalar);
                d.endian = endian;
                d.header_bytes = 3;
                let vol = load_raw(&d).unwrap_or_else(|e| panic!("{scalar} {endian:?}: {e}"));
                let expected: Vec<f32> = values.iter().map(|&v| v as f32).collect();
                assert_eq!(vol.data, expected, "{scalar} {endian:?}");
                assert_eq!(vol.spacing, [1.0, 1.0, 2.5]);
            }
        }
    }

    #[test]
    fn scalar_names_parse() {
        for (name, scalar) in [
            ("uchar", ScalarType::U8),
            ("unsigned  char", ScalarType::U8),
            ("int16", ScalarType::I16),
            ("short", ScalarType::I16),
            ("Float", ScalarType::F32),
            ("double", ScalarType::F64),
            ("unsigned int", ScalarType::U32),
        ] {
            assert_eq!(name.parse::<ScalarType>().ok(), Some(scalar), "{name}");
        }
        for scalar in ScalarType::ALL {
            assert_eq!(scalar.name().parse::<ScalarType>().ok(), Some(scalar));
        }
        assert!(matches!(
            "flot".parse::<ScalarType>(),
            Err(VolumeError::UnsupportedType(_))
        ));
    }

    #[test]
    fn desc_deserializes_with_defaults() {
        let d: RawDesc = serde_json::from_str(r#"{"path":"a.raw","dims":[2,3,4],"scalar":"i16"}"#).expect("json");
        assert_eq!(d.scalar, ScalarType::I16);
        assert_eq!(d.endian, Endian::Little);
        assert_eq!(d.spacing, [1.0; 3]);
        assert_eq!(d.header_bytes, 0);
    }

    #[test]
    fn truncated_file_is_reported_with_both_sizes() {
        let dir = ScratchDir::new("raw-truncated");
        let path = dir.write("head.raw", &[0u8; 1000]);
        let err = load_raw(&desc(path, [10, 10, 10], ScalarType::I16)).unwrap_err();
        assert!(
            matches!(
                err,
                VolumeError::Truncated {
                    expected_bytes: 2000,
                    actual_bytes: 1000,
                    ..
                }
            ),
            "{err}"
        );
        let text = err.to_string();
        assert!(
            text.contains("has 1000 bytes but dims 10×10×10 of i16 need 2000 bytes"),
            "{text}"
        );
    }

    #[test]
    fn longer_file_is_rejected() {
        let dir = ScratchDir::new("raw-long");
        let path = dir.write("long.raw", &[0u8; 9]);
        let err = load_raw(&desc(path, [2, 2, 2], ScalarType::U8)).unwrap_err();
        assert!(matches!(err, VolumeError::ExtraData { .. }), "{err}");
        let text = err.to_string();
        assert!(text.contains('9') && text.contains('8') && text.contains("dims don't match"));
    }

    #[test]
    fn absurd_dims_fail_before_touching_the_file() {
        let d = desc(PathBuf::from("does-not-exist.raw"), [1_000_000; 3], ScalarType::U8);
        let err = load_raw(&d).unwrap_err();
        assert!(matches!(err.root(), VolumeError::TooLarge { .. }), "{err}");
        assert!(err.to_string().starts_with("does-not-exist.raw (raw): "), "{err}");
    }

    #[test]
    fn sidecar_gives_layout_spacing_and_modality() {
        let dir = ScratchDir::new("raw-sidecar");
        let bytes: Vec<u8> = [-1000i16, 0, 40, 1200].iter().flat_map(|v| v.to_be_bytes()).collect();
        let path = dir.write("head.raw", &bytes);
        let side =
            r#"{"dims": [2, 2, 1], "scalar": "i16", "endian": "big", "spacing": [0.5, 0.5, 3], "modality": "CT"}"#;
        dir.write("head.raw.json", side.as_bytes());
        let loaded = crate::volume::open(&path).expect("load");
        assert_eq!(loaded.volume.data, vec![-1000.0, 0.0, 40.0, 1200.0]);
        assert_eq!(loaded.volume.spacing, [0.5, 0.5, 3.0]);
        assert_eq!(loaded.meta.units, crate::volume::Units::Hounsfield);
        dir.write("head.raw.json", br#"{"dims": [2, 2], "scalar": "i16"}"#);
        let err = crate::volume::open(&path).unwrap_err().to_string();
        assert!(err.contains("head.raw.json") && err.contains("raw sidecar"), "{err}");
    }

    #[test]
    fn nan_voxels_are_rejected() {
        let dir = ScratchDir::new("raw-nan");
        let bytes: Vec<u8> = [1.0f32, f32::NAN, 2.0, f32::NAN]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let path = dir.write("nan.raw", &bytes);
        let err = load_raw(&desc(path.clone(), [2, 2, 1], ScalarType::F32)).unwrap_err();
        assert!(matches!(err.root(), VolumeError::NonFinite { count: 2 }), "{err}");
        assert_eq!(
            err.to_string(),
            format!(
                "{} (raw): volume contains 2 non-finite voxel values (NaN or infinity)",
                path.display()
            )
        );
    }
}
