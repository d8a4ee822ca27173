//! Anatomical orientation, end to end: a volume with a marker at the patient's
//! left-anterior-superior corner, written in each format's own way of placing voxels in the
//! patient (DICOM IOP/IPP, NIfTI sform and qform, NRRD space directions, MetaImage
//! TransformMatrix and AnatomicalOrientation, VTK Direction), opened as a bare file. In the
//! default view (anterior, head up) the marker must appear top right (the patient's left is on
//! the viewer's right); in the left view top left (anterior towards the viewer's left).

mod common;

use std::path::{Path, PathBuf};

use clap::Parser;
use dicom_core::{DataElement, PrimitiveValue, VR};
use dicom_dictionary_std::tags;
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};

use caustica::input::InputArgs;
use caustica::render::{PreparedScene, RenderRequest};
use caustica::scene::{Environment, Light, TransferSource};
use common::{plain_tf, Gpu};

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    input: InputArgs,
}

const DIMS: [usize; 3] = [10, 8, 6];
const SPACING: f64 = 2.0;

/// Voxel axes as unit LPS vectors (x left, y posterior, z superior).
type Axes = [[f64; 3]; 3];

/// Samples (x fastest) with a 2×2×2 marker of 1 at the voxel corner that lies towards the
/// patient's left, anterior and superior for `axes`, 0 elsewhere.
fn marked(axes: &Axes) -> Vec<f32> {
    let las = [1.0, -1.0, 1.0];
    let corner: Vec<bool> = axes
        .iter()
        .map(|a| (0..3).map(|k| a[k] * las[k]).sum::<f64>() > 0.0)
        .collect();
    let mut data = vec![0.0f32; DIMS.iter().product()];
    for z in 0..DIMS[2] {
        for y in 0..DIMS[1] {
            for x in 0..DIMS[0] {
                let near = |i: usize, axis: usize| {
                    let n = DIMS[axis];
                    if corner[axis] {
                        i >= n - 2
                    } else {
                        i < 2
                    }
                };
                if near(x, 0) && near(y, 1) && near(z, 2) {
                    data[x + DIMS[0] * (y + DIMS[1] * z)] = 1.0;
                }
            }
        }
    }
    data
}

fn f32_bytes(data: &[f32]) -> Vec<u8> {
    data.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn ras(v: [f64; 3]) -> [f64; 3] {
    [-v[0], -v[1], v[2]]
}

fn vector(v: [f64; 3]) -> String {
    format!("({},{},{})", v[0], v[1], v[2])
}

fn write_nrrd(dir: &Path, axes: &Axes) -> PathBuf {
    // Written in RAS, the other anatomical space NRRD files use.
    let d = axes.map(|a| ras(a.map(|c| c * SPACING)));
    let mut bytes = format!(
        "NRRD0004\ntype: float\ndimension: 3\nsizes: {} {} {}\nspace: right-anterior-superior\n\
         space directions: {} {} {}\nspace origin: (5,-3,12)\nendian: little\nencoding: raw\n\n",
        DIMS[0],
        DIMS[1],
        DIMS[2],
        vector(d[0]),
        vector(d[1]),
        vector(d[2])
    )
    .into_bytes();
    bytes.extend(f32_bytes(&marked(axes)));
    let path = dir.join("v.nrrd");
    std::fs::write(&path, bytes).unwrap();
    path
}

fn write_metaimage(dir: &Path, axes: &Axes, by_code: bool) -> PathBuf {
    let orientation = if by_code {
        // ITK's codes name where each axis starts: the opposite of the direction it runs.
        let code: String = axes
            .iter()
            .map(|a| match (0..3).find(|&k| a[k] != 0.0).map(|k| (k, a[k] > 0.0)) {
                Some((0, true)) => 'R',
                Some((0, false)) => 'L',
                Some((1, true)) => 'A',
                Some((1, false)) => 'P',
                Some((2, true)) => 'I',
                _ => 'S',
            })
            .collect();
        format!("AnatomicalOrientation = {code}\n")
    } else {
        let m: Vec<String> = axes.iter().flatten().map(|v| v.to_string()).collect();
        format!("TransformMatrix = {}\nOffset = 1 2 3\n", m.join(" "))
    };
    let mut bytes = format!(
        "ObjectType = Image\nNDims = 3\nDimSize = {} {} {}\nElementSpacing = {SPACING} {SPACING} {SPACING}\n\
         {orientation}ElementType = MET_FLOAT\nElementDataFile = LOCAL\n",
        DIMS[0], DIMS[1], DIMS[2]
    )
    .into_bytes();
    bytes.extend(f32_bytes(&marked(axes)));
    let path = dir.join(if by_code { "code.mha" } else { "matrix.mha" });
    std::fs::write(&path, bytes).unwrap();
    path
}

fn write_vti(dir: &Path, axes: &Axes) -> PathBuf {
    // Row-major 3×3 whose columns are the axes.
    let d: Vec<String> = (0..3)
        .flat_map(|r| (0..3).map(move |c| axes[c][r].to_string()))
        .collect();
    let text = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\">\n\
         <ImageData WholeExtent=\"0 {} 0 {} 0 {}\" Origin=\"0 0 0\" Spacing=\"{SPACING} {SPACING} {SPACING}\" \
         Direction=\"{}\">\n<Piece Extent=\"0 {} 0 {} 0 {}\"><PointData Scalars=\"v\">\
         <DataArray type=\"Float32\" Name=\"v\" format=\"ascii\">{}</DataArray></PointData></Piece>\
         </ImageData>\n</VTKFile>\n",
        DIMS[0] - 1,
        DIMS[1] - 1,
        DIMS[2] - 1,
        d.join(" "),
        DIMS[0] - 1,
        DIMS[1] - 1,
        DIMS[2] - 1,
        marked(axes).iter().map(|v| v.to_string()).collect::<Vec<_>>().join(" ")
    );
    let path = dir.join("v.vti");
    std::fs::write(&path, text).unwrap();
    path
}

