//! DICOM files written here with dicom-object: every uncompressed syntax, files without a
//! preamble or meta group, scrambled, tilted and incomplete series, several series in one
//! folder, sign extension, 1-bit frames and hostile element lengths. The public test files of
//! every compressed syntax and object type are read in `tests/dicom_files.rs`.

use std::path::{Path, PathBuf};

use dicom_core::{DataElement, PrimitiveValue, VR};
use dicom_dictionary_std::tags;
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
use glam::DVec3;

use super::super::meta::Units;
use super::super::test_support::ScratchDir;
use super::*;

const CT: &str = "1.2.840.10008.5.1.4.1.1.2";
const SR: &str = "1.2.840.10008.5.1.4.1.1.88.33";

/// One slice: geometry, stored pixels and how to store them.
#[derive(Clone)]
struct SliceSpec {
    series: String,
    position: [f64; 3],
    orientation: [f64; 6],
    spacing: [f64; 2],
    rows: u16,
    cols: u16,
    pixels: Vec<u16>,
    bits_stored: u16,
    signed: bool,
    rescale: [f64; 2],
    instance: i64,
}

impl SliceSpec {
    fn new(series: &str, z: f64, pixels: Vec<i16>) -> SliceSpec {
        SliceSpec {
            series: series.into(),
            position: [-10.0, 20.0, z],
            orientation: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            spacing: [0.5, 0.5],
            rows: 2,
            cols: 3,
            pixels: pixels.into_iter().map(|v| v as u16).collect(),
            bits_stored: 16,
            signed: true,
            rescale: [1.0, -1024.0],
            instance: 0,
        }
    }
}

fn ds(values: &[f64]) -> PrimitiveValue {
    PrimitiveValue::from(values.iter().map(|v| v.to_string()).collect::<Vec<_>>().join("\\"))
}

fn image_object(s: &SliceSpec) -> InMemDicomObject {
    let mut o = InMemDicomObject::new_empty();
    let mut put = |tag, vr, value: PrimitiveValue| {
        o.put(DataElement::new(tag, vr, value));
    };
    put(tags::SOP_CLASS_UID, VR::UI, PrimitiveValue::from(CT));
    put(
        tags::SOP_INSTANCE_UID,
        VR::UI,
        PrimitiveValue::from(format!("2.25.{}", s.instance + 1000)),
    );
    put(tags::MODALITY, VR::CS, PrimitiveValue::from("CT"));
    put(
        tags::SERIES_INSTANCE_UID,
        VR::UI,
        PrimitiveValue::from(s.series.as_str()),
    );
    put(
        tags::SERIES_DESCRIPTION,
        VR::LO,
        PrimitiveValue::from(format!("series {}", s.series)),
    );
    put(
        tags::INSTANCE_NUMBER,
        VR::IS,
        PrimitiveValue::from(s.instance.to_string()),
    );
    put(tags::IMAGE_POSITION_PATIENT, VR::DS, ds(&s.position));
    put(tags::IMAGE_ORIENTATION_PATIENT, VR::DS, ds(&s.orientation));
    put(tags::SAMPLES_PER_PIXEL, VR::US, PrimitiveValue::from(1u16));
    put(
        tags::PHOTOMETRIC_INTERPRETATION,
        VR::CS,
        PrimitiveValue::from("MONOCHROME2"),
    );
    put(tags::ROWS, VR::US, PrimitiveValue::from(s.rows));
    put(tags::COLUMNS, VR::US, PrimitiveValue::from(s.cols));
    put(tags::PIXEL_SPACING, VR::DS, ds(&s.spacing));
    put(tags::BITS_ALLOCATED, VR::US, PrimitiveValue::from(16u16));
    put(tags::BITS_STORED, VR::US, PrimitiveValue::from(s.bits_stored));
    put(tags::HIGH_BIT, VR::US, PrimitiveValue::from(s.bits_stored - 1));
    put(
        tags::PIXEL_REPRESENTATION,
        VR::US,
        PrimitiveValue::from(u16::from(s.signed)),
    );
    put(tags::RESCALE_INTERCEPT, VR::DS, ds(&[s.rescale[1]]));
    put(tags::RESCALE_SLOPE, VR::DS, ds(&[s.rescale[0]]));
    put(tags::PIXEL_DATA, VR::OW, PrimitiveValue::U16(s.pixels.clone().into()));
    o
}

/// Writes `obj` as a Part-10 file in transfer syntax `syntax`.
fn write(obj: InMemDicomObject, syntax: &str, sop_class: &str, path: &Path) {
    let file = obj
        .with_meta(
            FileMetaTableBuilder::new()
                .transfer_syntax(syntax)
                .media_storage_sop_class_uid(sop_class),
        )
        .expect("meta");
    file.write_to_file(path).expect("write DICOM");
}

