//! The four transfer functions of the method: opacity α, particle colour c, refractive index η
//! (a curve) and medium colour m (a gradient), their JSON file format and validation.
//!
//! File format (`transfer_functions/*.json`): each function is a list of control points over the
//! normalised data value x ∈ [0, 1], linearly interpolated and held constant past the ends.
//! ```json
//! { "name": "glass",
//!   "opacity": [[0.0, 0.0], [0.8, 0.0], [0.9, 1.0]],          // [x, alpha per voxel]
//!   "color":   [[0.0, 1.0, 1.0, 1.0]],                         // [x, r, g, b] particle colour
//!   "eta":     [[0.0, 1.0], [0.4, 1.5]],                       // [x, refractive index]
//!   "medium":  [[0.0, 1.0, 1.0, 1.0], [0.4, 0.8, 1.0, 0.8]] }  // [x, r, g, b] transmittance per voxel
//! ```
//! Opacity is the fraction of light a one-voxel-long segment absorbs or reflects; the medium
//! colour is the fraction of each channel a one-voxel-long segment lets through. Both are
//! rescaled to the actual segment length by pre-integration ([`preintegrate`]).
//!
//! Two optional curves make the particles scatter (multiple scattering, see [`scattering`]):
//! ```json
//!   "albedo":     [[0.0, 0.0], [0.4, 0.95]],   // [x, ω] single-scattering albedo
//!   "anisotropy": [[0.0, 0.8]]                 // [x, g] Henyey–Greenstein mean cosine
//! ```
//! Opacity stays the extinction: of the light the particles remove, the fraction ω is
//! scattered on (and keeps travelling, spreading through the medium) and 1 − ω is absorbed.
//! The particle colour stays what the particles send toward the viewer. g shapes both: the
//! phase function of that last scattering toward the viewer, and how far forward the
//! scattered light keeps going. Without the two curves (or with ω = 0 and g = 0 everywhere)
//! images are exactly those of a medium that does not scatter.

mod auto;
mod curve;
pub mod import;
mod preintegrate;
pub mod scattering;

pub use auto::default_for;
pub use curve::{ColorRamp, Curve};
pub use import::{load_any, Imported};
pub use preintegrate::{preintegrate, PreintegratedTables, MAX_OPTICAL_DEPTH_PER_VOXEL, TABLE_SIZE};

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Refractive indices outside this range are rejected: below 1 nothing physical is modelled
/// here, and above 4 (germanium in the infrared) no material of interest exists.
pub const ETA_RANGE: [f32; 2] = [1.0, 4.0];

/// Range of the Henyey–Greenstein mean cosine g: beyond ±0.99 the phase function's peak
/// ((1 + |g|)/(1 − |g|)² times the isotropic value) exceeds 4·10⁴ and no sampling of it
/// resolves the lobe.
pub const ANISOTROPY_RANGE: [f32; 2] = [-0.99, 0.99];

#[derive(Debug, thiserror::Error)]
pub enum TransferError {
    #[error("cannot read transfer function file {path}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("transfer function file {path} is not valid JSON for a transfer function: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("invalid transfer function: {function} point {index}: {message}")]
    Invalid {
        function: &'static str,
        index: usize,
        message: String,
    },
    #[error("cannot import transfer functions from {path}: {message}")]
    Import { path: PathBuf, message: String },
    #[error("invalid transfer function: {function} has no control points")]
    Empty { function: &'static str },
    /// An invalid function (`Invalid`, `Empty`) read from a file, with the file and its format.
    #[error("{format} file {}: {inner}", path.display())]
    InFile {
        path: PathBuf,
        format: &'static str,
        inner: Box<TransferError>,
    },
}

impl TransferError {
    /// The error with the file it was read from and that file's format, where its message
    /// does not already name a file.
    pub fn in_file(self, path: &Path, format: &'static str) -> TransferError {
        match self {
            TransferError::Invalid { .. } | TransferError::Empty { .. } => TransferError::InFile {
                path: path.to_path_buf(),
                format,
                inner: Box::new(self),
            },
            other => other,
        }
    }
}

impl crate::Classify for TransferError {
    fn exit_class(&self) -> crate::ExitClass {
        crate::ExitClass::Input // every variant is a file or a function at fault
    }
}

fn default_eta() -> Curve {
    Curve::constant(1.0)
}

fn default_white() -> ColorRamp {
    ColorRamp::constant([1.0; 3])
}

/// The four transfer functions of one scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransferFunctions {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub opacity: Curve,
    #[serde(default = "default_white")]
    pub color: ColorRamp,
    #[serde(default = "default_eta")]
    pub eta: Curve,
    #[serde(default = "default_white")]
    pub medium: ColorRamp,
    /// Single-scattering albedo ω in [0, 1]: the fraction of the light the particles remove
    /// that they scatter on. Absent: 0 (nothing scatters on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo: Option<Curve>,
    /// Henyey–Greenstein mean cosine g in [`ANISOTROPY_RANGE`]. Absent: 0 (isotropic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anisotropy: Option<Curve>,
}

