//! Scalar volumes on a regular grid: the in-memory type, its errors and format dispatch.

mod decode;
pub mod dicom;
pub mod histogram;
pub mod meta;
pub mod metaimage;
pub mod nifti;
pub mod nrrd;
pub mod orient;
pub mod procedural;
pub mod raw;
mod read;
pub mod resample;
pub mod series;
#[cfg(test)]
mod test_support;
pub mod vti;

use std::path::{Path, PathBuf};

use rayon::prelude::*;

pub use histogram::Histogram;
pub use meta::{Format, Loaded, Units, VolumeMeta, CT_WINDOW};
pub use orient::PatientFrame;
pub use raw::{Endian, RawDesc, ScalarType};

/// Largest voxel count any loader or generator accepts (2^31). Checked before allocating,
/// so a corrupt or hostile header cannot request absurd amounts of memory.
pub const MAX_VOXELS: usize = 1 << 31;

/// A scalar volume on a regular grid. x fastest, then y, then z.
/// Axes: x right, y UP, z depth (back).
#[derive(Clone, Debug)]
pub struct Volume {
    /// Number of voxels along x, y, z.
    pub dims: [usize; 3],
    /// Physical size of a voxel along x, y, z (mm or any unit; only ratios matter).
    pub spacing: [f32; 3],
    /// `dims[0] * dims[1] * dims[2]` samples, x fastest.
    pub data: Vec<f32>,
    /// Minimum and maximum of `data`.
    pub value_range: [f32; 2],
}

/// The voxels of a volume's half-resolution level (`quality.volume_level` 1): ⌊n/2⌋ per
/// axis, at least 1, a mip level's extent.
pub fn half_level_dims(dims: [usize; 3]) -> [usize; 3] {
    dims.map(half_level_side)
}

/// [`half_level_dims`] along one axis of `n` voxels.
pub fn half_level_side(n: usize) -> usize {
    (n / 2).max(1)
}

impl Volume {
    /// Validates the grid (dims ≥ 1, sample count, finite positive spacing, finite samples)
    /// and computes the value range.
    pub fn new(dims: [usize; 3], spacing: [f32; 3], data: Vec<f32>) -> Result<Volume, VolumeError> {
        let expected = checked_voxel_count(dims)?;
        if data.len() != expected {
            return Err(VolumeError::SizeMismatch {
                expected,
                actual: data.len(),
            });
        }
        if !spacing.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(VolumeError::InvalidSpacing(spacing));
        }
        let non_finite = data.iter().filter(|v| !v.is_finite()).count();
        if non_finite > 0 {
            return Err(VolumeError::NonFinite { count: non_finite });
        }
        let value_range = value_range(&data);
        Ok(Volume {
            dims,
            spacing,
            data,
            value_range,
        })
    }

    /// The same voxels with axis `axes[i]` as axis i (x still fastest): `axes` a permutation
    /// of [0, 1, 2].
    pub fn with_axes(&self, axes: [usize; 3]) -> Volume {
        Volume {
            dims: axes.map(|a| self.dims[a]),
            spacing: axes.map(|a| self.spacing[a]),
            data: orient::permute(self, axes, [false; 3]),
            value_range: self.value_range,
        }
    }

    pub fn voxel_count(&self) -> usize {
        self.data.len()
    }

    /// Sample at integer voxel indices. Panics if an index is outside `dims`, like slice indexing.
    pub fn get(&self, x: usize, y: usize, z: usize) -> f32 {
        self.data[x + self.dims[0] * (y + self.dims[1] * z)]
    }

    /// Trilinear sample at continuous voxel coordinates, voxel centres at integer coordinates.
    /// Outside `[-0.5, dims - 0.5]` on any axis the result is 0.0 (air); inside, neighbours
    /// past the last voxel centre are clamped to the edge voxel.
    pub fn sample_trilinear(&self, p: [f32; 3]) -> f32 {
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        let mut frac = [0.0f32; 3];
        for axis in 0..3 {
            let coord = p[axis];
            let upper = self.dims[axis] as f32 - 0.5;
            // Written as a negated range test so NaN coordinates also count as outside.
            if !(coord >= -0.5 && coord <= upper) {
                return 0.0;
            }
            let base = coord.floor();
            frac[axis] = coord - base;
            let last = self.dims[axis] - 1;
            lo[axis] = if base < 0.0 { 0 } else { (base as usize).min(last) };
            hi[axis] = ((base + 1.0) as usize).min(last);
        }
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let row = |y: usize, z: usize| lerp(self.get(lo[0], y, z), self.get(hi[0], y, z), frac[0]);
        let plane = |z: usize| lerp(row(lo[1], z), row(hi[1], z), frac[1]);
        lerp(plane(lo[2]), plane(hi[2]), frac[2])
    }

    pub fn min_spacing(&self) -> f32 {
        self.spacing.iter().copied().fold(f32::INFINITY, f32::min)
    }

    /// Physical size of the whole grid: `dims * spacing` per axis.
    pub fn extent(&self) -> [f32; 3] {
        [0, 1, 2].map(|a| self.dims[a] as f32 * self.spacing[a])
    }

    /// Maps values through the window `[lo, hi]` to [0, 1] (clamped) and quantises to u16
    /// (0..=65535, round to nearest). An empty or inverted window acts as a threshold at `lo`.
    pub fn normalized_u16(&self, window: [f32; 2]) -> Vec<u16> {
        let normalize = normalizer(window);
        self.data.par_iter().map(|&v| normalize(v)).collect()
    }
}

