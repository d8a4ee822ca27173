//! `caustica info` and volume-file input on the command line, without a Vulkan device.

use std::path::PathBuf;
use std::process::{Command, Output};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("caustica-cli-formats-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

fn caustica(dir: &std::path::Path, args: &[&str]) -> Output {
    let missing_icd = dir.join("no-such-vulkan-driver.json");
    Command::new(env!("CARGO_BIN_EXE_caustica"))
        .args(args)
        .current_dir(dir)
        .env("VK_ICD_FILENAMES", &missing_icd)
        .env("VK_DRIVER_FILES", &missing_icd)
        .output()
        .expect("run caustica")
}

/// A 4×3×2 MetaImage CT volume in Hounsfield units.
fn write_ct_mha(dir: &std::path::Path) {
    let mut bytes = b"ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementSpacing = 0.5 0.5 2.5\n\
                      ElementType = MET_SHORT\nModality = MET_MOD_CT\nElementDataFile = LOCAL\n"
        .to_vec();
    for i in 0..24i16 {
        bytes.extend((i * 100 - 1000).to_le_bytes());
    }
    std::fs::write(dir.join("ct.mha"), bytes).unwrap();
}

#[test]
fn info_describes_a_volume_file() {
    let dir = scratch("info");
    write_ct_mha(&dir);
    let out = caustica(&dir, &["info", "ct.mha"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    for expected in [
        "MetaImage",
        "4×3×2",
        "i16",
        "0.5 × 0.5 × 2.5",
        "Hounsfield",
        "[-1000, 1300]",
        "CT window",
        "ct-amber",
    ] {
        assert!(stdout.contains(expected), "info should mention '{expected}':\n{stdout}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn info_and_render_fail_clearly_on_bad_files() {
    let dir = scratch("bad");
    std::fs::write(
        dir.join("huge.mha"),
        "NDims = 3\nDimSize = 1000000 1000000 1000000\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
    )
    .unwrap();
    std::fs::write(dir.join("bad.nii"), vec![7u8; 400]).unwrap();
    std::fs::write(
        dir.join("tf.itf"),
        "<InviwoWorkspace><Points><Point/></Points></InviwoWorkspace>",
    )
    .unwrap();
    write_ct_mha(&dir);
    for (args, expected) in [
        (
            vec!["info", "huge.mha"],
            "huge.mha (MetaImage): volume dims 1000000×1000000×1000000",
        ),
        (vec!["info", "bad.nii"], "not a NIfTI file"),
        (vec!["info", "missing*.nrrd"], "no files match"),
        (vec!["render", "huge.mha", "-o", "out.png"], "exceed the limit"),
        (
            vec!["render", "ct.mha", "--transfer", "tf.itf", "-o", "out.png"],
            "needs pos and rgba",
        ),
        (
            vec!["render", "ct.mha", "--time", "2", "-o", "out.png"],
            "needs a time series",
        ),
    ] {
        let out = caustica(&dir, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(expected) && !stderr.contains("panicked"),
            "{args:?}: {stderr}"
        );
        assert!(!dir.join("out.png").exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// One broken file per format: each error names the file's own format, and no other.
#[test]
fn header_errors_name_the_format_of_the_file() {
    let dir = scratch("names");
    let dicom_dir = dir.join("series");
    std::fs::create_dir_all(&dicom_dir).unwrap();
    // A Part-10 preamble and marker followed by a meta group element whose length runs past
    // the end of the file.
    let mut dicom = vec![0u8; 128];
    dicom.extend(b"DICM");
    dicom.extend([0x02, 0x00, 0x10, 0x00, b'U', b'I', 0xFF, 0x7F]);
    std::fs::write(dicom_dir.join("broken.dcm"), &dicom).unwrap();
    let cases: [(&str, &[u8], &str); 6] = [
        ("bad.nrrd", b"NRRD0004\ntype: flot\n\n", "NRRD"),
        ("bad.nii", &[7u8; 400], "NIfTI"),
        (
            "bad.mha",
            b"NDims = 3\nDimSize = 2 2\nElementDataFile = LOCAL\n",
            "MetaImage",
        ),
        ("bad.vti", b"<VTKFile type=\"PolyData\"></VTKFile>", "VTK ImageData"),
        ("series/broken.dcm", &dicom, "DICOM"),
        ("bad.raw.json", b"{\"dims\": [2, 2]}", "raw sidecar"),
    ];
    std::fs::write(dir.join("bad.raw"), [0u8; 8]).unwrap();
    let formats = ["NRRD", "NIfTI", "MetaImage", "VTK ImageData", "DICOM", "raw sidecar"];
    for (name, bytes, format) in cases {
        std::fs::write(dir.join(name), bytes).unwrap();
        let input = name.strip_suffix(".json").unwrap_or(name);
        let out = caustica(&dir, &["info", input]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(stderr.contains(&format!("{format} header of")), "{name}: {stderr}");
        for other in formats.iter().filter(|f| **f != format) {
            assert!(!stderr.contains(other), "{name} names {other}: {stderr}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
