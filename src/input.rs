//! What `caustica render` and `caustica view` read: a scene file, a volume file, a DICOM
//! directory, a time-series pattern, raw data or a built-in scene, with the overrides both
//! commands accept (`--transfer`, `--window`, `--time`, ...). Both build their scene here, so
//! a bare volume file looks the same in the window as in the offscreen render.

use std::path::{Path, PathBuf};

use crate::gpu::Context;
use crate::scene::{
    builtin, Camera, Precision, PrepareError, PreparedScene, Scene, SceneError, TransferSource, View, VolumeSource,
    VIEW_NAMES,
};
use crate::transfer::{TransferError, TransferFunctions};
use crate::volume::{Endian, RawDesc, ScalarType, VolumeError};

#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("give a scene file, a volume file or --scene NAME (see `caustica scenes`)")]
    Missing,
    #[error("{0}")]
    Option(String),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Volume(#[from] VolumeError),
    #[error(transparent)]
    Transfer(#[from] TransferError),
    #[error(transparent)]
    Prepare(#[from] PrepareError),
}

impl crate::Classify for InputError {
    fn exit_class(&self) -> crate::ExitClass {
        match self {
            InputError::Missing | InputError::Option(_) => crate::ExitClass::Input,
            InputError::Scene(e) => e.exit_class(),
            InputError::Volume(e) => e.exit_class(),
            InputError::Transfer(e) => e.exit_class(),
            InputError::Prepare(e) => e.exit_class(),
        }
    }
}

/// The input options shared by `caustica render` and `caustica view`.
#[derive(clap::Args, Clone, Debug)]
pub struct InputArgs {
    /// A scene file (.toml), a volume file (see README, "Volume input"), a DICOM directory,
    /// a time-series pattern with '*' (quote it), or raw data with --raw-dims.
    pub input: Option<PathBuf>,
    /// Use a built-in scene instead (see `caustica scenes`).
    #[arg(long, conflicts_with = "input")]
    pub scene: Option<String>,
    /// Override the scene's sample distance (multiple of the smallest voxel size).
    #[arg(long)]
    pub sample_distance: Option<f32>,
    /// Override the storage precision of the light, colour and medium buffers: f16 or f32.
    #[arg(long, value_parser = parse_precision)]
    pub precision: Option<Precision>,
    /// Override the resolution of a built-in scene's volume.
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Transfer functions replacing those of the scene: caustica JSON, ParaView colour map
    /// JSON, Inviwo .itf or 3D Slicer presets.xml (FILE#NAME picks one preset).
    #[arg(long)]
    pub transfer: Option<PathBuf>,
    /// Data window mapped onto the transfer functions, as LOW,HIGH in data units.
    #[arg(long, value_parser = parse_window)]
    pub window: Option<[f32; 2]>,
    /// Time series: the frame to show (index, rounded to the nearest).
    #[arg(long)]
    pub time: Option<f32>,
    /// DICOM: the series to load when the folder holds several (its number in
    /// `caustica info DIR`, or its UID).
    #[arg(long)]
    pub series: Option<String>,
    /// Look from one side of the patient: anterior, posterior, left, right, superior or
    /// inferior (patient data opens in the anterior view with the head up).
    #[arg(long, value_parser = parse_view)]
    pub view: Option<View>,
    /// Fail instead of downsampling a volume that exceeds the device's 3D-texture limits.
    #[arg(long)]
    pub no_downsample: bool,
    /// Raw volume: dims as XxYxZ.
    #[arg(long, value_parser = parse_dims)]
    pub raw_dims: Option<[usize; 3]>,
    /// Raw volume: scalar type (u8, i8, u16, i16, u32, i32, f32, f64).
    #[arg(long, default_value = "u8")]
    pub raw_type: String,
    /// Raw volume: byte order.
    #[arg(long, default_value = "little")]
    pub raw_endian: String,
    /// Raw volume: voxel spacing as X,Y,Z.
    #[arg(long, value_parser = parse_spacing)]
    pub raw_spacing: Option<[f32; 3]>,
    /// Raw volume: bytes to skip at the start of the file.
    #[arg(long, default_value_t = 0)]
    pub raw_header: u64,
}

/// An image or window size, WIDTHxHEIGHT, each at least 1.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WIDTHxHEIGHT, e.g. 512x512")?;
    let p = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("'{v}': {e}"));
    let (w, h) = (p(w)?, p(h)?);
    if w == 0 || h == 0 {
        return Err("width and height must be at least 1".into());
    }
    Ok((w, h))
}