/// What [`Volume::normalized_u16`] makes of each value under `window`. It never decreases as
/// the value grows, so the extremes of a set of values map to the extremes of their samples.
pub fn normalizer(window: [f32; 2]) -> impl Fn(f32) -> u16 + Copy + Sync {
    let [lo, hi] = window;
    let width = hi - lo;
    let usable = width.is_finite() && width > 0.0;
    move |v: f32| {
        let t = if usable {
            (v - lo) / width
        } else if v > lo {
            1.0
        } else {
            0.0
        };
        round_half_away(t.clamp(0.0, 1.0) * 65535.0) as u16
    }
}

/// `x.round()` (to nearest, halves away from zero), to the bit, without a call: on the x86-64
/// baseline `f32::round` is a call into libm for every value (no SSE4.1), which the volumes'
/// texels paid tens of millions of times at every change of the data window. Below 2²³ in
/// magnitude `x - trunc(x)` is exact, so comparing it with 0.5 decides as `round` does; from
/// there every float is an integer (and NaN and the infinities stay themselves).
#[inline]
pub fn round_half_away(x: f32) -> f32 {
    let a = x.abs();
    if a >= 8_388_608.0 || a.is_nan() {
        return x;
    }
    let t = a as i32 as f32;
    let r = if a - t >= 0.5 { t + 1.0 } else { t };
    r.copysign(x)
}

/// Loads a volume file, choosing the reader by extension; see [`open`].
pub fn load(path: &Path) -> Result<Volume, VolumeError> {
    open(path).map(|loaded| loaded.volume)
}

/// File extensions [`open`] understands (a directory is read as a DICOM series).
pub const EXTENSIONS: &str = ".nrrd, .nhdr, .mha, .mhd, .nii, .nii.gz, .hdr, .vti, a DICOM file (its series), \
                              a DICOMDIR, .raw with a .json sidecar, or a directory of DICOM files";

/// Loads a volume with what the file says about it and its histogram, choosing the reader by
/// extension; a directory, a DICOMDIR or a DICOM file is read as a DICOM series.
pub fn open(path: &Path) -> Result<Loaded, VolumeError> {
    open_series(path, None)
}

/// [`open`], choosing one of several DICOM series by its number or UID
/// ([`dicom::list_series`]); other formats ignore `series`.
pub fn open_series(path: &Path, series: Option<&str>) -> Result<Loaded, VolumeError> {
    if path.is_dir() {
        return dicom::open_dicom(path, series).map_err(|e| e.in_file(path, "DICOM"));
    }
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let ext = name.rsplit('.').next().unwrap_or("");
    let (format, loaded) = match ext {
        "nrrd" | "nhdr" => ("NRRD", nrrd::open_nrrd(path)),
        "mha" | "mhd" => ("MetaImage", metaimage::load_metaimage(path)),
        "nii" | "hdr" => ("NIfTI", nifti::load_nifti(path)),
        "gz" if name.ends_with(".nii.gz") || name.ends_with(".hdr.gz") => ("NIfTI", nifti::load_nifti(path)),
        "vti" => ("VTK ImageData", vti::load_vti(path)),
        "dcm" | "dicom" | "ima" => ("DICOM", dicom::open_dicom(path, series)),
        _ if name == "dicomdir" => ("DICOM", dicom::open_dicom(path, series)),
        _ => match raw::sidecar_path(path) {
            Some(sidecar) => ("raw", raw::load_raw_with_sidecar(path, &sidecar)),
            // Scanners often write DICOM files without an extension.
            None if dicom::is_dicom_file(path) => ("DICOM", dicom::open_dicom(path, series)),
            None => {
                return Err(VolumeError::UnknownFormat {
                    path: path.to_path_buf(),
                })
            }
        },
    };
    loaded.map_err(|e| e.in_file(path, format))
}

