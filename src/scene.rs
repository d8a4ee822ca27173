//! Everything one image depends on: volume source, transfer functions, camera, light, clip
//! plane, environment and quality. Scenes are TOML files (see README) or built in ([`builtin`]).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::transfer::{TransferError, TransferFunctions};
use crate::volume::series::Series;
use crate::volume::{self, raw::RawDesc, Format, Loaded, Volume, VolumeError, VolumeMeta};

mod builtin;
mod views;
pub use builtin::{builtin, BuiltinScene, BUILTIN_SCENES};
pub use views::{View, MAX_PITCH_DEG, VIEW_NAMES};

/// The largest light angle off the view direction. The planes are parallel to the image, so
/// light at 90° would travel inside one plane and never reach the next: the backward lookup
/// distance grows as tan(angle), 57 plane spacings at 89°. Artefacts become visible beyond ~85°.
pub const MAX_LIGHT_POLAR_DEG: f32 = 89.0;

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

/// Where the volume comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum VolumeSource {
    /// A procedural volume generated in code (`caustica scenes` lists them).
    Builtin {
        name: String,
        #[serde(default = "default_resolution")]
        resolution: usize,
    },
    /// A file whose format is known from its extension (see README, "Volume formats"), or a
    /// directory holding a DICOM series; `series` picks one of several DICOM series (its
    /// number in `caustica info DIR`, or its UID).
    File {
        path: PathBuf,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        series: Option<String>,
    },
    /// Raw samples: dims, scalar type, endianness and spacing given here.
    Raw(RawDesc),
    /// A time series: `files` in order, or the files matching `pattern` (one `*` in the file
    /// name); `frame` is the one shown.
    Series {
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        files: Vec<PathBuf>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        pattern: Option<PathBuf>,
        #[serde(default)]
        frame: usize,
    },
}

fn default_resolution() -> usize {
    128
}

impl VolumeSource {
    pub fn load(&self) -> Result<Volume, VolumeError> {
        self.open().map(|loaded| loaded.volume)
    }

    /// Loads the volume with its metadata and histogram; patient data is reoriented to the
    /// display axes ([`Loaded::into_display`]).
    pub fn open(&self) -> Result<Loaded, VolumeError> {
        self.open_stored().map(Loaded::into_display)
    }

    /// The volume as stored in its file.
    fn open_stored(&self) -> Result<Loaded, VolumeError> {
        match self {
            VolumeSource::Builtin { name, resolution } => Ok(Loaded::new(
                volume::procedural::generate(name, *resolution)?,
                VolumeMeta::new(Format::Procedural, None),
            )),
            VolumeSource::File { path, series } => volume::open_series(path, series.as_deref()),
            VolumeSource::Raw(desc) => Ok(Loaded::new(
                volume::raw::load_raw(desc)?,
                VolumeMeta::new(Format::Raw, Some(desc.scalar)),
            )),
            VolumeSource::Series { frame, .. } => match self.series()? {
                Some(series) => series.open_frame(*frame),
                None => Err(VolumeError::Series("no frames".into())),
            },
        }
    }

    /// The frames of a time series; `None` for a single volume.
    pub fn series(&self) -> Result<Option<Series>, VolumeError> {
        let VolumeSource::Series { files, pattern, .. } = self else {
            return Ok(None);
        };
        match (files.is_empty(), pattern) {
            (false, None) => Series::from_list(files.clone()).map(Some),
            (true, Some(p)) => Series::from_pattern(p).map(Some),
            _ => Err(VolumeError::Series(
                "give either files = [...] or pattern = \"...\"".into(),
            )),
        }
    }

    /// Selects frame `k` of a time series (no effect on a single volume).
    pub fn set_frame(&mut self, k: usize) {
        if let VolumeSource::Series { frame, .. } = self {
            *frame = k;
        }
    }

    fn resolve_paths(&mut self, base: &Path) {
        match self {
            VolumeSource::File { path, .. } => *path = base.join(&*path),
            VolumeSource::Raw(desc) => desc.path = base.join(&desc.path),
            VolumeSource::Series { files, pattern, .. } => {
                for f in files.iter_mut() {
                    *f = base.join(&*f);
                }
                if let Some(p) = pattern {
                    *p = base.join(&*p);
                }
            }
            VolumeSource::Builtin { .. } => {}
        }
    }
}