fn parse_dims(s: &str) -> Result<[usize; 3], String> {
    let v: Vec<usize> = s
        .split(['x', 'X'])
        .map(|p| p.trim().parse::<usize>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    v.try_into().map_err(|_| "expected XxYxZ, e.g. 256x256x108".to_string())
}

fn parse_spacing(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    v.try_into().map_err(|_| "expected X,Y,Z, e.g. 0.5,0.5,2".to_string())
}

fn parse_view(s: &str) -> Result<View, String> {
    View::parse(s).ok_or_else(|| format!("'{s}': expected one of {VIEW_NAMES}"))
}

fn parse_precision(s: &str) -> Result<Precision, String> {
    Precision::parse(s).ok_or_else(|| format!("'{s}': expected f16 or f32"))
}

fn parse_window(s: &str) -> Result<[f32; 2], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [lo, hi] if lo.is_finite() && hi.is_finite() && hi > lo => Ok([lo, hi]),
        _ => Err("expected LOW,HIGH with LOW < HIGH, e.g. -1000,2000".to_string()),
    }
}

/// A scene loaded for display, and what the user should be told about it (frame chosen,
/// transfer functions picked).
pub struct Prepared {
    pub prepared: PreparedScene,
    pub notes: Vec<String>,
}

impl InputArgs {
    /// True when the input is a bare volume file (no scene, no --transfer): its transfer
    /// functions then come from its histogram.
    pub fn wants_default_transfer(&self) -> bool {
        let scene_file = self.input.as_ref().is_some_and(|p| is_scene_file(p));
        self.scene.is_none() && !scene_file && self.transfer.is_none()
    }

    /// The scene with every override applied; `notes` receives the frame chosen by --time.
    pub fn load_scene(&self, notes: &mut Vec<String>) -> Result<Scene, InputError> {
        let mut scene = match (&self.scene, &self.input) {
            (Some(name), _) => builtin(name)?.scene,
            (None, Some(path)) if is_scene_file(path) => Scene::load(path)?,
            (None, Some(path)) => self.scene_for_volume(path)?,
            (None, None) => return Err(InputError::Missing),
        };
        if let Some(path) = &self.transfer {
            let imported = crate::transfer::load_any(path)?;
            scene.transfer = TransferSource::Inline(imported.tf);
            if imported.domain.is_some() {
                scene.window = imported.domain;
            }
        }
        if let Some(window) = self.window {
            scene.window = Some(window);
        }
        if let Some(t) = self.time {
            notes.push(select_time(&mut scene, t)?);
        }
        if let Some(wanted) = &self.series {
            match &mut scene.volume {
                VolumeSource::File { series, .. } => *series = Some(wanted.clone()),
                _ => {
                    return Err(InputError::Option(
                        "--series needs a DICOM folder, file or DICOMDIR".into(),
                    ))
                }
            }
        }
        if let Some(d) = self.sample_distance {
            scene.quality.sample_distance = d;
        }
        if let Some(p) = self.precision {
            scene.quality.precision = p;
        }
        if let Some(r) = self.resolution {
            scene.set_builtin_resolution(r);
        }
        scene.validate()?;
        Ok(scene)
    }

    /// Loads the scene's data. A bare volume file gets the default transfer functions of its
    /// histogram; they and the window they were made for are then written into the scene, so
    /// that the scene alone (saved by the viewer, or the viewer's editors) reproduces them.
    pub fn prepare(&self) -> Result<Prepared, InputError> {
        let mut notes = Vec::new();
        let scene = self.load_scene(&mut notes)?;
        let mut prepared = PreparedScene::load(&scene)?;
        let patient = prepared.volume_info.meta.patient.clone();
        let residual = patient
            .as_ref()
            .map_or(glam::Mat3::IDENTITY, |p| p.display_from_world());
        let bare_file = self.scene.is_none() && !self.input.as_ref().is_some_and(|p| is_scene_file(p));
        if let Some(view) = self.view {
            prepared.scene.camera.set_view(view, residual);
            notes.push(format!("view: {view}"));
        } else if bare_file && patient.is_some() {
            // Patient data: the anterior view with the head up, as in 3D Slicer.
            prepared.scene.camera = Camera::named(View::Anterior, residual);
            notes.push("view: anterior (patient data shown in anatomical orientation)".into());
        }
        if self.wants_default_transfer() {
            prepared.use_default_transfer();
            let window = prepared.window();
            prepared.scene.window = Some(window);
            prepared.scene.transfer = TransferSource::Inline(prepared.tf.clone());
            notes.push(format!(
                "transfer functions: {} (window {window:?})",
                prepared.tf.name.as_deref().unwrap_or("automatic"),
            ));
        }
        Ok(Prepared { prepared, notes })
    }

