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
    /// Bytes of one rgba texel of the state buffers.
    pub fn rgba_bytes(self) -> u64 {
        match self {
            Precision::F16 => 8,
            Precision::F32 => 16,
        }
    }

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
    /// Fourth-order central differences, two voxels either side: twelve lookups, exact on a
    /// cubic η. Its leading error no longer has the lattice's four-fold pattern, so the light
    /// behind a smooth lens stays round; next to a sharp index step it overshoots (a ring of
    /// opposite gradient two voxels out), which bends rays at glass faces and thin walls.
    #[serde(rename = "fourth-order")]
    FourthOrder,
}

impl Gradient {
    pub fn parse(s: &str) -> Option<Gradient> {
        match s {
            "central" => Some(Gradient::Central),
            "forward" => Some(Gradient::Forward),
            "fourth-order" => Some(Gradient::FourthOrder),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Gradient::Central => "central",
            Gradient::Forward => "forward",
            Gradient::FourthOrder => "fourth-order",
        }
    }

    /// The value of the shaders' `GRADIENT` override.
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// How light travels from plane to plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LightTransport {
    /// Forward beams: one beam per light-grid cell carries position, direction and power from
    /// plane to plane and deposits its power onto each plane over its footprint. Rays may
    /// cross, power is conserved, and light is never resampled.
    #[default]
    Beams,
    /// The paper's backward (semi-Lagrangian) scheme with the intensity law: light is looked
    /// up on the previous plane along the stored direction. Rays cannot cross, so light behind
    /// a focus stays concentrated (bounded by the power budget).
    Backward,
}

impl LightTransport {
    pub fn parse(s: &str) -> Option<LightTransport> {
        match s {
            "beams" => Some(LightTransport::Beams),
            "backward" => Some(LightTransport::Backward),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            LightTransport::Beams => "beams",
            LightTransport::Backward => "backward",
        }
    }
}

/// How light that the particles scatter (transfer functions with an albedo) travels on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum MultipleScattering {
    /// `spread` when the transfer functions scatter (an albedo above 0 where there are
    /// particles) and the light is neither refracted nor carried backward; `none` otherwise.
    #[default]
    Auto,
    /// Scattered light is lost: the particles show what they scatter toward the viewer once.
    None,
    /// Premoze et al. 2004: the light scattered out of each beam spreads around it by the
    /// width its path through the medium gives (forward beams, without refraction).
    Spread,
    /// Bernabei et al.: lattice-Boltzmann diffusion (six directions) of the light the
    /// particles scatter, in a coarser light volume (`render::lbm`).
    Lbm,
}

impl MultipleScattering {
    pub fn name(self) -> &'static str {
        match self {
            MultipleScattering::Auto => "auto",
            MultipleScattering::None => "none",
            MultipleScattering::Spread => "spread",
            MultipleScattering::Lbm => "lbm",
        }
    }

    pub fn is_auto(&self) -> bool {
        *self == MultipleScattering::Auto
    }
}

/// Default power budget of the backward transport: it cannot spread light again behind a
/// focus, so the budget is what bounds it there (see README, "Numerical safeguards").
pub const BACKWARD_MAX_CONCENTRATION: f32 = 64.0;

/// Range of `quality.beams_per_texel`: below 1/4 a beam covers 16 pixels and shadows turn
/// blocky; above 4 the beam buffers hold 16 times the image.
pub const MIN_BEAMS_PER_TEXEL: f32 = 0.25;
pub const MAX_BEAMS_PER_TEXEL: f32 = 4.0;

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
    /// light anywhere. Unset: [`super::MAX_CONCENTRATION`] with beams (a safeguard physical
    /// scenes do not reach) and [`BACKWARD_MAX_CONCENTRATION`] with the backward transport,
    /// where it bounds the light behind a focus (see README, "Numerical safeguards").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_concentration: Option<f32>,
    /// How light travels from plane to plane.
    pub light_transport: LightTransport,
    /// Light-grid cells (beams) per image pixel and axis on the first plane: 1 maps one to
    /// each pixel; 2 traces four times as many for smoother caustics. Unrefracted light also
    /// gets at most this many per voxel and axis, refracted light 1.5 times this many but
    /// no fewer than half this many per pixel (`ViewSetup::beam_grid`, `VoxelCap`).
    pub beams_per_texel: f32,
    /// Reconstruction of ∇η.
    pub gradient: Gradient,
    /// How light scattered by the particles travels on (see [`MultipleScattering`]); left
    /// out of written scenes when `auto`, so scenes without scattering read as before.
    #[serde(skip_serializing_if = "MultipleScattering::is_auto")]
    pub multiple_scattering: MultipleScattering,
    /// The lattice-Boltzmann mode's grid and convergence (`[quality.lbm]`).
    #[serde(skip_serializing_if = "super::LbmSettings::is_default")]
    pub lbm: super::LbmSettings,
    /// Resolution of the volume the passes sample: 0 the volume as loaded, 1 half of it per
    /// axis (each texel the box-filtered mean of the voxels it covers; an eighth of the texels
    /// more on the device). For coarse renders whose planes and pixels are two voxels apart
    /// or more, which the full resolution only aliases: the viewer's first levels. The bricks
    /// and cells that skip empty space then reach as far as the half level's texels read
    /// (`occupancy::half_level_reach`). Left out of written scenes when 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub volume_level: u32,
}

