//! `caustica animate`: its options, how they become an [`Animation`] (built from any input
//! `render` takes, or read from an animation file), and the run: render, then encode or check.

use std::path::{Path, PathBuf};

use caustica::animate::frames::{self, frames_dir, is_mp4, parse_range, parse_shard, runs};
use caustica::animate::paths::resolve_scene;
use caustica::animate::{
    encode_mp4, is_animation_file, load_key_file, render_frames, AnimateError, Animation, FrameFormat, Keys, Selection,
    TimeMode, Tracks, TransferKey, ANIMATION_FILE,
};
use caustica::gpu::{Context, ContextDesc, DeviceSelector};
use caustica::input::{fit_to_device, parse_size, InputArgs, Prepared};
use caustica::render::Renderer;
use caustica::scene::{ClipPlane, PreparedScene};

/// Values of a track given on the command line: `A,B[,C...]`, spread evenly over the animation.
#[derive(Clone, Debug, PartialEq)]
pub struct Values(pub Vec<f64>);

fn parse_values(s: &str) -> Result<Values, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    if v.len() < 2 || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "'{s}': expected two or more finite values FROM,TO[,...], e.g. 0,360"
        ));
    }
    Ok(Values(v))
}

fn parse_fps(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(f) if f.is_finite() && f > 0.0 && f <= 1000.0 => Ok(f),
        _ => Err(format!("'{s}': expected frames per second, a number in (0, 1000]")),
    }
}

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) && v.iter().any(|c| *c != 0.0) => Ok([x, y, z]),
        _ => Err(format!("'{s}': expected a finite non-zero vector X,Y,Z, e.g. 0,0,1")),
    }
}

/// Which frames of a time series: all, or `A..B` (both included).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SeriesRange {
    All,
    Frames(u32, u32),
}

fn parse_series(s: &str) -> Result<SeriesRange, String> {
    if s == "all" {
        Ok(SeriesRange::All)
    } else {
        parse_range(s).map(|(a, b)| SeriesRange::Frames(a, b))
    }
}

/// `caustica animate` options.
#[derive(clap::Args, Debug)]
pub struct AnimateArgs {
    /// INPUT is anything `render` takes, or an animation file (.toml with a `frames` key)
    /// that holds the tracks.
    #[command(flatten)]
    pub input: InputArgs,
    /// A folder for the numbered frames, or FILE.mp4 (frames in FILE_frames/, encoded by ffmpeg).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Report the missing and stale frames of a frame folder and exit (code 1 when incomplete).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["output", "input", "scene", "save_animation", "shard", "range"])]
    pub check: Option<PathBuf>,
    /// Write the animation (scene and tracks, TOML) to this file; without -o nothing is rendered.
    #[arg(long, value_name = "FILE.toml")]
    pub save_animation: Option<PathBuf>,
    /// Number of frames [default: 60, or the frames of --time-series].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,
    /// Frames per second of the MP4 and of the animation file [default: 30].
    #[arg(long, value_parser = parse_fps)]
    pub fps: Option<f64>,
    /// Frame size, WIDTHxHEIGHT [default: 512x512].
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Loop: frame k is at time k/frames, so the last frame leads back to the first.
    #[arg(long = "loop")]
    pub looped: bool,
    /// A full turn of the camera around the volume from the scene's yaw, looped.
    #[arg(long, conflicts_with = "yaw")]
    pub turntable: bool,
    /// Camera yaw in degrees, FROM,TO[,...] (values spread evenly over the animation).
    #[arg(long, value_parser = parse_values, allow_hyphen_values = true)]
    pub yaw: Option<Values>,
    /// Camera pitch in degrees, FROM,TO[,...].
    #[arg(long, value_parser = parse_values, allow_hyphen_values = true)]
    pub pitch: Option<Values>,
    /// Magnification relative to the scene's camera, FROM,TO[,...] (1 = the scene's view;
    /// interpolated geometrically).
    #[arg(long, value_parser = parse_values)]
    pub zoom: Option<Values>,
    /// Light angle off the view direction in degrees (0..89), FROM,TO[,...].
    #[arg(long, value_parser = parse_values)]
    pub light_polar: Option<Values>,
    /// Light angle around the view direction in degrees, FROM,TO[,...].
    #[arg(long, value_parser = parse_values, allow_hyphen_values = true)]
    pub light_azimuth: Option<Values>,
    /// Clip-plane offset from the centre in bounding radii, FROM,TO[,...] (sweeps the plane).
    #[arg(long, value_parser = parse_values, allow_hyphen_values = true)]
    pub clip: Option<Values>,
    /// Clip-plane normal X,Y,Z in volume axes [default: the scene's, else 0,0,1].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub clip_normal: Option<[f32; 3]>,
    /// Time series: step through its frames, `all` or FIRST..LAST (both included).
    #[arg(long, value_parser = parse_series)]
    pub time_series: Option<SeriesRange>,
    /// Time series between its frames: hold the nearest frame, or interpolate two.
    #[arg(long, value_enum, default_value_t = TimeMode::Hold)]
    pub time_mode: TimeMode,
    /// Transfer-function keys: two or more transfer-function or scene files, comma separated,
    /// spread evenly over the animation and interpolated point by point.
    #[arg(long, value_delimiter = ',')]
    pub transfer_keys: Vec<PathBuf>,
    /// Frame format in a folder: png (8-bit sRGB) or exr (linear float).
    #[arg(long, value_enum, default_value_t = FrameFormat::Png)]
    pub format: FrameFormat,
    /// Render shard INDEX of COUNT: the frames k with k mod COUNT = INDEX (INDEX from 0).
    #[arg(long, value_parser = parse_shard, value_name = "INDEX/COUNT")]
    pub shard: Option<(u32, u32)>,
    /// Render frames FIRST..LAST only (both included, from 0).
    #[arg(long, value_parser = parse_range, value_name = "FIRST..LAST")]
    pub range: Option<(u32, u32)>,
    /// Vulkan device: index or name substring (see `caustica devices`).
    #[arg(long, default_value = "auto")]
    pub device: String,
}

