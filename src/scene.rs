//! Everything one image depends on: volume source, transfer functions, camera, light, clip
//! plane, environment and quality. Scenes are TOML files (see README) or built in ([`builtin`]).
//! Also the GPU-free pieces the renderer and the CPU reference share: the view setup
//! ([`view`]), the scene with its data loaded ([`PreparedScene`]), environment maps and the
//! rendered image.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::transfer::{TransferError, TransferFunctions};
use crate::volume::VolumeError;

mod builtin;
mod camera;
pub mod environment;
pub mod image;
mod lighting;
mod prepared;
mod quality;
mod source;
mod validate;
pub mod view;
pub use builtin::{builtin, BuiltinScene, BUILTIN_SCENES};
pub use camera::{Camera, ClipPlane, Projection, View, MAX_PITCH_DEG, VIEW_NAMES};
pub use environment::{srgb_to_linear, EnvError, EnvMap};
pub use image::{linear_to_srgb, OutputError, RenderedImage};
pub use lighting::{
    Environment, Light, Shading, MAX_CONCENTRATION, MAX_LIGHT_POLAR_DEG, MAX_LIGHT_RADIANCE, MAX_SOFTNESS, MAX_SPECULAR,
};
pub use prepared::{PrepareError, PreparedScene, VolumeInfo};
pub use quality::{
    Gradient, LightTransport, Precision, Quality, Toggle, BACKWARD_MAX_CONCENTRATION, MAX_BEAMS_PER_TEXEL,
    MIN_BEAMS_PER_TEXEL,
};
pub use source::{TransferSource, VolumeSource};
pub use view::{camera_position, light_direction, ViewSetup};

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read scene file {path}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("scene file {path} is invalid: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("invalid scene: {0}")]
    Invalid(String),
    #[error(transparent)]
    Volume(#[from] VolumeError),
    #[error(transparent)]
    Transfer(#[from] TransferError),
}

impl crate::Classify for SceneError {
    fn exit_class(&self) -> crate::ExitClass {
        match self {
            SceneError::Io { .. } | SceneError::Parse { .. } | SceneError::Invalid(_) => crate::ExitClass::Input,
            SceneError::Volume(e) => e.exit_class(),
            SceneError::Transfer(e) => e.exit_class(),
        }
    }
}

/// A complete scene description.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    pub volume: VolumeSource,
    /// Optional separate volume used as the source of η (paper Fig. 12e); resampled onto the
    /// volume's grid when its dims differ (both span the same box).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eta_volume: Option<VolumeSource>,
    /// Data values mapped to 0 and 1 of the transfer-function domain; default: the value range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<[f32; 2]>,
    pub transfer: TransferSource,
    #[serde(default)]
    pub camera: Camera,
    #[serde(default)]
    pub light: Light,
    #[serde(default)]
    pub shading: Shading,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clip: Option<ClipPlane>,
    #[serde(default)]
    pub environment: Environment,
    #[serde(default)]
    pub quality: Quality,
}

impl Scene {
    /// Reads a TOML scene; relative paths are taken relative to the scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut scene: Scene = toml::from_str(&text).map_err(|e| SceneError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        scene.volume.resolve_paths(base);
        if let Some(v) = &mut scene.eta_volume {
            v.resolve_paths(base);
        }
        if let TransferSource::File(p) = &scene.transfer {
            // Any importable format; positions in data units give the window unless one is set.
            let imported = crate::transfer::load_any(&base.join(p))?;
            scene.window = scene.window.or(imported.domain);
            scene.transfer = TransferSource::Inline(imported.tf);
        }
        if let Environment::Image { path, .. } = &mut scene.environment {
            *path = base.join(&*path);
        }
        scene.validate()?;
        Ok(scene)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// The transfer functions (file sources are resolved by [`Scene::load`]).
    pub fn transfer_functions(&self) -> Result<TransferFunctions, SceneError> {
        match &self.transfer {
            TransferSource::Inline(tf) => Ok(tf.clone()),
            TransferSource::File(p) => Ok(TransferFunctions::load(p)?),
        }
    }
}