impl VolumeError {
    /// The error with the file it came from and that file's format, where its message does
    /// not already name a file (the volume's data, dims, spacing or scalar type).
    pub fn in_file(self, path: &Path, format: &'static str) -> VolumeError {
        match self {
            VolumeError::SizeMismatch { .. }
            | VolumeError::NonFinite { .. }
            | VolumeError::InvalidDims(_)
            | VolumeError::InvalidSpacing(_)
            | VolumeError::TooLarge { .. }
            | VolumeError::UnsupportedType(_) => VolumeError::InFile {
                path: path.to_path_buf(),
                format,
                inner: Box::new(self),
            },
            other => other,
        }
    }

    /// The error itself, without the file [`VolumeError::in_file`] added.
    pub fn root(&self) -> &VolumeError {
        match self {
            VolumeError::InFile { inner, .. } => inner.root(),
            other => other,
        }
    }
}

/// Voxel count of `dims`, rejecting zero-sized axes and anything above [`MAX_VOXELS`].
pub fn checked_voxel_count(dims: [usize; 3]) -> Result<usize, VolumeError> {
    if dims.contains(&0) {
        return Err(VolumeError::InvalidDims(dims));
    }
    match dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d)) {
        Some(count) if count <= MAX_VOXELS => Ok(count),
        _ => Err(VolumeError::TooLarge {
            dims,
            limit: MAX_VOXELS,
        }),
    }
}

/// `[min, max]` of non-empty finite data.
pub(crate) fn value_range(data: &[f32]) -> [f32; 2] {
    data.iter().fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], &v| {
        [lo.min(v), hi.max(v)]
    })
}

/// "10×10×10"
pub fn dims_text(dims: &[usize; 3]) -> String {
    format!("{}×{}×{}", dims[0], dims[1], dims[2])
}

fn voxel_product(dims: &[usize; 3]) -> u128 {
    dims.iter().map(|&d| d as u128).product()
}

fn line_text(line: &Option<usize>) -> String {
    line.map(|l| format!(" line {l}")).unwrap_or_default()
}

#[derive(Debug, thiserror::Error)]
pub enum VolumeError {
    /// An error that does not name the file by itself (its data, dims or spacing), with the
    /// file and its format.
    #[error("{} ({format}): {inner}", path.display())]
    InFile {
        path: PathBuf,
        format: &'static str,
        inner: Box<VolumeError>,
    },
    #[error("cannot read {}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("volume data has {actual} samples but its dims need {expected}")]
    SizeMismatch { expected: usize, actual: usize },
    #[error("volume contains {count} non-finite voxel values (NaN or infinity)")]
    NonFinite { count: usize },
    #[error("invalid volume dims {}: every dimension must be at least 1", dims_text(.0))]
    InvalidDims([usize; 3]),
    #[error("invalid voxel spacing {0:?}: every spacing must be finite and greater than 0")]
    InvalidSpacing([f32; 3]),
    #[error(
        "volume dims {} = {} voxels exceed the limit of {limit} voxels",
        dims_text(dims),
        voxel_product(dims)
    )]
    TooLarge { dims: [usize; 3], limit: usize },
    #[error(
        "{kind} {} has {actual_bytes} bytes but {layout} need {expected_bytes} bytes",
        path.display()
    )]
    Truncated {
        kind: &'static str,
        path: PathBuf,
        expected_bytes: u64,
        actual_bytes: u64,
        layout: String,
    },
    #[error(
        "{kind} {} has {actual_bytes} bytes but {layout} need only {expected_bytes} bytes: \
         dims don't match the data",
        path.display()
    )]
    ExtraData {
        kind: &'static str,
        path: PathBuf,
        expected_bytes: u64,
        actual_bytes: u64,
        layout: String,
    },
    /// A header (or sidecar) that cannot be read; `format` names the file's format.
    #[error("{format} header of {}{}: {message}", path.display(), line_text(line))]
    Header {
        format: &'static str,
        path: PathBuf,
        line: Option<usize>,
        message: String,
    },
    #[error(
        "{}: unsupported NRRD encoding '{encoding}' (supported: raw, gzip, ascii)",
        path.display()
    )]
    UnsupportedEncoding { path: PathBuf, encoding: String },
    #[error(
        "unsupported scalar type '{0}' (supported: u8, i8, u16, i16, u32, i32, f32, f64, \
         also under their C and NRRD names)"
    )]
    UnsupportedType(String),
    #[error("data of {}: {message}", path.display())]
    Data { path: PathBuf, message: String },
    #[error("time series: {0}")]
    Series(String),
    #[error(
        "{} holds several DICOM series; pick one with --series N or --series UID:\n{listing}",
        path.display()
    )]
    SeveralSeries { path: PathBuf, listing: String },
    #[error("DICOM series in {}: {message}", path.display())]
    DicomSeries { path: PathBuf, message: String },
    #[error(
        "unknown scene volume '{0}' (valid names: {names})",
        names = procedural::SCENE_VOLUMES.join(", ")
    )]
    UnknownScene(String),
    #[error(
        "unknown volume format for {} (supported: {ext}; for raw files give \
         --raw-dims and --raw-type, or kind = \"raw\" in a scene file)",
        path.display(),
        ext = EXTENSIONS
    )]
    UnknownFormat { path: PathBuf },
}

