//! Tests of the DICOM series reader with slices written here in each transfer syntax.

use super::super::meta::Units;
use super::super::test_support::ScratchDir;
use super::*;

/// Writes DICOM elements in one transfer syntax (tests only).
struct Writer {
    out: Vec<u8>,
    explicit: bool,
    big: bool,
}

impl Writer {
    fn u16(&mut self, v: u16) {
        self.out
            .extend(if self.big { v.to_be_bytes() } else { v.to_le_bytes() });
    }
    fn u32(&mut self, v: u32) {
        self.out
            .extend(if self.big { v.to_be_bytes() } else { v.to_le_bytes() });
    }
    /// An element without a VR (items and delimiters, or any element in implicit VR).
    fn bare(&mut self, group: u16, elem: u16, len: u32) {
        self.u16(group);
        self.u16(elem);
        self.u32(len);
    }
    fn element(&mut self, group: u16, elem: u16, vr: &[u8; 2], value: &[u8]) {
        let mut value = value.to_vec();
        if value.len() % 2 == 1 {
            value.push(if vr == b"UI" || vr == b"OB" { 0 } else { b' ' });
        }
        if !self.explicit {
            self.bare(group, elem, value.len() as u32);
        } else {
            self.u16(group);
            self.u16(elem);
            self.out.extend(vr);
            if matches!(vr, b"OB" | b"OW" | b"SQ" | b"UN") {
                self.out.extend([0, 0]);
                self.u32(value.len() as u32);
            } else {
                self.u16(value.len() as u16);
            }
        }
        self.out.extend(value);
    }
    fn us(&mut self, group: u16, elem: u16, v: u16) {
        let bytes = if self.big { v.to_be_bytes() } else { v.to_le_bytes() };
        self.element(group, elem, b"US", &bytes);
    }
}

/// Writes a minimal explicit-VR little-endian CT slice (tests).
#[allow(clippy::too_many_arguments)]
fn write_slice(
    rows: u16,
    cols: u16,
    position: [f64; 3],
    orientation: [f64; 6],
    spacing: [f64; 2],
    pixels: &[i16],
    rescale: [f64; 2],
    series: &str,
) -> Vec<u8> {
    let geometry = (position, orientation, spacing);
    write_slice_in(SYNTAX_EXPLICIT_LE, rows, cols, geometry, pixels, rescale, series)
}

/// Writes a minimal CT slice in the transfer syntax `syntax` (tests).
fn write_slice_in(
    syntax: &str,
    rows: u16,
    cols: u16,
    (position, orientation, spacing): ([f64; 3], [f64; 6], [f64; 2]),
    pixels: &[i16],
    rescale: [f64; 2],
    series: &str,
) -> Vec<u8> {
    let ds = |v: &[f64]| {
        v.iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join("\\")
            .into_bytes()
    };
    let mut w = Writer {
        out: vec![0u8; 128],
        explicit: true,
        big: false,
    };
    w.out.extend(b"DICM");
    // The file meta group is explicit VR little endian in every syntax.
    w.element(0x0002, 0x0010, b"UI", syntax.as_bytes());
    w.explicit = syntax != SYNTAX_IMPLICIT_LE;
    w.big = syntax == SYNTAX_EXPLICIT_BE;
    w.element(0x0008, 0x0060, b"CS", b"CT");
    // An undefined-length sequence with one undefined-length item, which the reader must skip.
    if w.explicit {
        w.u16(0x0008);
        w.u16(0x1140);
        w.out.extend(b"SQ\0\0");
        w.u32(u32::MAX);
    } else {
        w.bare(0x0008, 0x1140, u32::MAX);
    }
    w.bare(0xFFFE, 0xE000, u32::MAX);
    w.element(0x0008, 0x1150, b"UI", b"1.2.3");
    w.bare(0xFFFE, 0xE00D, 0);
    w.bare(0xFFFE, 0xE0DD, 0);
    w.element(0x0018, 0x0050, b"DS", b"2");
    w.element(0x0020, 0x000E, b"UI", series.as_bytes());
    w.element(0x0020, 0x0032, b"DS", &ds(&position));
    w.element(0x0020, 0x0037, b"DS", &ds(&orientation));
    w.us(0x0028, 0x0002, 1);
    w.us(0x0028, 0x0010, rows);
    w.us(0x0028, 0x0011, cols);
    w.element(0x0028, 0x0030, b"DS", &ds(&spacing));
    w.us(0x0028, 0x0100, 16);
    w.us(0x0028, 0x0103, 1);
    w.element(0x0028, 0x1052, b"DS", &ds(&[rescale[1]]));
    w.element(0x0028, 0x1053, b"DS", &ds(&[rescale[0]]));
    let big = w.big;
    let px: Vec<u8> = pixels
        .iter()
        .flat_map(|v| if big { v.to_be_bytes() } else { v.to_le_bytes() })
        .collect();
    w.element(0x7FE0, 0x0010, b"OW", &px);
    w.out
}

const AXIAL: [f64; 6] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// Slice k holds the value 100·k + x everywhere, so order and rescale are checkable.
fn slice_pixels(k: i16, cols: u16, rows: u16) -> Vec<i16> {
    (0..rows)
        .flat_map(|_| (0..cols).map(move |x| 100 * k + x as i16))
        .collect()
}