fn write_series(dir: &Path, slices: &[SliceSpec], syntax: &str) -> Vec<PathBuf> {
    slices
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let path = dir.join(format!("{}-{k}.dcm", s.series));
            write(image_object(s), syntax, CT, &path);
            path
        })
        .collect()
}

/// Stored values of slice k of a 3×2 test series.
fn stored(k: i16) -> Vec<i16> {
    (0..6).map(|i| 1000 + 100 * k + i).collect()
}

#[test]
fn uncompressed_syntaxes_load_a_scrambled_series_sorted_and_rescaled() {
    for syntax in [
        parse::EXPLICIT_VR_LE,
        parse::IMPLICIT_VR_LE,
        "1.2.840.10008.1.2.2",
        "1.2.840.10008.1.2.1.99",
    ] {
        let dir = ScratchDir::new("dicom-syntax");
        // Written out of order: z = 4, 0, 2 mm.
        let slices: Vec<SliceSpec> = [(2, 4.0), (0, 0.0), (1, 2.0)]
            .into_iter()
            .map(|(k, z)| SliceSpec::new("1.2.3", z, stored(k)))
            .collect();
        write_series(&dir.path(""), &slices, syntax);
        let l = open_dicom(&dir.path(""), None).unwrap_or_else(|e| panic!("{syntax}: {e}"));
        assert_eq!(l.volume.dims, [3, 2, 3], "{syntax}");
        assert_eq!(l.volume.spacing, [0.5, 0.5, 2.0], "{syntax}");
        let expected: Vec<f32> = (0..3).flat_map(stored).map(|v| f32::from(v) - 1024.0).collect();
        assert_eq!(l.volume.data, expected, "{syntax}");
        assert_eq!(l.meta.units, Units::Hounsfield);
        let frame = l.meta.patient.as_ref().expect("patient frame");
        assert_eq!(frame.axis_codes(), "LPS");
        assert_eq!(frame.origin, DVec3::new(-10.0, 20.0, 0.0));
    }
}

#[test]
fn files_without_preamble_or_meta_group_load() {
    let dir = ScratchDir::new("dicom-nometa");
    let slice = SliceSpec::new("9.8", 0.0, stored(0));
    let full = dir.path("full.dcm");
    write(image_object(&slice), parse::EXPLICIT_VR_LE, CT, &full);
    let bytes = std::fs::read(&full).unwrap();
    let expected: Vec<f32> = stored(0).into_iter().map(|v| f32::from(v) - 1024.0).collect();
    // "DICM" at byte 0, no preamble.
    let no_preamble = dir.write("a/no-preamble.dcm", &bytes[128..]);
    assert_eq!(open_dicom(&no_preamble, None).unwrap().volume.data, expected);
    // A bare implicit VR little endian data set: no preamble, no marker, no meta group.
    let mut bare = Vec::new();
    use dicom_transfer_syntax_registry::TransferSyntaxIndex;
    let implicit = dicom_transfer_syntax_registry::TransferSyntaxRegistry
        .get(parse::IMPLICIT_VR_LE)
        .unwrap();
    image_object(&slice).write_dataset_with_ts(&mut bare, implicit).unwrap();
    let bare = dir.write("b/bare", &bare);
    assert!(is_dicom_file(&bare));
    let l = crate::volume::open(&bare).expect("bare data set");
    assert_eq!(l.volume.data, expected);
}

#[test]
fn bits_stored_are_masked_and_sign_extended() {
    let dir = ScratchDir::new("dicom-bits");
    // 12 stored bits, signed: 0xF000 garbage above bit 11 (an old overlay) must be ignored and
    // 0x800..0xFFF are negative.
    let mut s = SliceSpec::new("4.5", 0.0, vec![0; 6]);
    s.bits_stored = 12;
    s.rescale = [1.0, 0.0];
    s.pixels = vec![0xF001, 0x07FF, 0x0800, 0x0FFF, 0xA123, 0x0000];
    write_series(&dir.path(""), &[s.clone()], parse::EXPLICIT_VR_LE);
    let l = open_dicom(&dir.path(""), None).unwrap();
    assert_eq!(l.volume.data, vec![1.0, 2047.0, -2048.0, -1.0, 0x123 as f32, 0.0]);
    // The same bits unsigned.
    let dir = ScratchDir::new("dicom-bits-u");
    s.signed = false;
    write_series(&dir.path(""), &[s], parse::EXPLICIT_VR_LE);
    let l = open_dicom(&dir.path(""), None).unwrap();
    assert_eq!(l.volume.data, vec![1.0, 2047.0, 2048.0, 4095.0, 0x123 as f32, 0.0]);
}