/// The finest `quality.volume_level` but one: the volumes have at most their half-resolution
/// level beside their own.
pub const MAX_VOLUME_LEVEL: u32 = 1;

fn is_zero(v: &u32) -> bool {
    *v == 0
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
            max_concentration: None,
            light_transport: LightTransport::Beams,
            beams_per_texel: 1.0,
            gradient: Gradient::Central,
            multiple_scattering: MultipleScattering::Auto,
            lbm: super::LbmSettings::default(),
            volume_level: 0,
        }
    }
}

impl Quality {
    /// Whether light and view rays refract with these transfer functions: `auto` refracts
    /// where η_tf is not constant (an η volume goes through η_tf too, so a constant curve
    /// refracts nothing either way).
    pub fn refracts(&self, tf: &crate::transfer::TransferFunctions) -> bool {
        match self.refraction {
            Toggle::On => true,
            Toggle::Off => false,
            Toggle::Auto => !tf.eta_is_constant(),
        }
    }

    /// The power budget in effect: the scene's, or the transport's default.
    pub fn max_concentration(&self) -> f32 {
        self.max_concentration.unwrap_or(match self.light_transport {
            LightTransport::Beams => super::MAX_CONCENTRATION,
            LightTransport::Backward => BACKWARD_MAX_CONCENTRATION,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradients_parse_from_the_scene_file_by_their_names() {
        for g in [Gradient::Central, Gradient::Forward, Gradient::FourthOrder] {
            let parsed: Quality = toml::from_str(&format!("gradient = \"{}\"", g.name())).unwrap();
            assert_eq!(parsed.gradient, g);
            assert_eq!(Gradient::parse(g.name()), Some(g));
        }
        assert!(toml::from_str::<Quality>("gradient = \"fourthorder\"").is_err());
    }

    #[test]
    fn the_volume_level_parses_is_checked_and_is_left_out_of_written_scenes_at_zero() {
        let parsed: Quality = toml::from_str("volume_level = 1").unwrap();
        assert_eq!(parsed.volume_level, 1);
        assert!(!toml::to_string(&Quality::default()).unwrap().contains("volume_level"));
        assert!(toml::to_string(&parsed).unwrap().contains("volume_level = 1"));
        let tf = crate::transfer::TransferFunctions::default();
        for (level, ok) in [(0, true), (1, true), (2, false)] {
            let quality = Quality {
                volume_level: level,
                ..Quality::default()
            };
            let checked = crate::scene::Scene::head_on("test", &tf, 1.0, quality).validate();
            assert_eq!(checked.is_ok(), ok, "volume_level {level}: {checked:?}");
            if let Err(e) = checked {
                assert!(e.to_string().contains("quality.volume_level 2 must be 0"), "{e}");
            }
        }
    }

    #[test]
    fn multiple_scattering_parses_from_the_scene_file() {
        assert_eq!(Quality::default().multiple_scattering, MultipleScattering::Auto);
        for m in [
            MultipleScattering::Auto,
            MultipleScattering::None,
            MultipleScattering::Spread,
            MultipleScattering::Lbm,
        ] {
            let parsed: Quality = toml::from_str(&format!("multiple_scattering = \"{}\"", m.name())).unwrap();
            assert_eq!(parsed.multiple_scattering, m);
        }
        assert!(toml::from_str::<Quality>("multiple_scattering = \"diffusion\"").is_err());
    }
}