impl AnimateArgs {
    /// The track options given (they conflict with an animation file).
    fn track_options(&self) -> Vec<&'static str> {
        let given = [
            (self.turntable, "--turntable"),
            (self.yaw.is_some(), "--yaw"),
            (self.pitch.is_some(), "--pitch"),
            (self.zoom.is_some(), "--zoom"),
            (self.light_polar.is_some(), "--light-polar"),
            (self.light_azimuth.is_some(), "--light-azimuth"),
            (self.clip.is_some(), "--clip"),
            (self.clip_normal.is_some(), "--clip-normal"),
            (self.time_series.is_some(), "--time-series"),
            (!self.transfer_keys.is_empty(), "--transfer-keys"),
            (self.input.transfer.is_some(), "--transfer"),
            (self.input.window.is_some(), "--window"),
            (self.input.time.is_some(), "--time"),
            (self.input.raw_dims.is_some(), "--raw-dims"),
        ];
        given.into_iter().filter(|(on, _)| *on).map(|(_, name)| name).collect()
    }

    /// The animation file given as INPUT, with --frames, --fps, --size, --loop and the
    /// quality overrides applied.
    fn animation_of_file(&self, path: &Path) -> Result<Animation, AnimateError> {
        let conflicting = self.track_options();
        if !conflicting.is_empty() {
            return Err(AnimateError::Usage(format!(
                "{} cannot change the animation file {}: edit its tracks, or give a scene or volume instead",
                conflicting.join(", "),
                path.display()
            )));
        }
        let mut a = Animation::load(path)?;
        self.apply_settings(&mut a);
        let q = &mut a.scene.quality;
        if let Some(d) = self.input.sample_distance {
            q.sample_distance = d;
        }
        if let Some(p) = self.input.precision {
            q.precision = p;
        }
        if let Some(r) = self.input.resolution {
            a.scene.set_builtin_resolution(r);
        }
        a.validate()?;
        Ok(a)
    }

    fn apply_settings(&self, a: &mut Animation) {
        if let Some(n) = self.frames {
            a.frames = n;
        }
        if let Some(f) = self.fps {
            a.fps = f;
        }
        if let Some((w, h)) = self.size {
            a.size = [w, h];
        }
        a.looped |= self.looped;
    }

    /// An animation of the input scene with the tracks of the options; also the loaded scene.
    fn animation_of_input(&self) -> Result<(Animation, PreparedScene), AnimateError> {
        let Prepared { prepared, notes } = self.input.prepare()?;
        for note in notes {
            eprintln!("{note}");
        }
        let mut scene = prepared.scene.clone();
        resolve_scene(&mut scene, Path::new(""))?;
        let spread = |v: &Option<Values>| -> Keys {
            v.as_ref().map_or(Vec::new(), |Values(v)| {
                let n = (v.len() - 1) as f64;
                v.iter().enumerate().map(|(i, x)| [i as f64 / n, *x]).collect()
            })
        };
        let mut tracks = Tracks::<TransferKey>::default();
        tracks.camera.yaw_deg = spread(&self.yaw);
        let y0 = scene.camera.yaw_deg as f64;
        if self.turntable {
            tracks.camera.yaw_deg = vec![[0.0, y0], [1.0, y0 + 360.0]];
        }
        tracks.camera.pitch_deg = spread(&self.pitch);
        tracks.camera.magnification = spread(&self.zoom);
        tracks.light.polar_deg = spread(&self.light_polar);
        tracks.light.azimuth_deg = spread(&self.light_azimuth);
        tracks.clip.offset = spread(&self.clip);
        if self.clip.is_some() || self.clip_normal.is_some() {
            let normal = self
                .clip_normal
                .or(scene.clip.as_ref().map(|c| c.normal))
                .unwrap_or([0.0, 0.0, 1.0]);
            let offset = tracks.clip.offset.first().map_or(0.0, |k| k[1] as f32);
            let clip = scene.clip.get_or_insert(ClipPlane { normal, offset });
            clip.normal = normal;
        }
        let mut frames = 60;
        if let Some(range) = self.time_series {
            let len = match scene.volume.series()? {
                Some(s) => s.len() as u32,
                None => {
                    return Err(AnimateError::Usage(
                        "--time-series needs a time-series input (a quoted pattern such as 'sim/t*.nrrd', or a scene with kind = \"series\")".into(),
                    ))
                }
            };
            let (a, b) = match range {
                SeriesRange::All => (0, len - 1),
                SeriesRange::Frames(a, b) if b < len => (a, b),
                SeriesRange::Frames(a, b) => {
                    return Err(AnimateError::Usage(format!(
                        "--time-series {a}..{b}: the series has {len} frames (0..{})",
                        len - 1
                    )))
                }
            };
            tracks.time.frame = vec![[0.0, a as f64], [1.0, b as f64]];
            tracks.time.mode = self.time_mode;
            frames = b - a + 1;
        }
        match self.transfer_keys.len() {
            0 => {}
            1 => {
                return Err(AnimateError::Usage(
                    "--transfer-keys needs two or more files (comma separated)".into(),
                ))
            }
            n => {
                for (i, path) in self.transfer_keys.iter().enumerate() {
                    let (functions, window) = load_key_file(path)?;
                    tracks.transfer.push(TransferKey {
                        at: i as f64 / (n - 1) as f64,
                        window,
                        functions,
                    });
                }
            }
        }
        let size = self.size.unwrap_or((512, 512));
        let mut a = Animation {
            frames,
            fps: 30.0,
            size: [size.0, size.1],
            looped: self.turntable,
            tracks,
            scene,
        };
        self.apply_settings(&mut a);
        a.validate()?;
        Ok((a, prepared))
    }
}