    /// A scene for a bare volume file: default camera, light and transfer functions.
    fn scene_for_volume(&self, path: &Path) -> Result<Scene, InputError> {
        let volume = match self.raw_dims {
            Some(dims) => VolumeSource::Raw(RawDesc {
                path: path.to_path_buf(),
                dims,
                scalar: self.raw_type.parse::<ScalarType>()?,
                endian: match self.raw_endian.as_str() {
                    "little" => Endian::Little,
                    "big" => Endian::Big,
                    other => {
                        return Err(InputError::Option(format!(
                            "--raw-endian '{other}': expected little or big"
                        )))
                    }
                },
                spacing: self.raw_spacing.unwrap_or([1.0; 3]),
                header_bytes: self.raw_header,
            }),
            None if path.to_string_lossy().contains('*') => VolumeSource::Series {
                files: Vec::new(),
                pattern: Some(path.to_path_buf()),
                frame: 0,
            },
            None => VolumeSource::File {
                path: path.to_path_buf(),
                series: None,
            },
        };
        Ok(Scene {
            volume,
            eta_volume: None,
            window: None,
            transfer: TransferSource::Inline(TransferFunctions::default()),
            camera: Default::default(),
            light: Default::default(),
            shading: Default::default(),
            clip: None,
            environment: Default::default(),
            quality: Default::default(),
        })
    }
}

fn is_scene_file(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "toml")
}

/// Applies `--time T` to a time-series volume; returns the line telling which frame it is.
fn select_time(scene: &mut Scene, t: f32) -> Result<String, InputError> {
    match scene.volume.series()? {
        Some(series) => {
            let frame = series.frame_at(t)?;
            scene.volume.set_frame(frame);
            Ok(format!(
                "frame {frame} of {}: {}",
                series.len(),
                series.frames[frame].display()
            ))
        }
        None => Err(InputError::Option(
            "--time needs a time series (a file pattern with '*' or kind = \"series\" in the scene)".into(),
        )),
    }
}

