//! Writes a volume file as a DICOM CT series (one explicit VR little endian file per axial
//! slice, with positions, orientation, spacing and a rescale intercept), optionally resampled,
//! to measure how long series take to load:
//!
//! ```sh
//! cargo run --release --example dicom_series -- target/datasets/ct-head.nhdr /tmp/ct-dicom
//! cargo run --release --example dicom_series -- target/datasets/ct-head.nhdr /tmp/ct-512 512x512x324
//! caustica info /tmp/ct-512            # prints "load time: … ms"
//! ```

use std::path::PathBuf;

use dicom_core::{DataElement, PrimitiveValue, VR};
use dicom_dictionary_std::tags;
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(input), Some(out)) = (args.get(1), args.get(2)) else {
        eprintln!("usage: dicom_series VOLUME OUT_DIR [XxYxZ]");
        std::process::exit(2);
    };
    let loaded = caustica::volume::open(&PathBuf::from(input))?;
    let mut volume = loaded.volume;
    if let Some(dims) = args.get(3) {
        let d: Vec<usize> = dims.split('x').map(str::parse).collect::<Result<_, _>>()?;
        volume = caustica::volume::resample::resample(&volume, [d[0], d[1], d[2]])?;
    }
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out)?;
    let [nx, ny, nz] = volume.dims;
    let ds = |v: &[f64]| PrimitiveValue::from(v.iter().map(|c| c.to_string()).collect::<Vec<_>>().join("\\"));
    let plane = nx * ny;
    for z in 0..nz {
        // Stored as unsigned with intercept −1024, as many CT scanners do.
        let pixels: Vec<u16> = volume.data[z * plane..(z + 1) * plane]
            .iter()
            .map(|v| (v + 1024.0).round().clamp(0.0, 65535.0) as u16)
            .collect();
        let mut o = InMemDicomObject::new_empty();
        let mut put = |tag, vr, value: PrimitiveValue| {
            o.put(DataElement::new(tag, vr, value));
        };
        let sop_class = "1.2.840.10008.5.1.4.1.1.2";
        put(tags::SOP_CLASS_UID, VR::UI, PrimitiveValue::from(sop_class));
        put(
            tags::SOP_INSTANCE_UID,
            VR::UI,
            PrimitiveValue::from(format!("2.25.1000{z}")),
        );
        put(tags::MODALITY, VR::CS, PrimitiveValue::from("CT"));
        put(tags::SERIES_INSTANCE_UID, VR::UI, PrimitiveValue::from("2.25.2024"));
        put(tags::INSTANCE_NUMBER, VR::IS, PrimitiveValue::from((z + 1).to_string()));
        let position = [0.0, 0.0, z as f64 * f64::from(volume.spacing[2])];
        put(tags::IMAGE_POSITION_PATIENT, VR::DS, ds(&position));
        put(
            tags::IMAGE_ORIENTATION_PATIENT,
            VR::DS,
            ds(&[1.0, 0.0, 0.0, 0.0, -1.0, 0.0]),
        );
        put(tags::SAMPLES_PER_PIXEL, VR::US, PrimitiveValue::from(1u16));
        put(
            tags::PHOTOMETRIC_INTERPRETATION,
            VR::CS,
            PrimitiveValue::from("MONOCHROME2"),
        );
        put(tags::ROWS, VR::US, PrimitiveValue::from(ny as u16));
        put(tags::COLUMNS, VR::US, PrimitiveValue::from(nx as u16));
        let spacing = [f64::from(volume.spacing[1]), f64::from(volume.spacing[0])];
        put(tags::PIXEL_SPACING, VR::DS, ds(&spacing));
        put(tags::BITS_ALLOCATED, VR::US, PrimitiveValue::from(16u16));
        put(tags::BITS_STORED, VR::US, PrimitiveValue::from(16u16));
        put(tags::HIGH_BIT, VR::US, PrimitiveValue::from(15u16));
        put(tags::PIXEL_REPRESENTATION, VR::US, PrimitiveValue::from(0u16));
        put(tags::RESCALE_INTERCEPT, VR::DS, ds(&[-1024.0]));
        put(tags::RESCALE_SLOPE, VR::DS, ds(&[1.0]));
        put(tags::PIXEL_DATA, VR::OW, PrimitiveValue::U16(pixels.into()));
        o.with_meta(
            FileMetaTableBuilder::new()
                .transfer_syntax("1.2.840.10008.1.2.1")
                .media_storage_sop_class_uid(sop_class),
        )?
        .write_to_file(out.join(format!("IM{z:05}.dcm")))?;
    }
    eprintln!("wrote {nz} slices of {nx}×{ny} to {}", out.display());
    Ok(())
}
