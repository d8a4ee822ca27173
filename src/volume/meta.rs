//! What a file says about its volume beyond the samples: format, stored scalar type, physical
//! units and modality, plus the histogram, all gathered once at load ([`Loaded`]).

use std::fmt;

use super::histogram::Histogram;
use super::orient::PatientFrame;
use super::{ScalarType, Volume};

/// The window of the CT transfer-function presets (`transfer_functions/ct-*.json`), in
/// Hounsfield units: air (−1000) maps to 0, dense bone (2000) to 1.
pub const CT_WINDOW: [f32; 2] = [-1000.0, 2000.0];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Procedural,
    Raw,
    Nrrd,
    MetaImage,
    Nifti,
    Dicom,
    Vti,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Procedural => "procedural",
            Format::Raw => "raw",
            Format::Nrrd => "NRRD",
            Format::MetaImage => "MetaImage",
            Format::Nifti => "NIfTI",
            Format::Dicom => "DICOM series",
            Format::Vti => "VTK ImageData",
        })
    }
}

/// Physical units of the sample values, when the file says.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Units {
    #[default]
    Unknown,
    /// CT attenuation, after any rescale slope/intercept.
    Hounsfield,
    Named(String),
}

impl fmt::Display for Units {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Units::Unknown => f.write_str("unknown"),
            Units::Hounsfield => f.write_str("Hounsfield units"),
            Units::Named(name) => f.write_str(name),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct VolumeMeta {
    pub format: Format,
    /// Scalar type as stored in the file (the samples are always f32 in memory).
    pub scalar: Option<ScalarType>,
    pub units: Units,
    /// Modality as written by the file (CT, MR, ...).
    pub modality: Option<String>,
    /// Things worth telling a user about the load (ignored fields, corrections applied).
    pub notes: Vec<String>,
    /// Where the voxels lie in the patient, when the file says (see [`super::orient`]).
    pub patient: Option<PatientFrame>,
}

impl VolumeMeta {
    pub fn new(format: Format, scalar: Option<ScalarType>) -> VolumeMeta {
        VolumeMeta {
            format,
            scalar,
            units: Units::Unknown,
            modality: None,
            notes: Vec::new(),
            patient: None,
        }
    }

    /// Sets the modality; CT data is in Hounsfield units.
    pub fn with_modality(mut self, modality: &str) -> VolumeMeta {
        let modality = modality.trim();
        if modality.is_empty() {
            return self;
        }
        if modality.eq_ignore_ascii_case("CT") || modality.eq_ignore_ascii_case("MET_MOD_CT") {
            self.units = Units::Hounsfield;
        }
        self.modality = Some(modality.to_string());
        self
    }
}

/// A loaded volume with what its file said about it and its histogram.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub volume: Volume,
    pub meta: VolumeMeta,
    pub histogram: Histogram,
}

impl Loaded {
    pub fn new(volume: Volume, meta: VolumeMeta) -> Loaded {
        let histogram = Histogram::new(&volume.data, volume.value_range);
        Loaded {
            volume,
            meta,
            histogram,
        }
    }

    /// The window used when a scene gives none: [`CT_WINDOW`] for data in Hounsfield units,
    /// the value range for procedural volumes (their transfer functions are written for it),
    /// otherwise the histogram's 0.5–99.5 percentile range.
    pub fn default_window(&self) -> [f32; 2] {
        match (&self.meta.units, self.meta.format) {
            (Units::Hounsfield, _) => CT_WINDOW,
            (_, Format::Procedural) => self.volume.value_range,
            _ => self.histogram.percentile_window(),
        }
    }

    /// Short name of the rule [`Loaded::default_window`] followed.
    pub fn window_rule(&self) -> &'static str {
        match (&self.meta.units, self.meta.format) {
            (Units::Hounsfield, _) => "CT window in Hounsfield units",
            (_, Format::Procedural) => "value range",
            _ => "0.5–99.5 percentiles of the histogram",
        }
    }
}
