//! The speed/accuracy knobs: toggles, storage precision, gradient reconstruction.

use serde::{Deserialize, Serialize};

/// A feature toggle: `auto` enables it when the scene needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Toggle {
    #[default]
    Auto,
    On,
    Off,
}

/// Storage precision of the light, colour and medium state buffers (positions and
/// directions are always 32-bit float).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// 16-bit float: half the memory and bandwidth; about 3 decimal digits.
    #[default]
    F16,
    /// 32-bit float everywhere.
    F32,
}

impl Precision {
    pub fn parse(s: &str) -> Option<Precision> {
        match s {
            "f16" => Some(Precision::F16),
            "f32" => Some(Precision::F32),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Precision::F16 => "f16",
            Precision::F32 => "f32",
        }
    }
}

/// Reconstruction of the η gradient that bends the rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Gradient {
    /// Central differences one voxel apart: six lookups, second-order accurate.
    #[default]
    Central,
    /// Forward differences: four lookups, first-order accurate (biased half a voxel ahead).
    Forward,
}

impl Gradient {
    pub fn parse(s: &str) -> Option<Gradient> {
        match s {
            "central" => Some(Gradient::Central),
            "forward" => Some(Gradient::Forward),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Gradient::Central => "central",
            Gradient::Forward => "forward",
        }
    }

    /// The value of the shaders' `GRADIENT` override.
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// The speed/accuracy knobs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Quality {
    /// Distance between planes as a multiple of the smallest voxel dimension.
    pub sample_distance: f32,
    pub refraction: Toggle,
    pub intensity_correction: bool,
    pub light_filter: bool,
    pub specular: bool,
    /// View rays stop compositing once their opacity exceeds this.
    pub termination_opacity: f32,
    /// Per-plane clamp of the intensity-law ratio S_{i-1}/S_i and of its inverse; bounds the
    /// brightening at focal points, where the back-projected area goes to zero.
    pub max_intensity_ratio: f32,
    /// Storage precision of the light, colour and medium state buffers.
    pub precision: Precision,
    /// Power budget of the caustics: light is never more than this many times the source
    /// light anywhere. Bounds the light behind a focus, where the backward scheme cannot
    /// spread it again (see README, "Numerical safeguards").
    pub max_concentration: f32,
    /// Reconstruction of ∇η.
    pub gradient: Gradient,
}

impl Default for Quality {
    fn default() -> Self {
        Quality {
            sample_distance: 1.0,
            refraction: Toggle::Auto,
            intensity_correction: true,
            light_filter: true,
            specular: true,
            termination_opacity: 0.995,
            max_intensity_ratio: 4.0,
            precision: Precision::F16,
            max_concentration: 64.0,
            gradient: Gradient::Central,
        }
    }
}