/// Runs `caustica animate`.
pub fn animate(args: &AnimateArgs) -> Result<(), AnimateError> {
    if let Some(dir) = &args.check {
        return check(dir);
    }
    let file = args.input.input.as_deref().filter(|p| is_animation_file(p));
    let (animation, prepared) = match file {
        Some(path) => (args.animation_of_file(path)?, None),
        None => {
            let (a, p) = args.animation_of_input()?;
            (a, Some(p))
        }
    };
    if let Some(path) = &args.save_animation {
        animation.save(path)?;
        eprintln!("wrote {} ({} frames)", path.display(), animation.frames);
    }
    let Some(output) = &args.output else {
        if args.save_animation.is_some() {
            return Ok(());
        }
        return Err(AnimateError::Usage(
            "give -o DIR (numbered frames) or -o FILE.mp4, or --save-animation FILE.toml".into(),
        ));
    };
    let mp4 = is_mp4(output);
    if mp4 && args.format == FrameFormat::Exr {
        return Err(AnimateError::Usage(
            "an MP4 is encoded from PNG frames: leave out --format exr, or give a folder".into(),
        ));
    }
    let selection = Selection {
        range: args.range,
        shard: args.shard,
    };
    let selected = selection.frames(animation.frames)?;
    let dir = frames_dir(output);
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    let mut prepared = match prepared {
        Some(mut p) => {
            p.scene = animation.scene.clone();
            p
        }
        None => PreparedScene::load(&animation.scene)?,
    };
    let allow = !args.input.no_downsample;
    fit_to_device(&mut prepared, &ctx, allow, false)?;
    let mut renderer = Renderer::new(ctx)?;
    let s = render_frames(
        &mut renderer,
        prepared,
        &animation,
        &dir,
        args.format,
        selection,
        allow,
        true,
    )?;
    if s.rendered > 0 {
        eprintln!(
            "rendered {} of {} frames in {:.1} s ({:.2} s per frame, GPU {:.0} ms per frame); {} already present; frames in {}",
            s.rendered,
            selected.len(),
            s.render_s,
            s.render_s / s.rendered as f64,
            s.gpu_ms / s.rendered as f64,
            s.skipped,
            dir.display()
        );
    } else {
        eprintln!(
            "all {} frames of this run are present in {}; nothing to render",
            s.selected,
            dir.display()
        );
    }
    if mp4 {
        if !s.complete {
            eprintln!(
                "not encoding {}: this run renders part of the frames (--shard/--range); once all parts are done, \
                 `caustica animate {} -o {}` encodes them",
                output.display(),
                dir.join(ANIMATION_FILE).display(),
                output.display()
            );
            return Ok(());
        }
        encode_mp4(&dir, animation.frames as usize, animation.fps, output)?;
        eprintln!(
            "wrote {} ({} frames at {} fps)",
            output.display(),
            animation.frames,
            animation.fps
        );
    }
    Ok(())
}

