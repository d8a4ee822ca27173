//! A scene with its data loaded (volumes, transfer functions, environment image): what the
//! renderer and the CPU reference both take.

use std::sync::Arc;

use super::environment::{EnvError, EnvMap};
use super::{Scene, SceneError};
use crate::transfer::TransferFunctions;
use crate::volume::resample::{fitting_dims, resample};
use crate::volume::{dims_text, Format, Histogram, Loaded, Volume, VolumeError, VolumeMeta};

/// Why a scene's data could not be loaded or fitted to a device.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Volume(#[from] VolumeError),
    #[error(transparent)]
    Environment(#[from] EnvError),
    /// The volume exceeds the device's limits and downsampling was not allowed.
    #[error("cannot render this view: {0}")]
    TooLarge(String),
}

impl crate::Classify for PrepareError {
    fn exit_class(&self) -> crate::ExitClass {
        match self {
            PrepareError::Scene(e) => e.exit_class(),
            PrepareError::Volume(e) => e.exit_class(),
            PrepareError::Environment(e) => e.exit_class(),
            // Refused before any GPU work: the input is too large for the device.
            PrepareError::TooLarge(_) => crate::ExitClass::Input,
        }
    }
}

/// A scene with its data loaded: volumes, transfer functions, environment image.
pub struct PreparedScene {
    pub scene: Scene,
    pub volume: Arc<Volume>,
    pub eta_volume: Option<Arc<Volume>>,
    pub tf: TransferFunctions,
    pub env: Option<EnvMap>,
    /// What the volume's file said about it, and its histogram (computed once at load).
    pub volume_info: VolumeInfo,
    /// The view reads the layers' orientation from a volume of its own (8 bytes per voxel,
    /// `render::layers`); where that does not fit the device beside the other volume textures
    /// ([`PreparedScene::fit_to_device`]), it samples the volume six times instead.
    pub orientation_volume: bool,
}

/// Metadata and histogram of the loaded volume, and the window used when the scene has none.
#[derive(Clone, Debug)]
pub struct VolumeInfo {
    pub meta: VolumeMeta,
    pub histogram: Histogram,
    pub default_window: [f32; 2],
}

impl VolumeInfo {
    fn of(loaded: &Loaded) -> VolumeInfo {
        VolumeInfo {
            meta: loaded.meta.clone(),
            histogram: loaded.histogram.clone(),
            default_window: loaded.default_window(),
        }
    }
}

impl PreparedScene {
    pub fn load(scene: &Scene) -> Result<Self, PrepareError> {
        scene.validate()?;
        let loaded = scene.volume.open()?;
        let volume_info = VolumeInfo::of(&loaded);
        let volume = Arc::new(loaded.volume);
        let eta_volume = match &scene.eta_volume {
            Some(src) => {
                let v = src.load()?;
                let v = if v.dims == volume.dims {
                    v
                } else {
                    log::warn!(
                        "resampling the η volume from {} onto the volume's grid {}",
                        dims_text(&v.dims),
                        dims_text(&volume.dims)
                    );
                    resample(&v, volume.dims)?
                };
                Some(Arc::new(v))
            }
            None => scene.volume.builtin_objects()?.map(Arc::new),
        };
        Ok(PreparedScene {
            tf: scene.transfer_functions()?,
            env: EnvMap::for_scene(&scene.environment)?,
            scene: scene.clone(),
            volume,
            eta_volume,
            volume_info,
            orientation_volume: true,
        })
    }

    pub fn from_parts(scene: Scene, volume: Volume, tf: TransferFunctions) -> Result<Self, PrepareError> {
        let loaded = Loaded::new(volume, VolumeMeta::new(Format::Procedural, None));
        Ok(PreparedScene {
            env: EnvMap::for_scene(&scene.environment)?,
            scene,
            volume_info: VolumeInfo::of(&loaded),
            volume: Arc::new(loaded.volume),
            eta_volume: None,
            tf,
            orientation_volume: true,
        })
    }

    /// The data window mapped onto [0, 1] of the transfer functions: the scene's, or else
    /// the volume's default (CT window for Hounsfield data, histogram percentiles for files,
    /// the value range for procedural volumes).
    pub fn window(&self) -> [f32; 2] {
        self.scene.window.unwrap_or(self.volume_info.default_window)
    }

    /// Replaces the transfer functions with the default for this volume's histogram and units.
    pub fn use_default_transfer(&mut self) {
        self.tf = crate::transfer::default_for(&self.volume_info.meta, &self.volume_info.histogram, self.window());
    }

