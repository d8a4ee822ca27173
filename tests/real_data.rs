//! Real data: the CT head and MRI head fetched from Debian packages by `datasets/fetch`
//! (cached under target/datasets, so only the first run downloads). A machine that cannot
//! download them fails these tests with the script's message instead of skipping them.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use caustica::render::{PreparedScene, RenderRequest};
use caustica::scene::{Camera, Environment, Projection, Scene, TransferSource, View, VolumeSource};
use caustica::transfer::{Curve, TransferFunctions};
use caustica::volume::{self, Units, CT_WINDOW};

use common::Gpu;

/// Serialises the fetch across the tests of this file (they run in parallel threads).
static FETCH: Mutex<()> = Mutex::new(());

fn datasets() -> PathBuf {
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
        "datasets/fetch could not provide the sample volumes (network or apt-get needed):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    dest
}

#[test]
fn ct_head_has_its_dims_spacing_and_hounsfield_units() {
    let loaded = volume::open(&datasets().join("ct-head.nhdr")).expect("CT head loads");
    let v = &loaded.volume;
    assert_eq!(v.dims, [256, 256, 108]);
    assert!((v.spacing[0] - 0.957_031_2).abs() < 1e-6 && v.spacing[0] == v.spacing[1]);
    assert_eq!(v.spacing[2], 1.5);
    assert_eq!(loaded.meta.units, Units::Hounsfield);
    assert_eq!(loaded.default_window(), CT_WINDOW);
    // Air outside the head and dense bone are both present.
    assert!(
        v.value_range[0] <= -1000.0 && v.value_range[1] >= 1000.0,
        "{:?}",
        v.value_range
    );
    // Most of the box is air: the median lies near −1000 HU.
    assert!(loaded.histogram.quantile(0.5) < -900.0);
    // An axial stack: columns to the patient's left, rows anterior, slices superior.
    let frame = loaded
        .meta
        .patient
        .as_ref()
        .expect("patient frame from space directions");
    assert_eq!(frame.axis_codes(), "LAS");
}

#[test]
fn mri_head_loads_from_nifti_gz() {
    let loaded = volume::open(&datasets().join("mri-head.nii.gz")).expect("MRI head loads");
    assert_eq!(loaded.volume.dims, [181, 217, 181]);
    assert_eq!(loaded.volume.spacing, [1.0; 3]);
    // The Colin 27 template is stored RAS: x towards the patient's right, y anterior, z up.
    let frame = loaded.meta.patient.as_ref().expect("patient frame from the sform");
    assert_eq!((frame.source, frame.axis_codes().as_str()), ("NIfTI sform", "RAS"));
    let [lo, hi] = loaded.default_window();
    assert!(lo >= 0.0 && hi > lo && hi <= loaded.volume.value_range[1]);
}

/// Renders the CT head along its slice axis from below (orthographic inferior view: anterior
/// at the top, the patient's left on the right) over a coloured background, downsampled to at
/// most 64 voxels per axis to keep the test fast.
fn render_ct(tf: TransferFunctions) -> (Vec<[f32; 4]>, [f32; 3], [usize; 3]) {
    let dir = datasets();
    let mut scene = Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/ct-head.toml"))
        .expect("the CT head scene parses");
    scene.volume = VolumeSource::File {
        path: dir.join("ct-head.nhdr"),
        series: None,
    };
    scene.transfer = TransferSource::Inline(tf);
    scene.clip = None;
    scene.camera = Camera::named(View::Inferior, glam::Mat3::IDENTITY);
    scene.camera.projection = Projection::Orthographic;
    scene.camera.zoom = 1.0;
    let background = [0.2, 0.4, 0.6];
    scene.environment = Environment::Color { color: background };
    let mut prepared = PreparedScene::load(&scene).expect("prepare");
    let dims = prepared
        .fit_to_device(64, u64::MAX, true)
        .expect("downsampling allowed")
        .expect("downsampled");
    let mut gpu = Gpu::new();
    let out = gpu.render(&prepared, &RenderRequest::new(64, 64));
    assert_eq!(out.image.count_invalid(), (0, 0), "non-finite or negative pixels");
    (out.image.pixels, background, dims)
}

/// Pixels of the image that look through the upper corners of the volume box, where every
/// axial slice holds air (the head is round; the patient table lies at the bottom).
fn air_pixels(pixels: &[[f32; 4]]) -> Vec<[f32; 4]> {
    // Orthographic, zoom 1: the image spans 2 bounding radii. The box is 245 × 245 × 162 mm,
    // radius 191 mm, so its front face spans ±20.5 px around the centre of a 64-px image;
    // pixels 16 px from the centre on both axes (±122 mm, ±112 mm from the axis) are air.
    let mut out = Vec::new();
    for (x, y) in [(16usize, 16usize), (47, 16), (17, 17), (46, 17)] {
        out.push(pixels[y * 64 + x]);
    }
    out
}

#[test]
fn ct_head_renders_finite_with_air_transparent_under_the_ct_preset() {
    let preset =
        TransferFunctions::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("transfer_functions/ct-head.json"))
            .expect("CT preset");
    let (pixels, background, dims) = render_ct(preset.clone());
    assert!(dims.iter().all(|&d| d <= 64), "{dims:?}");
    // Air is the background colour, untouched (half-float state buffers: 1e-3 bounds rounding).
    for p in air_pixels(&pixels) {
        for c in 0..3 {
            assert!(
                (p[c] - background[c]).abs() < 1e-3,
                "air pixel {p:?} differs from {background:?}"
            );
        }
    }
    // The head itself is visible: the centre differs from the background.
    let centre = pixels[32 * 64 + 32];
    assert!(
        (0..3).any(|c| (centre[c] - background[c]).abs() > 0.05),
        "centre {centre:?}"
    );

    // The same check catches air that is not transparent.
    let mut foggy = preset;
    foggy.opacity = Curve {
        points: vec![[0.0, 0.05], [1.0, 0.05]],
    };
    let (pixels, background, _) = render_ct(foggy);
    assert!(air_pixels(&pixels)
        .iter()
        .all(|p| (0..3).any(|c| (p[c] - background[c]).abs() > 1e-2)));
}

#[test]
fn fetch_fails_clearly_when_it_cannot_download() {
    // Without apt-get on the PATH the script must stop with a message, not produce files.
    let dest = std::env::temp_dir().join(format!("caustica-fetch-{}", std::process::id()));
    let out = Command::new("/bin/bash")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets").join("fetch"))
        .arg(&dest)
        .env("PATH", dest.join("no-tools-here"))
        .output()
        .expect("run datasets/fetch");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "fetch succeeded without apt-get: {stderr}");
    assert!(
        stderr.contains("datasets/fetch: error:") && stderr.contains("apt-get"),
        "{stderr}"
    );
    assert!(!dest.join("ct-head.nhdr").exists());
    let _ = std::fs::remove_dir_all(&dest);
}