/// A NIfTI-1 file with either an sform or a qform (`quaternion` b, c, d and qfac).
fn write_nifti(dir: &Path, axes: &Axes, quaternion: Option<([f32; 3], f32)>) -> PathBuf {
    let mut h = vec![0u8; 352];
    let put = |h: &mut Vec<u8>, at: usize, b: &[u8]| h[at..at + b.len()].copy_from_slice(b);
    put(&mut h, 0, &348i32.to_le_bytes());
    put(&mut h, 40, &3i16.to_le_bytes());
    for (i, d) in DIMS.iter().enumerate() {
        put(&mut h, 42 + 2 * i, &(*d as i16).to_le_bytes());
    }
    put(&mut h, 70, &16i16.to_le_bytes()); // float32
    put(&mut h, 72, &32i16.to_le_bytes());
    for i in 0..3 {
        put(&mut h, 80 + 4 * i, &(SPACING as f32).to_le_bytes());
    }
    put(&mut h, 108, &352.0f32.to_le_bytes());
    match quaternion {
        Some((bcd, qfac)) => {
            put(&mut h, 76, &qfac.to_le_bytes());
            put(&mut h, 252, &1i16.to_le_bytes());
            for (i, v) in bcd.iter().enumerate() {
                put(&mut h, 256 + 4 * i, &v.to_le_bytes());
            }
        }
        None => {
            put(&mut h, 254, &1i16.to_le_bytes());
            let d = axes.map(|a| ras(a.map(|c| c * SPACING)));
            for r in 0..3 {
                for (c, axis) in d.iter().enumerate() {
                    put(&mut h, 280 + 16 * r + 4 * c, &(axis[r] as f32).to_le_bytes());
                }
            }
        }
    }
    put(&mut h, 344, b"n+1\0");
    h.extend(f32_bytes(&marked(axes)));
    let path = dir.join(if quaternion.is_some() { "q.nii" } else { "s.nii" });
    std::fs::write(&path, h).unwrap();
    path
}