#[test]
fn one_bit_frames_are_packed_across_frame_boundaries() {
    let dir = ScratchDir::new("dicom-1bit");
    // Two 3×3 frames: 18 bits, the second frame starts inside the second byte.
    let bits: Vec<u8> = vec![1, 0, 1, 1, 1, 0, 0, 0, 1, /* frame 2 */ 0, 1, 1, 0, 0, 0, 1, 1, 0];
    let mut packed = vec![0u8; 3];
    for (i, b) in bits.iter().enumerate() {
        packed[i / 8] |= b << (i % 8);
    }
    let mut o = InMemDicomObject::new_empty();
    let mut put = |tag, vr, value: PrimitiveValue| {
        o.put(DataElement::new(tag, vr, value));
    };
    put(
        tags::SOP_CLASS_UID,
        VR::UI,
        PrimitiveValue::from("1.2.840.10008.5.1.4.1.1.7.1"),
    );
    put(tags::SERIES_INSTANCE_UID, VR::UI, PrimitiveValue::from("7.7"));
    put(tags::NUMBER_OF_FRAMES, VR::IS, PrimitiveValue::from("2"));
    put(tags::SAMPLES_PER_PIXEL, VR::US, PrimitiveValue::from(1u16));
    put(
        tags::PHOTOMETRIC_INTERPRETATION,
        VR::CS,
        PrimitiveValue::from("MONOCHROME2"),
    );
    put(tags::ROWS, VR::US, PrimitiveValue::from(3u16));
    put(tags::COLUMNS, VR::US, PrimitiveValue::from(3u16));
    put(tags::BITS_ALLOCATED, VR::US, PrimitiveValue::from(1u16));
    put(tags::BITS_STORED, VR::US, PrimitiveValue::from(1u16));
    put(tags::PIXEL_DATA, VR::OB, PrimitiveValue::U8(packed.into()));
    write(
        o,
        parse::EXPLICIT_VR_LE,
        "1.2.840.10008.5.1.4.1.1.7.1",
        &dir.path("mask.dcm"),
    );
    let l = open_dicom(&dir.path(""), None).unwrap();
    assert_eq!(l.volume.dims, [3, 3, 2]);
    assert_eq!(l.volume.data, bits.iter().map(|&b| f32::from(b)).collect::<Vec<_>>());
}

#[test]
fn several_series_are_listed_and_chosen_by_number_uid_or_file() {
    let dir = ScratchDir::new("dicom-multi");
    let a: Vec<SliceSpec> = (0..3).map(|k| SliceSpec::new("1.1", k as f64, stored(k))).collect();
    let b: Vec<SliceSpec> = (0..2)
        .map(|k| SliceSpec::new("2.2", k as f64 * 5.0, stored(5 + k)))
        .collect();
    let files_b = write_series(&dir.path(""), &b, parse::EXPLICIT_VR_LE);
    write_series(&dir.path(""), &a, parse::EXPLICIT_VR_LE);
    dir.write("notes.txt", b"not DICOM");
    let list = list_series(&dir.path("")).unwrap();
    assert_eq!(list.len(), 2);
    assert_eq!((list[0].uid.as_str(), list[0].frames), ("1.1", 3));
    assert_eq!(
        (list[1].uid.as_str(), list[1].frames, list[1].description.as_str()),
        ("2.2", 2, "series 2.2")
    );
    let err = open_dicom(&dir.path(""), None).unwrap_err().to_string();
    assert!(
        err.contains("several DICOM series") && err.contains("1.1") && err.contains("2.2"),
        "{err}"
    );
    assert_eq!(open_dicom(&dir.path(""), Some("2")).unwrap().volume.dims[2], 2);
    assert_eq!(open_dicom(&dir.path(""), Some("1.1")).unwrap().volume.dims[2], 3);
    assert!(open_dicom(&dir.path(""), Some("3"))
        .unwrap_err()
        .to_string()
        .contains("no series '3'"));
    // A file opens its own series; a broken file of another series does not stop it.
    dir.write("broken.dcm", b"DICM\x02\x00\x10\x00UI\xff\x7f");
    let l = open_dicom(&files_b[1], None).unwrap();
    assert_eq!(l.volume.dims[2], 2);
    assert!(
        l.meta.notes.iter().any(|n| n.contains("unreadable")),
        "{:?}",
        l.meta.notes
    );
}