impl Default for TransferFunctions {
    /// Conventional volume rendering: a linear opacity ramp, white particles, η = 1, white medium.
    fn default() -> Self {
        TransferFunctions {
            name: None,
            opacity: Curve {
                points: vec![[0.0, 0.0], [1.0, 0.5]],
            },
            color: default_white(),
            eta: default_eta(),
            medium: default_white(),
            albedo: None,
            anisotropy: None,
        }
    }
}

impl TransferFunctions {
    /// Parses and validates JSON text; `origin` names the source in error messages.
    pub fn from_json(text: &str, origin: &Path) -> Result<Self, TransferError> {
        let tf: TransferFunctions = serde_json::from_str(text).map_err(|e| TransferError::Parse {
            path: origin.to_path_buf(),
            message: e.to_string(),
        })?;
        tf.validate().map_err(|e| e.in_file(origin, "transfer-function JSON"))?;
        Ok(tf)
    }

    pub fn load(path: &Path) -> Result<Self, TransferError> {
        let text = std::fs::read_to_string(path).map_err(|source| TransferError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text, path)
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Checks every control point: finite, x in [0, 1] and non-decreasing, values in range.
    pub fn validate(&self) -> Result<(), TransferError> {
        self.opacity.validate("opacity", [0.0, 1.0])?;
        self.eta.validate("eta", ETA_RANGE)?;
        self.color.validate("color")?;
        self.medium.validate("medium")?;
        if let Some(a) = &self.albedo {
            a.validate("albedo", [0.0, 1.0])?;
        }
        if let Some(g) = &self.anisotropy {
            g.validate("anisotropy", ANISOTROPY_RANGE)?;
        }
        Ok(())
    }

    /// Single-scattering albedo at `x` (0 without an albedo curve).
    pub fn albedo_at(&self, x: f32) -> f32 {
        self.albedo.as_ref().map_or(0.0, |c| c.eval(x))
    }

    /// Henyey–Greenstein g at `x` (0 without an anisotropy curve).
    pub fn anisotropy_at(&self, x: f32) -> f32 {
        self.anisotropy.as_ref().map_or(0.0, |c| c.eval(x))
    }

    /// True when some data value scatters light on (ω > 0 somewhere, and there are particles
    /// to scatter: opacity > 0 somewhere).
    pub fn scatters(&self) -> bool {
        let particles = self.opacity.points.iter().any(|p| p[1] > 0.0);
        particles
            && self
                .albedo
                .as_ref()
                .is_some_and(|a| a.points.iter().any(|p| p[1] > 0.0))
    }

    /// True when the phase function is not isotropic somewhere (g ≠ 0).
    pub fn is_anisotropic(&self) -> bool {
        self.anisotropy
            .as_ref()
            .is_some_and(|g| g.points.iter().any(|p| p[1] != 0.0))
    }

    /// True when η is the same everywhere: no refraction work is needed.
    pub fn eta_is_constant(&self) -> bool {
        self.eta.is_constant()
    }

    /// True when the medium lets everything through: no medium buffer is needed.
    pub fn medium_is_white(&self) -> bool {
        self.medium
            .points
            .iter()
            .all(|p| p[1] >= 1.0 && p[2] >= 1.0 && p[3] >= 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_defaults() {
        let tf = TransferFunctions::from_json(r#"{"opacity": [[0,0],[1,1]]}"#, Path::new("t.json")).unwrap();
        assert!(tf.eta_is_constant());
        assert!(tf.medium_is_white());
        assert_eq!(tf.opacity.eval(0.5), 0.5);
    }

    #[test]
    fn rejects_bad_points() {
        let cases = [
            (r#"{"opacity": []}"#, "no control points"),
            (r#"{"opacity": [[0,0],[1,1.5]]}"#, "opacity point 1"),
            (r#"{"opacity": [[0.5,0],[0.2,1]]}"#, "decreasing"),
            (r#"{"opacity": [[0,0]], "eta": [[0, 0.5]]}"#, "eta point 0"),
            (r#"{"opacity": [[0,0]], "color": [[0, 1, 2, 1]]}"#, "color point 0"),
            (r#"{"opacity": [[0,0]], "medium": [[1.5, 1, 1, 1]]}"#, "outside [0, 1]"),
            (r#"{"opacity": [[0,0]], "colour": []}"#, "unknown field"),
            (r#"{"opacity": [[0,0]], "albedo": [[0, 1.2]]}"#, "albedo point 0"),
            (r#"{"opacity": [[0,0]], "albedo": []}"#, "albedo has no control points"),
            (
                r#"{"opacity": [[0,0]], "anisotropy": [[0, 0.5], [1, -1]]}"#,
                "anisotropy point 1",
            ),
            (r#"{"opacity": "x"}"#, "invalid type"),
        ];
        for (json, expected) in cases {
            let err = TransferFunctions::from_json(json, Path::new("t.json"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(expected), "{json}: '{err}' should mention '{expected}'");
        }
    }

    #[test]
    fn scattering_curves_are_optional_and_round_trip() {
        let plain = TransferFunctions::from_json(r#"{"opacity": [[0,0],[1,1]]}"#, Path::new("t.json")).unwrap();
        assert!(!plain.scatters() && !plain.is_anisotropic());
        assert_eq!((plain.albedo_at(0.5), plain.anisotropy_at(0.5)), (0.0, 0.0));
        assert!(!plain.to_json().contains("albedo"), "absent curves are not written");
        let json = r#"{"opacity": [[0,0],[1,1]], "albedo": [[0,0],[1,0.9]], "anisotropy": [[0,0.8]]}"#;
        let tf = TransferFunctions::from_json(json, Path::new("t.json")).unwrap();
        assert!(tf.scatters() && tf.is_anisotropic());
        assert!((tf.albedo_at(0.5) - 0.45).abs() < 1e-6);
        assert_eq!(tf.anisotropy_at(0.3), 0.8);
        let back = TransferFunctions::from_json(&tf.to_json(), Path::new("t.json")).unwrap();
        assert_eq!(back, tf);
        // Zero albedo everywhere, or no particles to scatter on, is no scattering.
        let zero = r#"{"opacity": [[0,0],[1,1]], "albedo": [[0,0]], "anisotropy": [[0,0]]}"#;
        let zero = TransferFunctions::from_json(zero, Path::new("t.json")).unwrap();
        assert!(!zero.scatters() && !zero.is_anisotropic());
        let clear = r#"{"opacity": [[0,0]], "albedo": [[0,1]]}"#;
        assert!(!TransferFunctions::from_json(clear, Path::new("t.json"))
            .unwrap()
            .scatters());
    }

    #[test]
    fn every_shipped_file_is_valid() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("transfer_functions");
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "json") {
                TransferFunctions::load(&path).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
        assert!(n >= 8, "expected the scene and CT presets, found {n}");
    }
}
