//! The light, the specular shading and the environment, with the bounds the light buffers
//! impose.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// The largest light angle off the view direction. The planes are parallel to the image, so
/// light at 90° would travel inside one plane and never reach the next: the backward lookup
/// distance grows as tan(angle), 57 plane spacings at 89°. Artefacts become visible beyond ~85°.
pub const MAX_LIGHT_POLAR_DEG: f32 = 89.0;

/// One distant light, given relative to the camera: `polar_deg` off the view direction (0 =
/// from behind the viewer, at most [`MAX_LIGHT_POLAR_DEG`]), `azimuth_deg` around it (0 = from
/// the top of the image, 90 = from the right).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Light {
    pub polar_deg: f32,
    pub azimuth_deg: f32,
    pub color: [f32; 3],
    pub intensity: f32,
    /// Angular spread of the source: blur radius per unit distance travelled (0 = hard shadows).
    pub softness: f32,
}

/// Largest light colour × intensity: the light buffers hold 16-bit floats (max 65504), and
/// caustics concentrate light by up to `quality.max_concentration` before the per-texel clamp
/// (`scene::view::MAX_LIGHT_VALUE`, the same number) applies.
pub const MAX_LIGHT_RADIANCE: f32 = 16384.0;

/// Largest `quality.max_concentration`: beyond this the light clamp (`MAX_LIGHT_VALUE`) is
/// what bounds caustics anyway, for any light of intensity ≥ 1.
pub const MAX_CONCENTRATION: f32 = 16384.0;

/// Largest `shading.specular` (a scale of the Cook–Torrance term; 1 is physical).
pub const MAX_SPECULAR: f32 = 100.0;

/// Largest softness: a blur radius equal to the distance travelled (a 45° half-angle source).
pub const MAX_SOFTNESS: f32 = 1.0;

impl Default for Light {
    fn default() -> Self {
        Light {
            polar_deg: 30.0,
            azimuth_deg: 0.0,
            color: [1.0; 3],
            intensity: 1.0,
            softness: 0.05,
        }
    }
}

/// Specular (Cook–Torrance) shading parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Shading {
    pub specular: f32,
    pub roughness: f32,
}

impl Default for Shading {
    fn default() -> Self {
        Shading {
            specular: 1.0,
            roughness: 0.2,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Environment {
    /// A procedural studio: sky gradient over a checkered floor.
    Studio {
        #[serde(default = "one")]
        intensity: f32,
    },
    /// A constant background colour.
    Color { color: [f32; 3] },
    /// An equirectangular image (PNG or EXR).
    Image {
        path: PathBuf,
        #[serde(default = "one")]
        intensity: f32,
    },
}

fn one() -> f32 {
    1.0
}

impl Default for Environment {
    fn default() -> Self {
        Environment::Studio { intensity: 1.0 }
    }
}
