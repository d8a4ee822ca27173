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
mod lbm;
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
pub use lbm::{LbmSettings, MAX_LBM_CELL_VOXELS, MAX_LBM_ITERATIONS};
pub use lighting::{
    Environment, Light, Shading, MAX_CONCENTRATION, MAX_LIGHT_POLAR_DEG, MAX_LIGHT_RADIANCE, MAX_SOFTNESS, MAX_SPECULAR,
};
pub use prepared::{PrepareError, PreparedScene, VolumeInfo};
pub use quality::{
    Gradient, LightTransport, MultipleScattering, Precision, Quality, Toggle, BACKWARD_MAX_CONCENTRATION,
    MAX_BEAMS_PER_TEXEL, MAX_VOLUME_LEVEL, MIN_BEAMS_PER_TEXEL,
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
    /// A scene file's value out of range (`Invalid`, an inline transfer function's), with the
    /// file.
    #[error("scene file {} (TOML): {inner}", path.display())]
    InFile { path: PathBuf, inner: Box<SceneError> },
}

impl SceneError {
    /// The error with the scene file it came from, where its message does not already name
    /// a file.
    pub fn in_file(self, path: &Path) -> SceneError {
        match self {
            SceneError::Invalid(_)
            | SceneError::Transfer(TransferError::Invalid { .. } | TransferError::Empty { .. }) => SceneError::InFile {
                path: path.to_path_buf(),
                inner: Box::new(self),
            },
            other => other,
        }
    }
}

impl crate::Classify for SceneError {
    fn exit_class(&self) -> crate::ExitClass {
        match self {
            SceneError::Io { .. } | SceneError::Parse { .. } | SceneError::Invalid(_) => crate::ExitClass::Input,
            SceneError::Volume(e) => e.exit_class(),
            SceneError::Transfer(e) => e.exit_class(),
            SceneError::InFile { inner, .. } => inner.exit_class(),
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
    /// Whether η comes from a volume of its own: the scene's `eta_volume`, or the objects of
    /// a built-in volume without their supports ([`VolumeSource::builtin_objects`]).
    pub fn has_eta_volume(&self) -> bool {
        self.eta_volume.is_some() || self.volume.has_builtin_objects()
    }

    /// Sets the resolution of the scene's built-in volumes (the volume and a built-in η
    /// volume alike, so that they stay on one grid).
    pub fn set_builtin_resolution(&mut self, n: usize) {
        self.volume.set_resolution(n);
        if let Some(eta) = &mut self.eta_volume {
            eta.set_resolution(n);
        }
    }

    /// An orthographic head-on view at `zoom` (it spans 2·(bounding radius)/zoom vertically)
    /// of a volume given apart from the scene (`name` labels it), hard white light along the
    /// view axis, a black background: the scenes of the benches' and tests' exact checks.
    pub fn head_on(name: &str, tf: &TransferFunctions, zoom: f32, quality: Quality) -> Scene {
        Scene {
            volume: VolumeSource::builtin(name, 0),
            eta_volume: None,
            window: Some([0.0, 1.0]),
            transfer: TransferSource::Inline(tf.clone()),
            camera: Camera {
                yaw_deg: 0.0,
                pitch_deg: 0.0,
                projection: Projection::Orthographic,
                zoom,
                ..Camera::default()
            },
            light: Light {
                polar_deg: 0.0,
                azimuth_deg: 0.0,
                color: [1.0; 3],
                intensity: 1.0,
                softness: 0.0,
            },
            shading: Shading::default(),
            clip: None,
            environment: Environment::Color { color: [0.0; 3] },
            quality,
        }
    }

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
        scene.validate().map_err(|e| e.in_file(path))?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_files_carry_the_scattering_curves() {
        let dir = std::env::temp_dir().join(format!("caustica-scene-scatter-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let inline = r#"
volume = { kind = "builtin", name = "ball-lens", resolution = 32 }
[transfer]
opacity = [[0.0, 0.0], [1.0, 0.2]]
albedo = [[0.0, 0.0], [0.5, 0.95]]
anisotropy = [[0.0, 0.8]]
"#;
        let path = dir.join("inline.toml");
        std::fs::write(&path, inline).unwrap();
        let scene = Scene::load(&path).unwrap();
        let tf = scene.transfer_functions().unwrap();
        assert!(tf.scatters());
        assert_eq!((tf.albedo_at(1.0), tf.anisotropy_at(0.3)), (0.95, 0.8));
        let back: Scene = toml::from_str(&scene.to_toml()).unwrap();
        assert_eq!(back, scene, "the curves survive writing the scene");
        // A JSON file named by the scene brings them too; a g outside its range is refused.
        let json = dir.join("milk.json");
        std::fs::write(&json, tf.to_json()).unwrap();
        std::fs::write(
            &path,
            "volume = { kind = \"builtin\", name = \"ball-lens\" }\ntransfer = \"milk.json\"\n",
        )
        .unwrap();
        assert_eq!(Scene::load(&path).unwrap().transfer_functions().unwrap(), tf);
        std::fs::write(&json, r#"{"opacity": [[0, 0.2]], "anisotropy": [[0, 1.0]]}"#).unwrap();
        let err = anyhow_chain(&Scene::load(&path).unwrap_err());
        assert!(err.contains("anisotropy point 0"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn anyhow_chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut source = e.source();
        while let Some(c) = source {
            s += &format!(": {c}");
            source = c.source();
        }
        s
    }
}