/// Transfer functions inline, or the path of a JSON file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum TransferSource {
    File(PathBuf),
    Inline(TransferFunctions),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Projection {
    #[default]
    Perspective,
    Orthographic,
}

/// An orbit camera around the volume's centre. Distances are in units of the volume's
/// bounding-sphere radius, so scenes do not depend on the voxel spacing. Orientation and the
/// named anatomical views: [`views`](self::View).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    pub yaw_deg: f32,
    pub pitch_deg: f32,
    /// Rotation of the image about the view direction (positive turns the camera clockwise,
    /// so the picture turns counter-clockwise).
    pub roll_deg: f32,
    pub distance: f32,
    pub fov_deg: f32,
    pub projection: Projection,
    /// Orthographic only: the view shows `2 / zoom` bounding radii vertically.
    pub zoom: f32,
    /// Look-at point, offset from the volume's centre in bounding radii (x right, y up, z back).
    pub target: [f32; 3],
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            yaw_deg: 0.0,
            pitch_deg: 20.0,
            roll_deg: 0.0,
            distance: 3.0,
            fov_deg: 40.0,
            projection: Projection::Perspective,
            zoom: 1.0,
            target: [0.0; 3],
        }
    }
}

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
/// (`render::MAX_LIGHT_VALUE`, the same number) applies.
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