/// One file per slice; the stack runs along axes[2] and may run against row × column.
fn write_dicom(dir: &Path, axes: &Axes) -> PathBuf {
    let data = marked(axes);
    let plane = DIMS[0] * DIMS[1];
    let ds = |v: &[f64]| PrimitiveValue::from(v.iter().map(|c| c.to_string()).collect::<Vec<_>>().join("\\"));
    for k in 0..DIMS[2] {
        let position: Vec<f64> = (0..3).map(|c| 7.0 + axes[2][c] * SPACING * k as f64).collect();
        let pixels: Vec<u16> = data[k * plane..(k + 1) * plane]
            .iter()
            .map(|v| *v as u16 * 1000)
            .collect();
        let mut o = InMemDicomObject::new_empty();
        let mut put = |tag, vr, value: PrimitiveValue| {
            o.put(DataElement::new(tag, vr, value));
        };
        put(
            tags::SOP_CLASS_UID,
            VR::UI,
            PrimitiveValue::from("1.2.840.10008.5.1.4.1.1.4"),
        );
        put(
            tags::SOP_INSTANCE_UID,
            VR::UI,
            PrimitiveValue::from(format!("2.25.77{k}")),
        );
        put(tags::MODALITY, VR::CS, PrimitiveValue::from("MR"));
        put(tags::SERIES_INSTANCE_UID, VR::UI, PrimitiveValue::from("2.25.4242"));
        put(tags::IMAGE_POSITION_PATIENT, VR::DS, ds(&position));
        put(
            tags::IMAGE_ORIENTATION_PATIENT,
            VR::DS,
            ds(&[axes[0], axes[1]].concat()),
        );
        put(tags::SAMPLES_PER_PIXEL, VR::US, PrimitiveValue::from(1u16));
        put(
            tags::PHOTOMETRIC_INTERPRETATION,
            VR::CS,
            PrimitiveValue::from("MONOCHROME2"),
        );
        put(tags::ROWS, VR::US, PrimitiveValue::from(DIMS[1] as u16));
        put(tags::COLUMNS, VR::US, PrimitiveValue::from(DIMS[0] as u16));
        put(tags::PIXEL_SPACING, VR::DS, ds(&[SPACING, SPACING]));
        put(tags::BITS_ALLOCATED, VR::US, PrimitiveValue::from(16u16));
        put(tags::BITS_STORED, VR::US, PrimitiveValue::from(16u16));
        put(tags::HIGH_BIT, VR::US, PrimitiveValue::from(15u16));
        put(tags::PIXEL_REPRESENTATION, VR::US, PrimitiveValue::from(0u16));
        put(tags::PIXEL_DATA, VR::OW, PrimitiveValue::U16(pixels.into()));
        o.with_meta(
            FileMetaTableBuilder::new()
                .transfer_syntax("1.2.840.10008.1.2.1")
                .media_storage_sop_class_uid("1.2.840.10008.5.1.4.1.1.4"),
        )
        .unwrap()
        .write_to_file(dir.join(format!("slice{k}.dcm")))
        .unwrap();
    }
    dir.to_path_buf()
}

/// Centroid (x, y in [0, 1], y down) of the pixels where the marker shows, rendering `path`
/// as a bare volume file (default camera) or from `view`.
fn marker_position(gpu: &mut Gpu, path: &Path, view: Option<&str>) -> [f32; 2] {
    let mut args = vec!["caustica", path.to_str().unwrap()];
    if let Some(v) = view {
        args.extend(["--view", v]);
    }
    let input = Cli::parse_from(args).input;
    let mut scene = input.prepare().expect("prepare").prepared.scene;
    // An opaque white marker in black space, lit from the camera.
    let tf = plain_tf(
        vec![[0.0, 0.0], [0.4, 0.0], [0.6, 1.0], [1.0, 1.0]],
        vec![[0.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]],
    );
    scene.transfer = TransferSource::Inline(tf);
    let peak = if path.is_dir() { 1000.0 } else { 1.0 };
    scene.window = Some([0.0, peak]);
    scene.environment = Environment::Color { color: [0.0; 3] };
    scene.light = Light {
        polar_deg: 0.0,
        softness: 0.0,
        ..Light::default()
    };
    let prepared = PreparedScene::load(&scene).expect("load");
    let size = 48;
    let out = gpu.render(&prepared, &RenderRequest::new(size, size));
    let (mut sx, mut sy, mut n) = (0.0f32, 0.0f32, 0.0f32);
    for (i, p) in out.image.pixels.iter().enumerate() {
        if common::luminance(p) > 0.05 {
            sx += (i as u32 % size) as f32 + 0.5;
            sy += (i as u32 / size) as f32 + 0.5;
            n += 1.0;
        }
    }
    assert!(n > 0.0, "{}: the marker is not visible", path.display());
    [sx / n / size as f32, sy / n / size as f32]
}

