//! Tests of the NRRD reader and writer against hand-written and generated files.

use std::io::Write;
use std::time::{Duration, Instant};

use flate2::write::GzEncoder;
use flate2::Compression;

use super::{load_nrrd, write_nrrd};
use crate::volume::test_support::ScratchDir;
use crate::volume::{load, Volume, VolumeError};

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = GzEncoder::new(Vec::new(), Compression::fast());
    encoder.write_all(bytes).expect("compress");
    encoder.finish().expect("compress")
}

fn attached(header: &str, data: &[u8]) -> Vec<u8> {
    let mut bytes = header.as_bytes().to_vec();
    bytes.extend_from_slice(data);
    bytes
}

fn sample_volume() -> Volume {
    let dims = [5, 4, 3];
    let data = (0..60)
        .map(|i| (i as f32 * 0.37 - 7.0).powi(3) * 1.0e-3 + 1.0 / (i as f32 + 3.0))
        .collect();
    Volume::new(dims, [0.3, 1.0 / 3.0, 2.5], data).expect("valid volume")
}

#[test]
fn write_read_round_trip_is_exact() {
    let dir = ScratchDir::new("nrrd-roundtrip");
    let vol = sample_volume();
    for gz in [false, true] {
        let path = dir.path(if gz { "vol-gz.nrrd" } else { "vol.nrrd" });
        write_nrrd(&path, &vol, gz).expect("write");
        let back = load(&path).expect("read back");
        assert_eq!(back.dims, vol.dims);
        assert_eq!(back.spacing, vol.spacing);
        assert_eq!(back.data, vol.data, "gzip {gz}");
        assert_eq!(back.value_range, vol.value_range);
    }
}

#[test]
fn attached_raw_i16_big_endian() {
    let dir = ScratchDir::new("nrrd-i16");
    let values: [i16; 8] = [-32768, -2, -1, 0, 1, 300, 1000, 32767];
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    let header = "NRRD0004\n# a comment\ntype: short\ndimension: 3\nsizes: 2 2 2\n\
                  endian: big\nencoding: raw\nmodality:=CT\n\n";
    let path = dir.write("x.nrrd", &attached(header, &data));
    let vol = load_nrrd(&path).expect("load");
    let expected: Vec<f32> = values.iter().map(|&v| f32::from(v)).collect();
    assert_eq!(vol.data, expected);
    assert_eq!(vol.dims, [2, 2, 2]);
    assert_eq!(vol.spacing, [1.0; 3]);
}

#[test]
fn detached_header_with_skips() {
    let dir = ScratchDir::new("nrrd-detached");
    let mut data = b"junk line\n1234".to_vec();
    data.extend([10u8, 20, 30, 40, 50, 60]);
    dir.write("data.bin", &data);
    let header = "NRRD0005\ntype: uint8\ndimension: 3\nsizes: 3 2 1\nencoding: raw\n\
                  spacings: 0.5 nan 2\ndata file: data.bin\nline skip: 1\nbyte skip: 4\n";
    let path = dir.write("head.nhdr", header.as_bytes());
    let vol = load(&path).expect("load");
    assert_eq!(vol.data, vec![10.0, 20.0, 30.0, 40.0, 50.0, 60.0]);
    assert_eq!(vol.spacing, [0.5, 1.0, 2.0]);
}

