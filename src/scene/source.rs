//! Where a scene's data comes from: the volume (built in, a file, raw samples, a series) and
//! the transfer functions (inline or a file).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::transfer::TransferFunctions;
use crate::volume::procedural::Part;
use crate::volume::series::Series;
use crate::volume::{self, raw::RawDesc, Format, Loaded, Volume, VolumeError, VolumeMeta};

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
    /// A file whose format is known from its extension (see README, "Volume input"), or a
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
    /// The whole built-in volume `name` at `resolution`.
    pub fn builtin(name: &str, resolution: usize) -> VolumeSource {
        VolumeSource::Builtin {
            name: name.to_string(),
            resolution,
        }
    }

    /// Whether this is a built-in scene volume whose objects stand on supports (ground,
    /// walls): its η then comes from the objects alone ([`VolumeSource::builtin_objects`]).
    pub fn has_builtin_objects(&self) -> bool {
        matches!(self, VolumeSource::Builtin { name, .. } if volume::procedural::SCENE_VOLUMES.contains(&name.as_str()))
    }

    /// The objects of a built-in scene volume without their ground and walls, on the same
    /// grid and with the same values: the η source of built-in volumes, so that the supports'
    /// surfaces, blended from air to ground, do not pass through the objects' η in a thin film.
    pub fn builtin_objects(&self) -> Result<Option<Volume>, VolumeError> {
        match self {
            VolumeSource::Builtin { name, resolution } if self.has_builtin_objects() => {
                volume::procedural::generate_part(name, *resolution, Part::Objects).map(Some)
            }
            _ => Ok(None),
        }
    }

    /// Sets the resolution of a built-in volume (no effect on others).
    pub fn set_resolution(&mut self, n: usize) {
        if let VolumeSource::Builtin { resolution, .. } = self {
            *resolution = n;
        }
    }

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

    pub(super) fn resolve_paths(&mut self, base: &Path) {
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