#[test]
fn the_marker_at_left_anterior_superior_shows_top_right_in_front_and_top_left_from_the_left() {
    let x = [1.0, 0.0, 0.0];
    let y = [0.0, 1.0, 0.0];
    let z = [0.0, 0.0, 1.0];
    let neg = |v: [f64; 3]| v.map(|c| -c);
    // Axial, sagittal and coronal grids, some axes reversed, in each format's own terms.
    let coronal: Axes = [x, neg(z), neg(y)];
    let sagittal: Axes = [y, neg(z), x];
    let axial_ras: Axes = [neg(x), neg(y), z];
    let axial_flipped: Axes = [x, neg(y), neg(z)];
    let mut gpu = Gpu::new();
    let root = std::env::temp_dir().join(format!("caustica-orientation-{}", std::process::id()));
    let case_dir = |name: &str| {
        let d = root.join(name);
        std::fs::create_dir_all(&d).unwrap();
        d
    };
    // A qform of 90° about z (b = c = 0, d = sin 45°) turns voxel x to anterior and voxel y to
    // the patient's left (RAS −x); qfac −1 makes z run inferior.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let qform_axes: Axes = [neg(y), x, neg(z)];
    let cases: Vec<(&str, PathBuf)> = vec![
        ("DICOM coronal", write_dicom(&case_dir("dicom-coronal"), &coronal)),
        ("DICOM sagittal", write_dicom(&case_dir("dicom-sagittal"), &sagittal)),
        ("NIfTI sform", write_nifti(&case_dir("nifti-s"), &axial_ras, None)),
        (
            "NIfTI qform",
            write_nifti(&case_dir("nifti-q"), &qform_axes, Some(([0.0, 0.0, s], -1.0))),
        ),
        ("NRRD", write_nrrd(&case_dir("nrrd"), &coronal)),
        (
            "MetaImage matrix",
            write_metaimage(&case_dir("mha-m"), &sagittal, false),
        ),
        (
            "MetaImage code",
            write_metaimage(&case_dir("mha-c"), &axial_flipped, true),
        ),
        ("VTK Direction", write_vti(&case_dir("vti"), &coronal)),
    ];
    for (name, path) in cases {
        let [fx, fy] = marker_position(&mut gpu, &path, None);
        assert!(
            fx > 0.5 && fy < 0.5,
            "{name}: anterior view shows the marker at ({fx:.2}, {fy:.2}), not top right"
        );
        let [lx, ly] = marker_position(&mut gpu, &path, Some("left"));
        assert!(
            lx < 0.5 && ly < 0.5,
            "{name}: left view shows the marker at ({lx:.2}, {ly:.2}), not top left"
        );
    }
    let _ = std::fs::remove_dir_all(&root);
}

/// The check above fails for data whose orientation is ignored: the same marker in a file
/// without orientation lands elsewhere in the anterior view.
#[test]
fn the_marker_check_fails_without_orientation() {
    let root = std::env::temp_dir().join(format!("caustica-orientation-none-{}", std::process::id()));
    std::fs::create_dir_all(&root).unwrap();
    // Coronal axes, but the file says nothing about them (a NIfTI with neither form).
    let x = [1.0, 0.0, 0.0];
    let coronal: Axes = [x, [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]];
    let path = write_nifti(&root, &coronal, None);
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[254..256].copy_from_slice(&0i16.to_le_bytes());
    std::fs::write(&path, bytes).unwrap();
    let [fx, fy] = marker_position(&mut Gpu::new(), &path, None);
    assert!(
        !(fx > 0.5 && fy < 0.5),
        "unoriented data passed the check: ({fx:.2}, {fy:.2})"
    );
    let _ = std::fs::remove_dir_all(&root);
}
