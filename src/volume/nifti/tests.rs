//! Round trips, rescale, orientation and malformed headers of the NIfTI reader.

use std::io::Write;

use flate2::write::GzEncoder;
use flate2::Compression;

use super::super::test_support::{encode_values, test_values, ScratchDir};
use super::write::write_nifti_bytes;
use super::*;
use crate::volume::ScalarType;

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

#[test]
fn sform_and_qform_give_the_patient_frame_in_lps() {
    use glam::DVec3;

    use super::write::{set_qform, set_sform};
    let dir = ScratchDir::new("nifti-orient");
    let data = [0u8; 8];
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-5;
    for version in [1u8, 2] {
        // Voxel x runs along RAS −x (towards the patient's left), y anterior, z superior;
        // 2 mm voxels, origin (10, −20, 30) in RAS.
        let mut bytes = write_nifti_bytes(version, [2, 2, 2], [2.0; 3], 2, &data, [0.0, 0.0], Endian::Little);
        set_sform(
            &mut bytes,
            version,
            [[-2.0, 0.0, 0.0, 10.0], [0.0, 2.0, 0.0, -20.0], [0.0, 0.0, 2.0, 30.0]],
        );
        let l = load_nifti(&dir.write(&format!("s{version}.nii"), &bytes)).unwrap();
        let f = l.meta.patient.expect("sform frame");
        assert_eq!(f.source, "NIfTI sform");
        // RAS (−1, 0, 0) is LPS (1, 0, 0): towards the patient's left.
        assert_eq!(f.axis_codes(), "LAS", "v{version}");
        assert!(close(f.origin, DVec3::new(-10.0, 20.0, 30.0)));
    }
    // qform: 90° about z (b = c = 0, d = sin 45°) maps voxel x to RAS +y (anterior) and
    // voxel y to RAS −x (left); qfac −1 flips z to inferior.
    let mut bytes = write_nifti_bytes(1, [2, 2, 2], [1.0; 3], 2, &data, [0.0, 0.0], Endian::Little);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    set_qform(&mut bytes, [0.0, 0.0, s], [1.0, 2.0, 3.0], -1.0);
    let f = load_nifti(&dir.write("q.nii", &bytes))
        .unwrap()
        .meta
        .patient
        .expect("qform frame");
    assert_eq!((f.source, f.axis_codes().as_str()), ("NIfTI qform", "ALI"));
    assert!(close(f.origin, DVec3::new(-1.0, -2.0, 3.0)));
    // Neither code set: no frame.
    let plain = write_nifti_bytes(1, [2, 2, 2], [1.0; 3], 2, &data, [0.0, 0.0], Endian::Little);
    assert!(load_nifti(&dir.write("p.nii", &plain)).unwrap().meta.patient.is_none());
}
