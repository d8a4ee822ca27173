//! caustica: interactive volume rendering with refraction, soft shadows and caustics, after
//! Magnus & Bruckner, "Interactive Dynamic Volume Illumination with Refraction and Caustics"
//! (IEEE TVCG 2017).
//!
//! Data flows one way: **file → [`volume::Volume`] → [`scene::Scene`] → [`render::Renderer`] → image**.
//!
//! | module | what it holds |
//! |---|---|
//! | [`volume`] | `Volume` (dims, spacing, samples, value range), one file per format loader (NRRD, MetaImage, NIfTI, DICOM, VTK, raw), histogram and metadata ([`volume::Loaded`]), resampling, time series, procedural scenes |
//! | [`transfer`] | the four transfer functions (α, c, η, m), their JSON format, importers (ParaView, Inviwo, Slicer), defaults from a histogram, pre-integration |
//! | [`scene`] | everything one image depends on; TOML scene files; built-in scenes; the GPU-free pieces both renderers share: view setup and camera, light direction, the prepared scene (data loaded), environment maps, the rendered image |
//! | [`gpu`] | a thin documented layer over ash: device, memory, images, pipelines, naga shaders |
//! | [`input`] | what `render` and `view` read (scene, volume file, series, raw, built-in) and their shared options → a loaded scene |
//! | [`render`] | the method on top of `gpu`: plane sweep, propagation passes, scene textures; `Features` |
//! | [`reference`] | CPU renderers used to check the GPU one; the independent reference (f64, photons), which uses only `scene`, `volume` and `transfer` |
//! | [`bench`] | the speed–accuracy sweep: GPU frame times and errors against the reference |
//! | [`animate`] | frame sequences: tracks over a base scene, sharded and resumable runs, manifest, MP4 |
//! | [`app`] | the interactive viewer (`caustica view`): winit window, egui panel, progressive frames |
//!
//! Each layer only calls the one below it: `main`, `animate` and `app` use `render` + `scene`; `render` uses `gpu`;
//! nothing in `gpu` knows what a volume is.

mod exit_class;
pub use exit_class::{Classify, ExitClass};

pub mod animate;
pub mod app;
pub mod bench;
// The one module with `unsafe` code (Cargo.toml denies it elsewhere): the documented layer
// over ash, whose contract is in its module doc.
#[allow(unsafe_code)]
pub mod gpu;
pub mod input;
pub mod reference;
pub mod render;
pub mod scene;
pub mod transfer;
pub mod volume;
