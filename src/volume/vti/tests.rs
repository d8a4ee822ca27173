//! Round trips of every type, byte order, encoding and compression, malformed files and
//! orientation of the VTK ImageData reader.

use std::io::Write;

use flate2::write::ZlibEncoder;
use flate2::Compression;

use base64::Engine as _;

use super::super::test_support::{encode_values, test_values, ScratchDir};
use super::*;

fn type_name(s: ScalarType) -> &'static str {
    match s {
        ScalarType::U8 => "UInt8",
        ScalarType::I8 => "Int8",
        ScalarType::U16 => "UInt16",
        ScalarType::I16 => "Int16",
        ScalarType::U32 => "UInt32",
        ScalarType::I32 => "Int32",
        ScalarType::F32 => "Float32",
        ScalarType::F64 => "Float64",
    }
}

fn word(v: u64, w: usize, endian: Endian) -> Vec<u8> {
    match (w, endian) {
        (4, Endian::Little) => (v as u32).to_le_bytes().to_vec(),
        (4, Endian::Big) => (v as u32).to_be_bytes().to_vec(),
        (_, Endian::Little) => v.to_le_bytes().to_vec(),
        (_, Endian::Big) => v.to_be_bytes().to_vec(),
    }
}

/// (header, data) of one VTK block, split into two zlib blocks when compressed.
fn block(data: &[u8], w: usize, endian: Endian, compressed: bool) -> (Vec<u8>, Vec<u8>) {
    if !compressed {
        return (word(data.len() as u64, w, endian), data.to_vec());
    }
    let block_size = data.len().div_ceil(2).max(1);
    let chunks: Vec<Vec<u8>> = data
        .chunks(block_size)
        .map(|c| {
            let mut z = ZlibEncoder::new(Vec::new(), Compression::fast());
            z.write_all(c).unwrap();
            z.finish().unwrap()
        })
        .collect();
    let last = data.len() - block_size * (chunks.len() - 1);
    let mut header = word(chunks.len() as u64, w, endian);
    header.extend(word(block_size as u64, w, endian));
    header.extend(word(last as u64, w, endian));
    for c in &chunks {
        header.extend(word(c.len() as u64, w, endian));
    }
    (header, chunks.concat())
}

fn vti(scalar: ScalarType, n: usize, endian: Endian, w: usize, compressed: bool, mode: &str, data: &[u8]) -> Vec<u8> {
    let order = if endian == Endian::Big {
        "BigEndian"
    } else {
        "LittleEndian"
    };
    let header_type = if w == 8 { "UInt64" } else { "UInt32" };
    let compressor = if compressed {
        " compressor=\"vtkZLibDataCompressor\""
    } else {
        ""
    };
    let (head, body) = block(data, w, endian, compressed);
    let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
    let format = if mode == "binary" { "binary" } else { "appended" };
    let inline = if mode == "binary" {
        format!("{}{}", b64(&head), b64(&body))
    } else {
        String::new()
    };
    let mut out = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"{order}\" \
         header_type=\"{header_type}\"{compressor}>\n<ImageData WholeExtent=\"0 {} 0 0 0 0\" Origin=\"0 0 0\" \
         Spacing=\"0.5 1 4\">\n<Piece Extent=\"0 {} 0 0 0 0\"><PointData Scalars=\"v\">\
         <DataArray type=\"{}\" Name=\"v\" format=\"{format}\" offset=\"0\">{inline}</DataArray>\
         </PointData></Piece></ImageData>\n",
        n - 1,
        n - 1,
        type_name(scalar)
    )
    .into_bytes();
    match mode {
        "raw" => {
            out.extend(b"<AppendedData encoding=\"raw\">\n_");
            out.extend(&head);
            out.extend(&body);
            out.extend(b"\n</AppendedData>\n</VTKFile>\n");
        }
        "base64" => {
            out.extend(b"<AppendedData encoding=\"base64\">\n_");
            out.extend(format!("{}{}", b64(&head), b64(&body)).as_bytes());
            out.extend(b"\n</AppendedData>\n</VTKFile>\n");
        }
        _ => out.extend(b"</VTKFile>\n"),
    }
    out
}