    /// Loads frame `k` of a time-series volume in place (the viewer's time slider). Call
    /// [`PreparedScene::fit_to_device`] again afterwards if frames may exceed the device limits.
    pub fn load_frame(&mut self, k: usize) -> Result<(), PrepareError> {
        self.scene.volume.set_frame(k);
        let loaded = self.scene.volume.open()?;
        self.volume_info = VolumeInfo::of(&loaded);
        self.volume = Arc::new(loaded.volume);
        Ok(())
    }

    /// Downsamples the volumes (and warns) when they exceed `max_dim` voxels along an axis or
    /// `max_bytes` of volume texture memory; with `allow` false that is an error instead.
    /// Returns the new dims when the volume was downsampled. The orientation volume is kept
    /// only where it fits as well; it never makes the volume smaller. The volumes'
    /// half-resolution level counts where the scene reads it (`quality.volume_level`).
    pub fn fit_to_device(
        &mut self,
        max_dim: u32,
        max_bytes: u64,
        allow: bool,
    ) -> Result<Option<[usize; 3]>, PrepareError> {
        self.fit_to_device_keeping(max_dim, max_bytes, allow, false)
    }

    /// [`PreparedScene::fit_to_device`] for renders that keep the volumes' half-resolution
    /// level even where this scene does not read it (`keep_half_level`: the viewer, whose
    /// coarse levels do; `RenderRequest::keep_coarse_volume`).
    pub fn fit_to_device_keeping(
        &mut self,
        max_dim: u32,
        max_bytes: u64,
        allow: bool,
        keep_half_level: bool,
    ) -> Result<Option<[usize; 3]>, PrepareError> {
        // What the device holds: the volume's 16-bit samples and, with refraction, an rgba16f
        // gradient volume (8 bytes per voxel, `render::gradient`) of the η source, the η
        // volume or else the volume itself; an η volume's own samples are not uploaded. With
        // the half-resolution level, each has an image of ⌊n/2⌋ per axis beside it.
        let refracts = self.scene.quality.refracts(&self.tf);
        let half = keep_half_level || self.scene.quality.volume_level > 0;
        let count = |d: [usize; 3]| d.iter().map(|&n| n as u64).product::<u64>();
        let voxels = |d: [usize; 3]| {
            count(d)
                + if half {
                    count(crate::volume::half_level_dims(d))
                } else {
                    0
                }
        };
        let gradient_dims = refracts.then(|| self.eta_volume.as_ref().map_or(self.volume.dims, |e| e.dims));
        let bytes = 2 * voxels(self.volume.dims) + gradient_dims.map_or(0, |d| 8 * voxels(d));
        let largest = self
            .volume
            .dims
            .iter()
            .chain(gradient_dims.iter().flatten())
            .copied()
            .max()
            .unwrap_or(1);
        // The orientation volume: 8 bytes per voxel of the volume (`render::layers`).
        let orientation = |dims: [usize; 3], bytes: u64| bytes.saturating_add(8 * voxels(dims)) <= max_bytes;
        if largest <= max_dim as usize && bytes <= max_bytes {
            self.orientation_volume = orientation(self.volume.dims, bytes);
            if !self.orientation_volume {
                log::info!(
                    "the orientation volume ({} MiB) does not fit beside the volume textures; the view samples the volume six times instead",
                    (8 * voxels(self.volume.dims)) >> 20
                );
            }
            return Ok(None);
        }
        // Downsampled, the η volume takes the volume's dims: 2 + 8 bytes per voxel then, and
        // with the half level an eighth more (⌊n/2⌋³ ≤ n³/8 where no axis is a single voxel).
        let per_voxel = if refracts { 10 } else { 2 };
        let per_voxel_levels = if half { per_voxel * 9 } else { per_voxel * 8 };
        let max_voxels = (max_bytes.saturating_mul(8) / per_voxel_levels).min(usize::MAX as u64) as usize;
        let dims = fitting_dims(self.volume.dims, max_dim as usize, max_voxels).unwrap_or(self.volume.dims);
        let what = format!(
            "the volume {} exceeds the device's limits ({max_dim} texels per axis, {} MiB for volume textures)",
            dims_text(&self.volume.dims),
            max_bytes >> 20
        );
        if !allow {
            return Err(PrepareError::TooLarge(format!(
                "{what}; allow downsampling or use a smaller volume"
            )));
        }
        log::warn!("{what}: downsampling to {}", dims_text(&dims));
        if dims != self.volume.dims {
            self.volume = Arc::new(resample(&self.volume, dims)?);
        }
        if let Some(eta) = &self.eta_volume {
            if eta.dims != dims {
                self.eta_volume = Some(Arc::new(resample(eta, dims)?));
            }
        }
        self.orientation_volume = orientation(dims, per_voxel * voxels(dims));
        Ok(Some(dims))
    }
}