/// `--check DIR`: prints what is present, missing and stale; an error when incomplete.
fn check(dir: &Path) -> Result<(), AnimateError> {
    let r = frames::check(dir)?;
    println!("{}: {} of {} frames present", dir.display(), r.present.len(), r.total);
    if !r.missing.is_empty() {
        println!("missing: {}", runs(&r.missing));
    }
    if !r.stale.is_empty() {
        println!(
            "stale: {} (showing another version of the animation, or damaged)",
            runs(&r.stale)
        );
    }
    if r.animation_changed {
        println!("{ANIMATION_FILE} does not match the manifest's hash (edited after the frames were rendered?)");
    }
    if r.complete() {
        println!("complete");
        return Ok(());
    }
    Err(AnimateError::Incomplete {
        dir: dir.to_path_buf(),
        animation: dir.join(ANIMATION_FILE),
        missing: r.missing.len(),
        stale: r.stale.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_lists_need_two_finite_values() {
        assert_eq!(parse_values("0,360"), Ok(Values(vec![0.0, 360.0])));
        assert_eq!(parse_values("-10, 0 ,10"), Ok(Values(vec![-10.0, 0.0, 10.0])));
        for bad in ["5", "0,x", "0,inf", ""] {
            assert!(parse_values(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_series("all"), Ok(SeriesRange::All));
        assert_eq!(parse_series("2..4"), Ok(SeriesRange::Frames(2, 4)));
        assert!(parse_series("4..2").is_err());
        assert!(parse_vec3("0,0,0").is_err());
        assert!(parse_fps("0").is_err());
    }
}