#[test]
fn round_trips_types_byte_orders_encodings_and_zlib() {
    let dir = ScratchDir::new("vti");
    for scalar in ScalarType::ALL {
        for endian in [Endian::Little, Endian::Big] {
            for w in [4usize, 8] {
                for compressed in [false, true] {
                    for mode in ["raw", "base64", "binary"] {
                        let values = test_values(scalar);
                        let data = encode_values(&values, scalar, endian);
                        let name = format!("{scalar}-{endian:?}-{w}-{compressed}-{mode}.vti");
                        let p = dir.write(&name, &vti(scalar, values.len(), endian, w, compressed, mode, &data));
                        let l = load_vti(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
                        let expected: Vec<f32> = values.iter().map(|&v| v as f32).collect();
                        assert_eq!(l.volume.data, expected, "{name}");
                        assert_eq!(l.volume.spacing, [0.5, 1.0, 4.0]);
                    }
                }
            }
        }
    }
}

#[test]
fn malformed_files_fail_clearly() {
    let dir = ScratchDir::new("vti-bad");
    let data = encode_values(&[1.0; 8], ScalarType::F32, Endian::Little);
    let good = vti(ScalarType::F32, 8, Endian::Little, 4, false, "raw", &data);
    let text = String::from_utf8_lossy(&good).to_string();
    let cut = good.len() - 30;
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated", good[..cut].to_vec(), "need 32 bytes"),
        (
            "absurd",
            text.replace(
                "WholeExtent=\"0 7 0 0 0 0\"",
                "WholeExtent=\"0 999999 0 999999 0 999999\"",
            )
            .into_bytes(),
            "exceed the limit",
        ),
        (
            "type",
            text.replace("Float32", "Complex").into_bytes(),
            "type 'Complex'",
        ),
        (
            "lying-size",
            {
                let mut b = good.clone();
                let at = find(&b, b"\n_").unwrap() + 2;
                b[at..at + 4].copy_from_slice(&8u32.to_le_bytes());
                b
            },
            "holds 8 bytes",
        ),
        (
            "compressor",
            text.replace(
                "header_type=\"UInt32\"",
                "header_type=\"UInt32\" compressor=\"vtkLZ4DataCompressor\"",
            )
            .into_bytes(),
            "LZ4",
        ),
        (
            "not-xml",
            b"<VTKFile type=\"ImageData\"><ImageData".to_vec(),
            "invalid XML",
        ),
        (
            "extent",
            text.replace("WholeExtent=\"0 7", "WholeExtent=\"5 2").into_bytes(),
            "inverted",
        ),
        ("garbage", vec![0xFFu8; 64], "UTF-8"),
    ];
    for (name, bytes, expected) in cases {
        let p = dir.write(&format!("{name}.vti"), &bytes);
        let err = load_vti(&p).expect_err(name).to_string();
        assert!(err.contains(expected), "{name}: '{err}' should mention '{expected}'");
    }
    // A zlib block table claiming an absurd block count.
    let z = vti(ScalarType::F32, 8, Endian::Little, 4, true, "raw", &data);
    let mut b = z.clone();
    let at = find(&b, b"\n_").unwrap() + 2;
    b[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = load_vti(&dir.write("blocks.vti", &b)).expect_err("blocks").to_string();
    assert!(err.contains("block table"), "{err}");
}

#[test]
fn a_non_identity_direction_gives_the_patient_frame() {
    let dir = ScratchDir::new("vti-orient");
    let data = encode_values(&[1.0; 8], ScalarType::F32, Endian::Little);
    let good = String::from_utf8(vti(ScalarType::F32, 8, Endian::Little, 4, false, "binary", &data)).unwrap();
    // Axis x runs along −y (anterior in LPS), y along +x (left), z along +z (superior).
    for (direction, codes) in [
        (" Direction=\"0 1 0 -1 0 0 0 0 1\"", Some("ALS")),
        (" Direction=\"1 0 0 0 1 0 0 0 1\"", None),
        ("", None),
    ] {
        let text = good.replace(" Origin=\"0 0 0\"", &format!(" Origin=\"1 2 3\"{direction}"));
        let l = load_vti(&dir.write("o.vti", text.as_bytes())).expect(direction);
        let frame = l.meta.patient;
        assert_eq!(frame.as_ref().map(|f| f.axis_codes()).as_deref(), codes, "{direction}");
        if let Some(f) = frame {
            assert_eq!(f.origin, glam::DVec3::new(1.0, 2.0, 3.0));
        }
    }
    let bad = good.replace(" Origin=\"0 0 0\"", " Direction=\"1 0 0 1 0 0 0 0 1\"");
    let err = load_vti(&dir.write("bad.vti", bad.as_bytes())).unwrap_err().to_string();
    assert!(err.contains("degenerate"), "{err}");
}
