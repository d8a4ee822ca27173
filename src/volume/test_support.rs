//! Scratch directories for the volume readers' tests, removed when dropped.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

pub struct ScratchDir {
    root: PathBuf,
}

impl ScratchDir {
    pub fn new(tag: &str) -> ScratchDir {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let unique = NEXT.fetch_add(1, Ordering::Relaxed);
        let root = std::env::temp_dir().join(format!("caustica-{tag}-{}-{unique}", std::process::id()));
        std::fs::create_dir_all(&root).expect("create scratch directory");
        ScratchDir { root }
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.root.join(name)
    }

    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.path(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).expect("create scratch subdirectory");
        }
        std::fs::write(&path, bytes).expect("write scratch file");
        path
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        // Leftover files in the temp directory are harmless, so a failed cleanup is ignored.
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

use super::{Endian, ScalarType};

/// Test values per type, chosen to include the extremes of each range.
pub fn test_values(scalar: ScalarType) -> Vec<f64> {
    match scalar {
        ScalarType::U8 => vec![0.0, 1.0, 127.0, 128.0, 255.0],
        ScalarType::I8 => vec![-128.0, -1.0, 0.0, 1.0, 127.0],
        ScalarType::U16 => vec![0.0, 1.0, 1234.0, 40000.0, 65535.0],
        ScalarType::I16 => vec![-32768.0, -1234.0, 0.0, 258.0, 32767.0],
        ScalarType::U32 => vec![0.0, 1.0, 70000.0, 16777216.0, 4294967295.0],
        ScalarType::I32 => vec![-2147483648.0, -70000.0, 0.0, 5.0, 2147483647.0],
        ScalarType::F32 => vec![-1.5, 0.0, 0.1, 3.25e10, -7.0e-12],
        ScalarType::F64 => vec![-1.5, 1.0 / 3.0, 0.0, 2.0e30, -4.5e-20],
    }
}

/// Encodes values as `scalar` samples in the given byte order.
pub fn encode_values(values: &[f64], scalar: ScalarType, endian: Endian) -> Vec<u8> {
    let big = endian == Endian::Big;
    macro_rules! bytes {
        ($v:expr) => {
            if big {
                $v.to_be_bytes().to_vec()
            } else {
                $v.to_le_bytes().to_vec()
            }
        };
    }
    values
        .iter()
        .flat_map(|&value| match scalar {
            ScalarType::U8 => bytes!(value as u8),
            ScalarType::I8 => bytes!(value as i8),
            ScalarType::U16 => bytes!(value as u16),
            ScalarType::I16 => bytes!(value as i16),
            ScalarType::U32 => bytes!(value as u32),
            ScalarType::I32 => bytes!(value as i32),
            ScalarType::F32 => bytes!(value as f32),
            ScalarType::F64 => bytes!(value),
        })
        .collect()
}