#[test]
fn a_missing_slice_is_reported_and_interpolated_on_a_regular_grid() {
    let dir = ScratchDir::new("dicom-gap");
    // Slices at 0, 2, 4, 8, 10 mm: the one at 6 mm is missing.
    let slices: Vec<SliceSpec> = [0, 1, 2, 4, 5]
        .into_iter()
        .map(|k| SliceSpec::new("3.3", 2.0 * f64::from(k), stored(k)))
        .collect();
    write_series(&dir.path(""), &slices, parse::EXPLICIT_VR_LE);
    let l = open_dicom(&dir.path(""), None).unwrap();
    assert_eq!(l.volume.dims, [3, 2, 6]);
    assert_eq!(l.volume.spacing[2], 2.0);
    // The filled slice lies halfway between its neighbours, as the stored ramp does.
    let expected: Vec<f32> = (0..6).flat_map(stored).map(|v| f32::from(v) - 1024.0).collect();
    assert_eq!(l.volume.data, expected);
    assert!(l.meta.notes.iter().any(|n| n.contains("missing")), "{:?}", l.meta.notes);
}

#[test]
fn tilted_stacks_are_moved_onto_a_straight_grid() {
    let dir = ScratchDir::new("dicom-tilt");
    // Each slice starts one column (0.5 mm) further along x than the one below it (gantry
    // tilt). On the straight grid of the first slice, slice k's bright column 1 lies at 1 + k.
    let slices: Vec<SliceSpec> = (0..3)
        .map(|k| {
            let mut s = SliceSpec::new("5.5", f64::from(k), vec![0; 6]);
            s.position[0] += 0.5 * f64::from(k);
            s.pixels = (0..6).map(|i| if i % 3 == 1 { 2000 } else { 1000 }).collect();
            s
        })
        .collect();
    write_series(&dir.path(""), &slices, parse::EXPLICIT_VR_LE);
    let l = open_dicom(&dir.path(""), None).unwrap();
    assert!(l.meta.notes.iter().any(|n| n.contains("tilted")), "{:?}", l.meta.notes);
    // Slice 1 moved back by one column: its bright column lands on x = 2.
    assert_eq!(l.volume.get(2, 0, 1), 2000.0 - 1024.0);
    assert_eq!(l.volume.get(1, 0, 0), 2000.0 - 1024.0);
}

#[test]
fn objects_without_pixels_and_hostile_lengths_fail_clearly() {
    let dir = ScratchDir::new("dicom-bad");
    let mut sr = InMemDicomObject::new_empty();
    sr.put(DataElement::new(tags::SOP_CLASS_UID, VR::UI, PrimitiveValue::from(SR)));
    sr.put(DataElement::new(
        tags::SERIES_INSTANCE_UID,
        VR::UI,
        PrimitiveValue::from("8.8"),
    ));
    write(sr, parse::EXPLICIT_VR_LE, SR, &dir.path("report.dcm"));
    let err = open_dicom(&dir.path("report.dcm"), None).unwrap_err().to_string();
    assert!(err.contains("holds no image: Structured Report"), "{err}");
    // A data-set element claiming 4 GiB - 2 bytes: refused before anything is allocated.
    let good = dir.path("good.dcm");
    write(
        image_object(&SliceSpec::new("6.6", 0.0, stored(0))),
        parse::EXPLICIT_VR_LE,
        CT,
        &good,
    );
    let mut bytes = std::fs::read(&good).unwrap();
    let at = bytes.windows(4).position(|w| w == [0x08, 0x00, 0x60, 0x00]).unwrap();
    bytes[at + 4..at + 6].copy_from_slice(b"OB");
    bytes[at + 6..at + 12].copy_from_slice(&[0, 0, 0xFE, 0xFF, 0xFF, 0xFF]);
    let hostile = dir.write("h/hostile.dcm", &bytes);
    let err = open_dicom(&hostile, None).unwrap_err().to_string();
    assert!(err.contains("claims 4294967294 bytes"), "{err}");
    let err = open_dicom(&dir.write("t/truncated.dcm", &bytes[..200]), None)
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("DICOM header of"), "{err}");
    // An unknown VR has a 32-bit length for dicom-rs (it reads it as UN): found by fuzzing,
    // where the walk took a 16-bit length and dicom-rs then allocated 273 MB.
    bytes[at + 4..at + 6].copy_from_slice(b"ZZ");
    bytes[at + 6..at + 12].copy_from_slice(&[0, 0, 0x43, 0x46, 0x4C, 0x10]);
    let err = open_dicom(&dir.write("u/unknown-vr.dcm", &bytes), None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("claims 273434179 bytes"), "{err}");
}