#[test]
fn series_is_sorted_rescaled_and_spaced_from_positions() {
    let dir = ScratchDir::new("dicom");
    // Written in scrambled order and file names; positions decide the order.
    for (file, k) in [("b", 2i16), ("a", 0), ("c", 1), ("d", 3)] {
        let pos = [-10.0, -20.0, 5.0 + 2.5 * f64::from(k)];
        let bytes = write_slice(
            3,
            4,
            pos,
            AXIAL,
            [0.7, 0.6],
            &slice_pixels(k, 4, 3),
            [2.0, -1024.0],
            "1.2.9",
        );
        dir.write(file, &bytes);
    }
    dir.write("README.txt", b"not dicom");
    let l = load_dicom_dir(&dir.path("")).expect("load");
    let v = &l.volume;
    assert_eq!(v.dims, [4, 3, 4]);
    assert_eq!(v.spacing, [0.6, 0.7, 2.5]);
    for k in 0..4 {
        for x in 0..4 {
            assert_eq!(v.get(x, 1, k), 2.0 * (100.0 * k as f32 + x as f32) - 1024.0);
        }
    }
    assert_eq!(l.meta.units, Units::Hounsfield);
}

#[test]
fn every_uncompressed_transfer_syntax_reads_the_same() {
    let pixels = slice_pixels(3, 4, 2);
    for syntax in [SYNTAX_IMPLICIT_LE, SYNTAX_EXPLICIT_LE, SYNTAX_EXPLICIT_BE] {
        let geometry = ([1.0, 2.0, 3.0], AXIAL, [0.5, 0.25]);
        let bytes = write_slice_in(syntax, 2, 4, geometry, &pixels, [1.0, -1024.0], "5");
        let s = parse_slice(&bytes, Path::new("x.dcm")).unwrap_or_else(|e| panic!("{syntax}: {e}"));
        assert_eq!(
            (s.rows, s.columns, s.bits_allocated, s.signed),
            (2, 4, 16, true),
            "{syntax}"
        );
        assert_eq!(s.pixel_spacing, Some([0.5, 0.25]));
        assert_eq!(s.position, Some(DVec3::new(1.0, 2.0, 3.0)));
        assert_eq!((s.slope, s.intercept), (1.0, -1024.0));
        let values = decode_samples(&s.pixels, ScalarType::I16, s.endian);
        let expected: Vec<f32> = pixels.iter().map(|&v| f32::from(v)).collect();
        assert_eq!(values, expected, "{syntax}");
    }
}

#[test]
fn tilted_stack_is_sorted_along_the_normal_and_unsheared() {
    let dir = ScratchDir::new("dicom-tilt");
    // Rotated orientation (rows along y, columns along -x): normal is +z.
    let orient = [0.0, 1.0, 0.0, -1.0, 0.0, 0.0];
    // Gantry tilt: each slice moves 1 mm along the row direction (+y) per 2 mm in z.
    for k in 0..3i16 {
        let pos = [0.0, f64::from(k), 2.0 * f64::from(k)];
        let mut px = vec![0i16; 8 * 8];
        // A bright voxel at the same physical point (y = 4 mm) in every slice.
        px[4 * 8 + (4 - k as usize)] = 1000;
        dir.write(
            &format!("s{k}"),
            &write_slice(8, 8, pos, orient, [1.0, 1.0], &px, [1.0, 0.0], "7"),
        );
    }
    let l = load_dicom_dir(&dir.path("")).expect("load");
    assert!((l.volume.spacing[2] - 2.0).abs() < 1e-6, "{:?}", l.volume.spacing);
    for k in 0..3 {
        assert_eq!(
            l.volume.get(4, 4, k),
            1000.0,
            "slice {k} should be shifted back onto the straight grid"
        );
    }
    assert!(l.meta.notes.iter().any(|n| n.contains("tilted")));
}

#[test]
fn malformed_slices_fail_clearly() {
    let dir = ScratchDir::new("dicom-bad");
    let good = write_slice(4, 4, [0.0; 3], AXIAL, [1.0, 1.0], &[0; 16], [1.0, 0.0], "1");
    let mut compressed = good.clone();
    let at = compressed
        .windows(19)
        .position(|w| w == SYNTAX_EXPLICIT_LE.as_bytes())
        .unwrap();
    compressed.splice(at..at + 19, b"1.2.840.10008.1.2.4.50".iter().copied());
    compressed[at - 2..at].copy_from_slice(&22u16.to_le_bytes());
    let mut huge_len = good.clone();
    let px_at = huge_len.len() - 32 - 4;
    huge_len[px_at..px_at + 4].copy_from_slice(&0x7FFF_FFF0u32.to_le_bytes());
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated", good[..good.len() - 10].to_vec(), "past the end"),
        ("compressed", compressed, "compressed or unknown"),
        ("huge", huge_len, "past the end"),
        ("nodicm", vec![0u8; 200], "not a DICOM"),
    ];
    for (name, bytes, expected) in cases {
        let p = dir.write(name, &bytes);
        let err = parse_slice(&std::fs::read(&p).unwrap(), &p)
            .expect_err(name)
            .to_string();
        assert!(err.contains(expected), "{name}: '{err}' should mention '{expected}'");
    }
    // A series of 10^6 × 10^6-pixel slices is refused before allocating the volume.
    let s = Slice {
        rows: 65535,
        columns: 65535,
        bits_allocated: 16,
        slope: 1.0,
        ..Slice::default()
    };
    let err = assemble(vec![s; 1000], Path::new("x")).expect_err("absurd").to_string();
    assert!(err.contains("exceed the limit"), "{err}");
    // An empty directory says so.
    let empty = ScratchDir::new("dicom-empty");
    let err = load_dicom_dir(&empty.path("")).expect_err("empty").to_string();
    assert!(err.contains("no DICOM files"), "{err}");
}