/// A plane that zeroes opacity on its positive side and leaves every other property alone
/// (paper Fig. 9). `normal` in volume axes, `offset` from the centre in bounding radii.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipPlane {
    pub normal: [f32; 3],
    #[serde(default)]
    pub offset: f32,
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

    /// Range checks for everything a user can type.
    pub fn validate(&self) -> Result<(), SceneError> {
        let bad = |m: String| Err(SceneError::Invalid(m));
        if let TransferSource::Inline(tf) = &self.transfer {
            tf.validate()?;
        }
        let q = &self.quality;
        if !(q.sample_distance.is_finite() && (0.01..=16.0).contains(&q.sample_distance)) {
            return bad(format!(
                "quality.sample_distance {} must be in [0.01, 16]",
                q.sample_distance
            ));
        }
        if !(q.max_intensity_ratio.is_finite() && q.max_intensity_ratio >= 1.0) {
            return bad("quality.max_intensity_ratio must be ≥ 1".into());
        }
        if !(q.max_concentration.is_finite() && (1.0..=MAX_CONCENTRATION).contains(&q.max_concentration)) {
            return bad(format!("quality.max_concentration must be in [1, {MAX_CONCENTRATION}]"));
        }
        if !(0.0..=1.0).contains(&q.termination_opacity) {
            return bad("quality.termination_opacity must be in [0, 1]".into());
        }
        let l = &self.light;
        if !(0.0..=MAX_LIGHT_POLAR_DEG).contains(&l.polar_deg) {
            return bad(format!(
                "light.polar_deg {} must be in [0, {MAX_LIGHT_POLAR_DEG}]: the light must be in the viewer's hemisphere",
                l.polar_deg
            ));
        }
        if !(0.0..=MAX_SOFTNESS).contains(&l.softness) {
            return bad(format!("light.softness {} must be in [0, {MAX_SOFTNESS}]", l.softness));
        }
        if l.color.iter().chain([&l.intensity]).any(|c| !c.is_finite() || *c < 0.0) {
            return bad("light colour and intensity must be finite and ≥ 0".into());
        }
        if l.color.iter().any(|c| c * l.intensity > MAX_LIGHT_RADIANCE) {
            return bad(format!(
                "light colour × intensity must be at most {MAX_LIGHT_RADIANCE} (16-bit light buffers)"
            ));
        }
        let s = &self.shading;
        if !(s.specular.is_finite() && (0.0..=MAX_SPECULAR).contains(&s.specular)) {
            return bad(format!(
                "shading.specular {} must be in [0, {MAX_SPECULAR}]",
                s.specular
            ));
        }
        if !(0.0..=1.0).contains(&s.roughness) {
            return bad(format!("shading.roughness {} must be in [0, 1]", s.roughness));
        }
        if !l.azimuth_deg.is_finite() {
            return bad("light.azimuth_deg must be finite".into());
        }
        let c = &self.camera;
        let camera_ok = c.distance.is_finite()
            && c.distance > 0.0
            && (1.0..=170.0).contains(&c.fov_deg)
            && c.zoom.is_finite()
            && c.zoom > 0.0
            && [c.yaw_deg, c.pitch_deg, c.roll_deg]
                .iter()
                .chain(&c.target)
                .all(|v| v.is_finite());
        if !camera_ok {
            return bad(
                "camera: distance and zoom must be finite and > 0, fov_deg in [1, 170], angles and target finite"
                    .into(),
            );
        }
        let env_ok = match &self.environment {
            Environment::Studio { intensity } | Environment::Image { intensity, .. } => {
                intensity.is_finite() && (0.0..=MAX_LIGHT_RADIANCE).contains(intensity)
            }
            Environment::Color { color } => color
                .iter()
                .all(|v| v.is_finite() && (0.0..=MAX_LIGHT_RADIANCE).contains(v)),
        };
        if !env_ok {
            return bad(format!(
                "environment intensity and colour must be finite and in [0, {MAX_LIGHT_RADIANCE}]"
            ));
        }
        if let Some(w) = self.window {
            if !(w[0].is_finite() && w[1].is_finite() && w[1] > w[0]) {
                return bad(format!("window {w:?} must be two finite values, low < high"));
            }
        }
        if let Some(clip) = &self.clip {
            if clip.normal.iter().all(|v| *v == 0.0) || clip.normal.iter().any(|v| !v.is_finite()) {
                return bad("clip.normal must be a finite non-zero vector".into());
            }
            if !clip.offset.is_finite() {
                return bad("clip.offset must be finite".into());
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every number a user can type is range-checked: NaN, ±Inf and out-of-range values of
    /// each field are rejected with a message naming the field.
    #[test]
    fn non_finite_and_out_of_range_values_are_rejected() {
        let base = builtin("ball-lens").unwrap().scene;
        base.validate().unwrap();
        type Edit = fn(&mut Scene, f32);
        let fields: [(&str, Edit); 16] = [
            ("sample_distance", |s, v| s.quality.sample_distance = v),
            ("max_intensity_ratio", |s, v| s.quality.max_intensity_ratio = v),
            ("max_concentration", |s, v| s.quality.max_concentration = v),
            ("termination_opacity", |s, v| s.quality.termination_opacity = v),
            ("light.polar_deg", |s, v| s.light.polar_deg = v),
            ("light.azimuth_deg", |s, v| s.light.azimuth_deg = v),
            ("light.softness", |s, v| s.light.softness = v),
            ("light colour", |s, v| s.light.intensity = v),
            ("shading.specular", |s, v| s.shading.specular = v),
            ("shading.roughness", |s, v| s.shading.roughness = v),
            ("camera", |s, v| s.camera.distance = v),
            ("camera", |s, v| s.camera.zoom = v),
            ("camera", |s, v| s.camera.yaw_deg = v),
            ("camera", |s, v| s.camera.target[1] = v),
            ("environment", |s, v| {
                s.environment = Environment::Studio { intensity: v }
            }),
            ("clip.offset", |s, v| {
                s.clip = Some(ClipPlane {
                    normal: [1.0, 0.0, 0.0],
                    offset: v,
                })
            }),
        ];
        for (name, edit) in fields {
            for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let mut s = base.clone();
                edit(&mut s, v);
                let err = s.validate().expect_err(name).to_string();
                assert!(err.contains(name), "{name} = {v}: '{err}'");
            }
        }
        let mut s = base.clone();
        s.light.intensity = 2.0 * MAX_LIGHT_RADIANCE;
        assert!(s.validate().is_err(), "a light beyond the 16-bit light buffers");
        let mut s = base;
        s.shading.roughness = 1.5;
        assert!(s.validate().is_err());
    }
}