/// Downsamples `prepared` to the limits of `ctx`'s device (see
/// [`PreparedScene::fit_to_device_keeping`]; `keep_half_level` for renders that keep the
/// volumes' half-resolution level, the viewer's). Volume textures may use half the
/// device-local memory; the rest is state and tables.
pub fn fit_to_device(
    prepared: &mut PreparedScene,
    ctx: &Context,
    allow: bool,
    keep_half_level: bool,
) -> Result<Option<[usize; 3]>, PrepareError> {
    prepared.fit_to_device_keeping(
        ctx.info.max_image_3d,
        ctx.device_local_bytes() / 2,
        allow,
        keep_half_level,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::nrrd::write_nrrd;
    use crate::volume::Volume;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        input: InputArgs,
    }

    fn args(list: &[&str]) -> InputArgs {
        Cli::try_parse_from(std::iter::once("caustica").chain(list.iter().copied()))
            .expect("valid options")
            .input
    }

    struct Scratch(PathBuf);

    impl Scratch {
        fn new(tag: &str) -> Scratch {
            let dir = std::env::temp_dir().join(format!("caustica-input-{tag}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            Scratch(dir)
        }

        fn s(&self, name: &str) -> String {
            self.0.join(name).to_str().unwrap().to_string()
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// A 12³ volume of values `offset + 0..50` in the data's own units and one outlier at
    /// `offset + 10000`, which the percentile window leaves out (1 voxel of 1728 < 0.5 %).
    fn write_volume(path: &str, offset: f32) {
        let n = 12;
        let data = (0..n * n * n)
            .map(|i| offset + if i == 0 { 10000.0 } else { (i % 50) as f32 })
            .collect();
        let v = Volume::new([n, n, n], [1.0; 3], data).unwrap();
        write_nrrd(Path::new(path), &v, false).unwrap();
    }

    /// A bare volume file gets the transfer functions of its histogram, and the scene carries
    /// them and their window: rendering the scene alone gives the same functions and window.
    #[test]
    fn bare_file_gets_default_transfer_and_window_in_the_scene() {
        let dir = Scratch::new("bare");
        let file = dir.s("v.nrrd");
        write_volume(&file, 0.0);
        let a = args(&[&file]);
        assert!(a.wants_default_transfer());
        let Prepared { prepared, notes } = a.prepare().unwrap();
        let plain = PreparedScene::load(&a.load_scene(&mut Vec::new()).unwrap()).unwrap();
        let window = plain.volume_info.default_window;
        assert_eq!(prepared.scene.window, Some(window));
        assert_ne!(
            window, plain.volume.value_range,
            "a histogram window, not the value range"
        );
        let expected = crate::transfer::default_for(&plain.volume_info.meta, &plain.volume_info.histogram, window);
        assert_ne!(expected, TransferFunctions::default());
        assert_eq!(prepared.tf, expected);
        assert_eq!(prepared.scene.transfer, TransferSource::Inline(expected.clone()));
        // The scene alone reproduces the view (what a saved scene is rendered from).
        let again = PreparedScene::load(&prepared.scene).unwrap();
        assert_eq!((again.window(), again.tf), (window, expected));
        assert!(notes.iter().any(|n| n.starts_with("transfer functions:")), "{notes:?}");

        // --window moves the window the defaults are made for.
        let narrow = args(&[&file, "--window", "0,100"]).prepare().unwrap().prepared;
        assert_eq!(narrow.scene.window, Some([0.0, 100.0]));
        assert_eq!(
            narrow.tf,
            crate::transfer::default_for(&plain.volume_info.meta, &plain.volume_info.histogram, [0.0, 100.0])
        );
    }

    /// An imported colour map replaces the defaults and its data-unit domain becomes the
    /// window; --window still wins over it.
    #[test]
    fn transfer_import_sets_the_window() {
        let dir = Scratch::new("import");
        let file = dir.s("v.nrrd");
        write_volume(&file, 0.0);
        let map = dir.s("map.json");
        std::fs::write(
            &map,
            r#"[{"Name": "A", "RGBPoints": [-1000, 0, 0, 0, 1000, 1, 0.5, 0], "Points": [-1000, 0, 0.5, 0, 1000, 1, 0.5, 0]}]"#,
        )
        .unwrap();
        let a = args(&[&file, "--transfer", &map]);
        assert!(!a.wants_default_transfer());
        let prepared = a.prepare().unwrap().prepared;
        let imported = crate::transfer::load_any(Path::new(&map)).unwrap();
        assert_eq!(imported.domain, Some([-1000.0, 1000.0]));
        assert_eq!(prepared.scene.window, imported.domain);
        assert_eq!(prepared.window(), [-1000.0, 1000.0]);
        assert_eq!(prepared.tf, imported.tf);
        let windowed = args(&[&file, "--transfer", &map, "--window", "5,50"])
            .prepare()
            .unwrap();
        assert_eq!(windowed.prepared.window(), [5.0, 50.0]);
    }

    /// --time picks a frame of a pattern; its defaults come from that frame's histogram.
    #[test]
    fn time_selects_a_frame_and_needs_a_series() {
        let dir = Scratch::new("series");
        for (k, offset) in [(0, 0.0), (1, 5000.0), (2, -3000.0)] {
            write_volume(&dir.s(&format!("t{k}.nrrd")), offset);
        }
        let pattern = dir.s("t*.nrrd");
        let Prepared { prepared, notes } = args(&[&pattern, "--time", "1.2"]).prepare().unwrap();
        assert!(matches!(prepared.scene.volume, VolumeSource::Series { frame: 1, .. }));
        assert!(
            notes[0].starts_with("frame 1 of 3: ") && notes[0].ends_with("t1.nrrd"),
            "{notes:?}"
        );
        let w = prepared.scene.window.unwrap();
        assert!(w[0] >= 5000.0 && w[1] <= 6000.0, "window {w:?} is frame 1's");
        assert!(
            args(&[&pattern, "--time", "3"]).prepare().is_err(),
            "past the last frame"
        );
        let single = args(&[&dir.s("t0.nrrd"), "--time", "0"]).load_scene(&mut Vec::new());
        assert!(matches!(single, Err(InputError::Option(m)) if m.contains("time series")));
    }
}