impl crate::Classify for VolumeError {
    fn exit_class(&self) -> crate::ExitClass {
        crate::ExitClass::Input // every variant is a file or its data at fault
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_half_away_is_round_to_the_bit() {
        // Halves, the floats beside them, the 2²³ boundary, signs, zeros and the non-finite.
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            2.5,
            -2.5,
            0.499_999_97,
            0.500_000_06,
            65_534.5,
            65_535.0,
            8_388_607.5,
            8_388_608.0,
            -8_388_607.5,
            16_777_217.0,
            f32::MAX,
            f32::MIN_POSITIVE,
            1e-45,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        for h in 0..70_000 {
            let half = h as f32 + 0.5;
            xs.extend([
                half,
                -half,
                f32::from_bits(half.to_bits() - 1),
                f32::from_bits(half.to_bits() + 1),
            ]);
        }
        // Every 61st bit pattern of the positive and negative floats below 2²⁴.
        let top = 16_777_216.0f32.to_bits();
        xs.extend(
            (0..top)
                .step_by(61)
                .flat_map(|b| [f32::from_bits(b), -f32::from_bits(b)]),
        );
        for x in xs {
            assert_eq!(round_half_away(x).to_bits(), x.round().to_bits(), "{x:e}");
        }
        assert!(round_half_away(f32::NAN).is_nan());
    }

    #[test]
    fn axes_reordered_keep_every_voxel() {
        let dims = [5, 4, 3];
        let data: Vec<f32> = (0..60).map(|i| i as f32).collect();
        let v = Volume::new(dims, [1.0, 2.0, 3.0], data).unwrap();
        for axes in [[0, 1, 2], [2, 1, 0], [1, 2, 0], [2, 0, 1]] {
            let w = v.with_axes(axes);
            assert_eq!(w.dims, axes.map(|a| dims[a]));
            assert_eq!(w.spacing, axes.map(|a| v.spacing[a]));
            for z in 0..w.dims[2] {
                for y in 0..w.dims[1] {
                    for x in 0..w.dims[0] {
                        // Voxel (x, y, z) of the new layout is the one whose axis axes[i] is at
                        // the i-th of them.
                        let mut at = [0; 3];
                        for (i, c) in [x, y, z].into_iter().enumerate() {
                            at[axes[i]] = c;
                        }
                        assert_eq!(w.get(x, y, z), v.get(at[0], at[1], at[2]), "{axes:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn errors_in_a_files_data_name_the_file_and_its_format() {
        // NaN voxels in an NRRD file, and dims the size check rejects in a MetaImage header:
        // the message says which file and which format, and the error underneath is kept.
        let dir = test_support::ScratchDir::new("volume-in-file");
        let mut nrrd = b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 1\nencoding: raw\nendian: little\n\n".to_vec();
        nrrd.extend([1.0f32, f32::NAN].iter().flat_map(|v| v.to_le_bytes()));
        let path = dir.write("nan.nrrd", &nrrd);
        let err = open(&path).unwrap_err();
        assert!(matches!(err.root(), VolumeError::NonFinite { count: 1 }), "{err}");
        assert_eq!(
            err.to_string(),
            format!(
                "{} (NRRD): volume contains 1 non-finite voxel values (NaN or infinity)",
                path.display()
            )
        );
        let mha = b"ObjectType = Image\nNDims = 3\nDimSize = 0 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
        let path = dir.write("empty.mha", mha);
        let err = open(&path).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("empty.mha") && text.contains("MetaImage"), "{text}");
        // Errors that already name their file are left as they are.
        let err = open(&dir.write("short.nrrd", &nrrd[..nrrd.len() - 2])).unwrap_err();
        assert!(!matches!(err, VolumeError::InFile { .. }), "{err}");
        assert!(err.to_string().contains("short.nrrd"), "{err}");
    }

    fn ramp(dims: [usize; 3]) -> Volume {
        let count = dims.iter().product();
        let data = (0..count).map(|i| i as f32).collect();
        Volume::new(dims, [1.0, 2.0, 0.5], data).expect("valid volume")
    }

    #[test]
    fn new_validates_and_computes_range() {
        let vol = ramp([2, 3, 4]);
        assert_eq!(vol.voxel_count(), 24);
        assert_eq!(vol.value_range, [0.0, 23.0]);
        assert_eq!(vol.get(1, 2, 3), 23.0);
        assert_eq!(vol.min_spacing(), 0.5);
        assert_eq!(vol.extent(), [2.0, 6.0, 2.0]);

        let err = Volume::new([2, 2, 2], [1.0; 3], vec![0.0; 7]).unwrap_err();
        assert!(matches!(err, VolumeError::SizeMismatch { expected: 8, actual: 7 }));
        let err = Volume::new([0, 2, 2], [1.0; 3], vec![]).unwrap_err();
        assert!(matches!(err, VolumeError::InvalidDims(_)));
        let err = Volume::new([1, 1, 1], [1.0, 0.0, 1.0], vec![0.0]).unwrap_err();
        assert!(matches!(err, VolumeError::InvalidSpacing(_)));
        let err = Volume::new([1, 1, 1], [1.0, f32::NAN, 1.0], vec![0.0]).unwrap_err();
        assert!(matches!(err, VolumeError::InvalidSpacing(_)));
        let data = vec![0.0, f32::NAN, f32::INFINITY, 1.0];
        let err = Volume::new([4, 1, 1], [1.0; 3], data).unwrap_err();
        assert!(matches!(err, VolumeError::NonFinite { count: 2 }));
    }

    #[test]
    fn voxel_limit_is_checked_without_overflow() {
        assert!(matches!(
            checked_voxel_count([usize::MAX, 2, 2]),
            Err(VolumeError::TooLarge { .. })
        ));
        assert!(checked_voxel_count([1 << 10, 1 << 10, 1 << 11]).is_ok());
        let err = checked_voxel_count([1 << 10, 1 << 10, (1 << 11) + 1]).unwrap_err();
        assert!(err.to_string().contains("1024×1024×2049"), "{err}");
    }

    #[test]
    fn trilinear_matches_voxels_and_interpolates() {
        let vol = ramp([3, 3, 3]);
        assert_eq!(vol.sample_trilinear([1.0, 2.0, 0.0]), vol.get(1, 2, 0));
        let mid = vol.sample_trilinear([0.5, 0.5, 0.5]);
        let mut corners = 0.0;
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..2 {
                    corners += vol.get(x, y, z);
                }
            }
        }
        assert!((mid - corners / 8.0).abs() < 1e-5);
        // Between the last centre and the grid border the edge voxel is repeated.
        assert_eq!(vol.sample_trilinear([2.4, 2.0, 2.0]), vol.get(2, 2, 2));
        assert_eq!(vol.sample_trilinear([-0.4, 0.0, 0.0]), vol.get(0, 0, 0));
        assert_eq!(vol.sample_trilinear([-0.6, 1.0, 1.0]), 0.0);
        assert_eq!(vol.sample_trilinear([1.0, 2.6, 1.0]), 0.0);
        assert_eq!(vol.sample_trilinear([1.0, f32::NAN, 1.0]), 0.0);
    }

    #[test]
    fn normalized_u16_windows_and_rounds() {
        let vol = Volume::new([5, 1, 1], [1.0; 3], vec![-1.0, 0.0, 0.5, 1.0, 2.0]).expect("valid");
        assert_eq!(vol.normalized_u16([0.0, 1.0]), vec![0, 0, 32768, 65535, 65535]);
        assert_eq!(vol.normalized_u16([0.5, 0.5]), vec![0, 0, 0, 65535, 65535]);
    }

    #[test]
    fn load_rejects_unknown_extension() {
        let err = load(Path::new("head.raw")).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("head.raw") && text.contains(".nrrd, .nhdr"), "{text}");
        assert!(
            text.contains(".nii.gz") && text.contains(".vti") && text.contains(".mha"),
            "{text}"
        );
    }
}