#[test]
fn space_directions_give_spacing() {
    let dir = ScratchDir::new("nrrd-directions");
    let header = "NRRD0004\ntype: float\ndimension: 3\nspace: left-posterior-superior\n\
                  sizes: 1 1 2\nspace directions: (0,0.5,0) (-3,0,4) (0, 0, 2.5)\n\
                  space origin: (0,0,0)\nendian: little\nencoding: raw\n\n";
    let data: Vec<u8> = [1.5f32, -2.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    let path = dir.write("dirs.nrrd", &attached(header, &data));
    let vol = load_nrrd(&path).expect("load");
    assert_eq!(vol.spacing, [0.5, 5.0, 2.5]);
    assert_eq!(vol.data, vec![1.5, -2.0]);
}

#[test]
fn anatomical_spaces_give_the_patient_frame_in_lps() {
    use glam::DVec3;
    let dir = ScratchDir::new("nrrd-space");
    let data: Vec<u8> = [1.0f32, 2.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    // The same voxel axes (x towards the patient's right, y anterior, z superior) written in
    // each anatomical space; "none" or a non-anatomical space gives no frame.
    for (space, dirs, origin, codes) in [
        (
            "right-anterior-superior",
            "(2,0,0) (0,2,0) (0,0,3)",
            "(10,20,30)",
            Some("RAS"),
        ),
        ("RAS", "(2,0,0) (0,2,0) (0,0,3)", "(10,20,30)", Some("RAS")),
        (
            "left-posterior-superior",
            "(-2,0,0) (0,-2,0) (0,0,3)",
            "(-10,-20,30)",
            Some("RAS"),
        ),
        (
            "left-anterior-superior",
            "(-2,0,0) (0,2,0) (0,0,3)",
            "(-10,20,30)",
            Some("RAS"),
        ),
        ("scanner-xyz", "(2,0,0) (0,2,0) (0,0,3)", "(10,20,30)", None),
    ] {
        let header = format!(
            "NRRD0004\ntype: float\ndimension: 3\nspace: {space}\nsizes: 1 1 2\n\
             space directions: {dirs}\nspace origin: {origin}\nendian: little\nencoding: raw\n\n"
        );
        let path = dir.write("o.nrrd", &attached(&header, &data));
        let loaded = super::open_nrrd(&path).expect("load");
        assert_eq!(loaded.volume.spacing, [2.0, 2.0, 3.0], "{space}");
        let frame = loaded.meta.patient;
        assert_eq!(frame.as_ref().map(|f| f.axis_codes()).as_deref(), codes, "{space}");
        if let Some(f) = frame {
            assert!((f.origin - DVec3::new(-10.0, -20.0, 30.0)).length() < 1e-9, "{space}");
        }
    }
}

#[test]
fn ascii_encoding() {
    let dir = ScratchDir::new("nrrd-ascii");
    let header = "NRRD0001\ntype: double\ndimension: 3\nsizes: 2 2 1\nencoding: ascii\n\n";
    let path = dir.write("a.nrrd", &attached(header, b"1 2.5\n-3e2,\t4\n"));
    let vol = load_nrrd(&path).expect("load");
    assert_eq!(vol.data, vec![1.0, 2.5, -300.0, 4.0]);

    let short = dir.write("short.nrrd", &attached(header, b"1 2 3\n"));
    let err = load_nrrd(&short).unwrap_err();
    assert!(err.to_string().contains("3 values"), "{err}");
    let bad = dir.write("bad.nrrd", &attached(header, b"1 2 x 4\n"));
    let err = load_nrrd(&bad).unwrap_err();
    assert!(err.to_string().contains("'x'"), "{err}");
}

#[test]
fn gzip_encoding() {
    let dir = ScratchDir::new("nrrd-gzip");
    let header = "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 2 1 2\n\
                  endian: little\nencoding: gz\n\n";
    let raw: Vec<u8> = [7u16, 65535, 0, 300].iter().flat_map(|v| v.to_le_bytes()).collect();
    let path = dir.write("g.nrrd", &attached(header, &gzip(&raw)));
    let vol = load_nrrd(&path).expect("load");
    assert_eq!(vol.data, vec![7.0, 65535.0, 0.0, 300.0]);
}

fn header_error(text: &str) -> VolumeError {
    let dir = ScratchDir::new("nrrd-bad");
    let path = dir.write("x.nrrd", &attached(text, &[0u8; 64]));
    load_nrrd(&path).unwrap_err()
}

#[test]
fn missing_sizes_is_reported() {
    let err = header_error("NRRD0004\ntype: uchar\ndimension: 3\nencoding: raw\n\n");
    assert!(matches!(err, VolumeError::Header { line: None, .. }), "{err}");
    assert!(err.to_string().contains("'sizes'"), "{err}");
}

#[test]
fn unknown_type_names_the_line() {
    let err = header_error("NRRD0004\n# c\ndimension: 3\ntype: flot\nsizes: 1 1 1\n\n");
    let text = err.to_string();
    assert!(text.contains("x.nrrd line 4: unknown type 'flot'"), "{text}");
    let err = header_error("NRRD0004\ntype: int64\n\n");
    assert!(err.to_string().contains("not supported"), "{err}");
}

#[test]
fn unknown_encoding_is_unsupported() {
    let err = header_error("NRRD0004\ntype: uchar\nencoding: bzip2\n\n");
    match err {
        VolumeError::UnsupportedEncoding { encoding, .. } => assert_eq!(encoding, "bzip2"),
        other => panic!("unexpected error {other}"),
    }
}

#[test]
fn other_header_problems() {
    let cases = [
        ("PNG\n", "not a NRRD file"),
        ("NRRD0004\ntype: uchar\ndimension: 4\n\n", "dimension 4"),
        ("NRRD0004\nsizes: 1 2\n\n", "2 entries"),
        ("NRRD0004\nbyte skip: -1\n\n", "byte skip -1"),
        ("NRRD0004\nendian: middle\n\n", "middle"),
        ("NRRD0004\nno separator\n\n", "field: value"),
    ];
    for (header, needle) in cases {
        let err = header_error(header);
        assert!(matches!(err, VolumeError::Header { .. }), "{err}");
        assert!(err.to_string().contains(needle), "{header:?}: {err}");
    }
}

#[test]
fn absurd_sizes_fail_fast() {
    let start = Instant::now();
    let err = header_error(
        "NRRD0004\ntype: float\ndimension: 3\nsizes: 1000000 1000000 1000000\n\
         endian: little\nencoding: gzip\n\n",
    );
    assert!(matches!(err, VolumeError::TooLarge { .. }), "{err}");
    assert!(start.elapsed() < Duration::from_secs(2));
}

#[test]
fn truncated_raw_data() {
    let dir = ScratchDir::new("nrrd-truncated");
    let header = "NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4 4\nendian: little\n\
                  encoding: raw\n\n";
    let path = dir.write("t.nrrd", &attached(header, &[0u8; 100]));
    let err = load_nrrd(&path).unwrap_err();
    assert!(
        matches!(
            err,
            VolumeError::Truncated {
                expected_bytes: 256,
                actual_bytes: 100,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn gzip_shorter_than_claimed() {
    let dir = ScratchDir::new("nrrd-gzip-short");
    let header = "NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4 4\nendian: little\n\
                  encoding: gzip\n\n";
    let path = dir.write("s.nrrd", &attached(header, &gzip(&[0u8; 200])));
    let err = load_nrrd(&path).unwrap_err();
    assert!(
        matches!(
            err,
            VolumeError::Truncated {
                expected_bytes: 256,
                actual_bytes: 200,
                ..
            }
        ),
        "{err}"
    );
    let corrupt = dir.write("c.nrrd", &attached(header, b"not gzip at all"));
    assert!(matches!(load_nrrd(&corrupt), Err(VolumeError::Data { .. })));
}

#[test]
fn missing_data_file_is_io_error() {
    let dir = ScratchDir::new("nrrd-nodata");
    let header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n\
                  data file: nowhere.raw\n";
    let path = dir.write("h.nhdr", header.as_bytes());
    let err = load(&path).unwrap_err();
    assert!(matches!(err, VolumeError::Io { .. }), "{err}");
    assert!(err.to_string().contains("nowhere.raw"), "{err}");
}

#[test]
fn every_scalar_type_and_endianness_round_trips() {
    use crate::volume::test_support::{encode_values, test_values};
    use crate::volume::{Endian, ScalarType};
    let dir = ScratchDir::new("nrrd-types");
    for scalar in ScalarType::ALL {
        for (endian, name) in [(Endian::Little, "little"), (Endian::Big, "big")] {
            let values = test_values(scalar);
            let data = encode_values(&values, scalar, endian);
            let header = format!(
                "NRRD0004\ntype: {scalar}\ndimension: 3\nsizes: {} 1 1\nendian: {name}\nencoding: raw\n\
                 space directions: (0.5,0,0) (0,1,0) (0,0,5)\nmodality:=CT\n\n",
                values.len()
            );
            let path = dir.write(&format!("{scalar}-{name}.nrrd"), &attached(&header, &data));
            let loaded = super::open_nrrd(&path).unwrap_or_else(|e| panic!("{scalar} {name}: {e}"));
            let expected: Vec<f32> = values.iter().map(|&v| v as f32).collect();
            assert_eq!(loaded.volume.data, expected, "{scalar} {name}");
            assert_eq!(loaded.volume.spacing, [0.5, 1.0, 5.0]);
            assert_eq!(loaded.meta.units, crate::volume::Units::Hounsfield);
            assert_eq!(loaded.meta.scalar, Some(scalar));
        }
    }
}
