//! Public DICOM test files (pydicom's, fetched from PyPI by `datasets/fetch` and cached under
//! target/datasets/dicom): every transfer syntax the pure-Rust codecs decode, multi-frame
//! objects, RT dose, segmentations, colour, files without a meta group, non-image objects and
//! DICOMDIRs. Lossless encodings must decode to exactly the samples of their uncompressed
//! twins; lossy ones to within a stated bound.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use caustica::volume::dicom::{list_series, open_dicom};
use caustica::volume::{Loaded, Units};

static FETCH: Mutex<()> = Mutex::new(());

/// The fetched test files (see `datasets/fetch`).
fn files() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dest = root.join("target").join("datasets");
    let _guard = FETCH.lock().unwrap_or_else(|e| e.into_inner());
    let out = Command::new("bash")
        .arg(root.join("datasets").join("fetch"))
        .arg(&dest)
        .output()
        .expect("run datasets/fetch");
    assert!(
        out.status.success(),
        "datasets/fetch could not provide the DICOM test files (network, apt-get and pip needed):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    dest.join("dicom")
}

/// A copy of test file `name` alone in a folder, so that pydicom's variants of one image
/// (which share a series UID) are not read as one series.
fn alone(name: &str) -> PathBuf {
    let src = files().join(name);
    let dir = std::env::temp_dir().join(format!("caustica-dicom-files-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let dst = dir.join(name);
    std::fs::copy(&src, &dst).unwrap_or_else(|e| panic!("{}: {e}", src.display()));
    dst
}

fn load(name: &str) -> Loaded {
    let path = alone(name);
    let loaded = open_dicom(&path, None).unwrap_or_else(|e| panic!("{name}: {e}"));
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
    loaded
}

fn load_err(name: &str) -> String {
    let path = alone(name);
    let err = open_dicom(&path, None).expect_err(name).to_string();
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
    err
}

fn mean_abs_diff(a: &Loaded, b: &Loaded) -> f64 {
    assert_eq!(a.volume.dims, b.volume.dims);
    let sum: f64 = a
        .volume
        .data
        .iter()
        .zip(&b.volume.data)
        .map(|(x, y)| f64::from((x - y).abs()))
        .sum();
    sum / a.volume.data.len() as f64
}

#[test]
fn lossless_encodings_decode_to_the_uncompressed_samples() {
    // (reference, same image in another syntax or encoding)
    let pairs = [
        ("MR_small.dcm", "MR_small_implicit.dcm"),     // implicit VR little endian
        ("MR_small.dcm", "MR_small_bigendian.dcm"),    // explicit VR big endian
        ("MR_small.dcm", "MR_small_RLE.dcm"),          // RLE lossless, 16 bits
        ("MR_small.dcm", "MR_small_jp2klossless.dcm"), // JPEG 2000 lossless
        ("emri_small.dcm", "emri_small_jpeg_2k_lossless.dcm"), // 10 frames, JPEG 2000
        ("rtdose.dcm", "rtdose_rle.dcm"),              // RLE, 32 bits, 15 frames
        ("SC_rgb.dcm", "SC_rgb_rle.dcm"),              // RLE, RGB
        ("SC_rgb_2frame.dcm", "SC_rgb_rle_2frame.dcm"), // RLE, RGB, 2 frames
        ("US1_UNCR.dcm", "US1_J2KR.dcm"),              // JPEG 2000 lossless, YBR_RCT colour
    ];
    for (reference, encoded) in pairs {
        let a = load(reference);
        let b = load(encoded);
        assert_eq!(a.volume.dims, b.volume.dims, "{encoded}");
        assert_eq!(a.volume.spacing, b.volume.spacing, "{encoded}");
        // Colour becomes luminance in f32: the same RGB gives the same sum bit for bit.
        assert_eq!(a.volume.data, b.volume.data, "{encoded} differs from {reference}");
        assert!(
            a.volume.value_range[1] > a.volume.value_range[0],
            "{reference} is constant"
        );
    }
}

#[test]
fn lossy_encodings_stay_close_to_the_uncompressed_samples() {
    // JPEG 2000 (the lossy syntax) of an NM image, range −30–245: measured mean |Δ| 0 (this
    // codestream happens to use the reversible wavelet); 1 bounds a real lossy stream.
    let d = mean_abs_diff(&load("JPEG2000_UNC.dcm"), &load("JPEG2000.dcm"));
    assert!(d < 1.0, "JPEG 2000 lossy: mean |Δ| {d}");
    // JPEG baseline of an 8-bit RGB test pattern (YBR 4:2:2 inside the codestream): luminance
    // within 2 of 255 on average (measured 0.30), the quantisation of the JPEG.
    let rgb = load("SC_rgb.dcm");
    let d = mean_abs_diff(&rgb, &load("SC_rgb_jpeg_dcmtk.dcm"));
    assert!(d < 2.0, "JPEG baseline: mean |Δ| {d}");
    // Native YBR_FULL_422: Y is the luminance; only the chroma was subsampled (measured 0.27,
    // the rounding of Y to 8 bits).
    let d = mean_abs_diff(&rgb, &load("SC_ybr_full_422_uncompressed.dcm"));
    assert!(d < 1.0, "YBR_FULL_422: mean |Δ| {d}");
    // An image upside down fails these bounds by far (measured 121).
    let mut flipped = rgb.clone();
    flipped.volume.data.reverse();
    let d = mean_abs_diff(&rgb, &flipped);
    assert!(d > 10.0, "the bounds would not notice a wrong image: {d}");
}

#[test]
fn jpeg_lossless_deflate_and_single_images_decode() {
    for (name, dims) in [
        ("JPEG-LL.dcm", [256, 1024, 1]),
        ("JPGLosslessP14SV1_1s_1f_8b.dcm", [1024, 768, 1]),
        ("image_dfl.dcm", [512, 512, 1]),
        ("CT_small.dcm", [128, 128, 1]),
    ] {
        let l = load(name);
        assert_eq!(l.volume.dims, dims, "{name}");
        let h = &l.histogram;
        // A real image, not noise or zeros: a spread of values, most of them shared by
        // neighbours (natural images are smooth).
        assert!(h.tails[1] > h.tails[0], "{name}: {:?}", h.tails);
        let d = &l.volume.data;
        let steps = d
            .windows(2)
            .filter(|w| (w[1] - w[0]).abs() > 0.25 * (h.tails[1] - h.tails[0]))
            .count();
        assert!(steps * 10 < d.len(), "{name}: {steps} large jumps between neighbours");
    }
    let ct = load("CT_small.dcm");
    assert_eq!(ct.meta.units, Units::Hounsfield);
    assert!(
        ct.volume.value_range[0] < -800.0,
        "air in HU after rescale: {:?}",
        ct.volume.value_range
    );
}

#[test]
fn multi_frame_objects_place_their_frames() {
    // Enhanced CT: positions, orientation and rescale in the functional groups.
    let ect = load("eCT_Supplemental.dcm");
    assert_eq!(ect.volume.dims, [512, 512, 2]);
    assert_eq!(ect.meta.units, Units::Hounsfield);
    assert!(ect.meta.patient.is_some());
    assert!(ect.volume.value_range[0] <= -1000.0, "{:?}", ect.volume.value_range);
    // RT dose: 15 frames 5 mm apart from the Grid Frame Offset Vector, scaled to dose.
    let dose = load("rtdose.dcm");
    assert_eq!(dose.volume.dims, [10, 10, 15]);
    assert_eq!(dose.volume.spacing[2], 5.0);
    assert!(dose.meta.notes.iter().any(|n| n.contains("Dose Grid Scaling")));
    assert!(
        dose.volume.value_range[1] < 2.0,
        "scaled dose {:?}",
        dose.volume.value_range
    );
    // Segmentation: 1-bit frames, values 0 and 1.
    let seg = load("liver.dcm");
    assert_eq!(seg.volume.dims[..2], [512, 512]);
    assert!(seg.volume.data.iter().all(|v| *v == 0.0 || *v == 1.0));
    assert!(seg.volume.data.contains(&1.0));
    assert!(seg.meta.patient.is_some());
    // Ultrasound cine: 120 colour frames without positions, stacked in order.
    let cine = load("color3d_jpeg_baseline.dcm");
    assert_eq!(cine.volume.dims, [640, 480, 120]);
    assert!(
        cine.meta.notes.iter().any(|n| n.contains("no positions")),
        "{:?}",
        cine.meta.notes
    );
    assert!(cine.meta.notes.iter().any(|n| n.contains("luminance")));
}

#[test]
fn non_image_objects_and_undecodable_syntaxes_fail_clearly() {
    for (name, kind) in [
        ("test-SR.dcm", "Structured Report"),
        ("rtplan.dcm", "RT plan"),
        ("rtstruct.dcm", "RT structure set"),
        ("waveform_ecg.dcm", "waveform"),
        // No preamble, no meta group, explicit VR big endian.
        ("ExplVR_BigEndNoMeta.dcm", "RT plan (RT Ion Plan)"),
    ] {
        let err = load_err(name);
        assert!(
            err.contains(&format!("this DICOM object holds no image: {kind}")),
            "{name}: {err}"
        );
        assert!(err.starts_with("DICOM header of"), "{name}: {err}");
    }
    for (name, syntax) in [
        ("MR_small_jpeg_ls_lossless.dcm", "JPEG-LS Lossless"),
        ("JPGExtended.dcm", "JPEG Extended"),
    ] {
        let err = load_err(name);
        assert!(err.contains("cannot decode") && err.contains(syntax), "{name}: {err}");
    }
    // The command line exits 1 with the same message.
    let path = alone("rtplan.dcm");
    let out = Command::new(env!("CARGO_BIN_EXE_caustica"))
        .args(["info", path.to_str().unwrap()])
        .output()
        .expect("run caustica");
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("holds no image: RT plan"));
}

#[test]
fn dicomdir_lists_its_series_whatever_the_record_order() {
    let dir = files().join("dicomdirtests");
    let list = list_series(&dir.join("DICOMDIR")).expect("DICOMDIR");
    assert!(list.len() >= 5, "{list:?}");
    for variant in ["DICOMDIR-reordered", "DICOMDIR-implicit", "DICOMDIR-bigEnd"] {
        let other = list_series(&dir.join(variant)).unwrap_or_else(|e| panic!("{variant}: {e}"));
        assert_eq!(other, list, "{variant}");
    }
    // A folder holding a DICOMDIR is read through it; one series loads by number or UID.
    assert_eq!(list_series(&dir).expect("folder"), list);
    let ct = list
        .iter()
        .find(|s| s.modality == "CT" && s.frames > 1)
        .expect("a CT series");
    let by_number = open_dicom(&dir, Some(&ct.number.to_string())).expect("by number");
    let by_uid = open_dicom(&dir, Some(&ct.uid)).expect("by UID");
    assert_eq!(by_number.volume.dims, [ct.columns, ct.rows, by_number.volume.dims[2]]);
    assert_eq!(by_number.volume.data, by_uid.volume.data);
    // Without a choice: the listing, and the option that picks one.
    let err = open_dicom(&dir, None).unwrap_err().to_string();
    assert!(err.contains("--series") && err.contains(&ct.uid), "{err}");
    let out = Command::new(env!("CARGO_BIN_EXE_caustica"))
        .args(["info", dir.to_str().unwrap()])
        .output()
        .expect("run caustica");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    assert!(
        stdout.contains(&format!("{} DICOM series", list.len())) && stdout.contains(&ct.uid),
        "{stdout}"
    );
}
