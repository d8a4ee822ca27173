//! The render loop: the frames a run selected and does not find present, each rendered by one
//! `Renderer` (textures stay cached while the volume and transfer functions stay the same)
//! and written with its hash. Time-series frames are loaded (and blended) as frames need them.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use super::file::{Animation, ANIMATION_FILE};
use super::frames::{frame_hash, frame_name, present, write_frame, FrameFormat, Manifest, Selection};
use super::tracks::{Blend, FrameSpec};
use super::AnimateError;
use crate::input::fit_to_device;
use crate::render::{RenderRequest, Renderer};
use crate::scene::{PreparedScene, VolumeInfo, VolumeSource};
use crate::volume::series::Series;
use crate::volume::{Loaded, Volume};

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    pub dir: PathBuf,
    /// Frames this run was asked for (after `--shard` and `--range`).
    pub selected: usize,
    /// Of those, already present with the right hash.
    pub skipped: usize,
    pub rendered: usize,
    /// Wall time of the rendered frames (loading, rendering, writing), in seconds.
    pub render_s: f64,
    /// GPU time of the rendered frames (timestamp queries), in milliseconds.
    pub gpu_ms: f64,
    /// True when every frame of the animation is now present.
    pub complete: bool,
}

/// A time-series frame of the volume, as loaded (before fitting to the device).
struct Frame {
    volume: Arc<Volume>,
    info: VolumeInfo,
}

impl Frame {
    fn of(loaded: Loaded) -> Frame {
        Frame {
            info: VolumeInfo {
                default_window: loaded.default_window(),
                meta: loaded.meta,
                histogram: loaded.histogram,
            },
            volume: Arc::new(loaded.volume),
        }
    }
}

/// The series frames an animation shows; keeps the last two loaded ones.
struct SeriesFrames {
    series: Series,
    cache: Vec<(usize, Arc<Frame>)>,
    /// What `prepared` holds now: (frame, blend).
    shown: Option<(usize, Option<(usize, u64)>)>,
}

impl SeriesFrames {
    fn frame(&mut self, k: usize) -> Result<Arc<Frame>, AnimateError> {
        if let Some((_, f)) = self.cache.iter().find(|(i, _)| *i == k) {
            return Ok(f.clone());
        }
        let f = Arc::new(Frame::of(self.series.open_frame(k)?));
        if self.cache.len() >= 2 {
            self.cache.remove(0);
        }
        self.cache.push((k, f.clone()));
        Ok(f)
    }

    /// Puts frame `k` (blended with `blend`) into `prepared`, unless it is there already.
    fn show(
        &mut self,
        prepared: &mut PreparedScene,
        k: usize,
        blend: Option<Blend>,
        allow_downsample: bool,
        renderer: &Renderer,
    ) -> Result<(), AnimateError> {
        let key = (k, blend.map(|b| (b.next_frame, b.weight.to_bits())));
        if self.shown == Some(key) {
            return Ok(());
        }
        let lo = self.frame(k)?;
        let (volume, info) = match blend {
            None => (lo.volume.clone(), lo.info.clone()),
            Some(b) => {
                let hi = self.frame(b.next_frame)?;
                let blended = blend_volumes(&lo.volume, &hi.volume, b.weight)
                    .map_err(|m| AnimateError::Invalid(format!("time series frames {k} and {}: {m}", b.next_frame)))?;
                let f = Frame::of(Loaded::new(blended, lo.info.meta.clone()));
                (f.volume, f.info)
            }
        };
        prepared.volume = volume;
        prepared.volume_info = info;
        fit_to_device(prepared, renderer.context(), allow_downsample, false)?;
        self.shown = Some(key);
        Ok(())
    }
}

/// `(1 − w)·a + w·b` voxel by voxel; the frames must share their grid.
fn blend_volumes(a: &Volume, b: &Volume, w: f64) -> Result<Volume, String> {
    if a.dims != b.dims || a.spacing != b.spacing {
        return Err(format!(
            "cannot interpolate between grids {:?} and {:?} (spacing {:?}, {:?}); use mode = \"hold\"",
            a.dims, b.dims, a.spacing, b.spacing
        ));
    }
    let data = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| ((1.0 - w) * x as f64 + w * y as f64) as f32)
        .collect();
    Volume::new(a.dims, a.spacing, data).map_err(|e| e.to_string())
}

fn series_frame(spec: &FrameSpec) -> usize {
    match spec.scene.volume {
        VolumeSource::Series { frame, .. } => frame,
        _ => 0,
    }
}

fn progress_bar(show: bool, len: usize) -> Option<indicatif::ProgressBar> {
    if !show || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(len as u64);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "frames {pos}/{len} {wide_bar} {elapsed_precise} elapsed, ETA {eta_precise} {msg}",
    ) {
        bar.set_style(style);
    }
    Some(bar)
}

/// Renders the selected frames of `animation` that `dir` does not hold yet (or holds with
/// another hash) into `dir`, and writes the animation and the manifest next to them.
/// `prepared` is the animation's scene, loaded and fitted to the renderer's device.
#[allow(clippy::too_many_arguments)]
pub fn render_frames(
    renderer: &mut Renderer,
    mut prepared: PreparedScene,
    animation: &Animation,
    dir: &Path,
    format: FrameFormat,
    selection: Selection,
    allow_downsample: bool,
    progress: bool,
) -> Result<RunSummary, AnimateError> {
    let specs = animation.frame_specs()?;
    let selected = selection.frames(animation.frames)?;
    std::fs::create_dir_all(dir).map_err(|e| AnimateError::Write {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })?;
    animation.save(&dir.join(ANIMATION_FILE))?;
    let manifest = Manifest::new(animation, &specs, format)?;
    manifest.save(dir)?;
    let expected: Vec<(u32, String)> = selected
        .iter()
        .map(|&k| (k, manifest.frames[k as usize].hash.clone()))
        .collect();
    let done = present(dir, &expected, format);
    let todo: Vec<u32> = selected.iter().copied().filter(|k| !done.contains(k)).collect();

    let mut series = match (&animation.scene.volume, animation.tracks.time.is_empty()) {
        (VolumeSource::Series { .. }, false) => animation.scene.volume.series()?.map(|series| SeriesFrames {
            series,
            cache: Vec::new(),
            shown: None,
        }),
        _ => None,
    };
    let bar = progress_bar(progress, todo.len());
    let started = Instant::now();
    let mut gpu_ms = 0.0;
    let req = RenderRequest::new(animation.size[0], animation.size[1]);
    for &k in &todo {
        let spec = &specs[k as usize];
        let frame_started = Instant::now();
        prepared.scene = spec.scene.clone();
        prepared.tf = spec.scene.transfer_functions()?;
        if let Some(s) = &mut series {
            s.show(
                &mut prepared,
                series_frame(spec),
                spec.blend,
                allow_downsample,
                renderer,
            )?;
        }
        let errors_before = renderer.context().validation_errors();
        let out = renderer.render(&prepared, &req)?;
        let ctx = renderer.context();
        if ctx.validation_errors() > errors_before {
            return Err(AnimateError::Validation {
                frame: k,
                count: ctx.validation_errors() - errors_before,
                first: ctx.validation_messages().last().cloned().unwrap_or_default(),
            });
        }
        let (non_finite, negative) = out.image.count_invalid();
        if non_finite > 0 || negative > 0 {
            return Err(AnimateError::InvalidImage {
                frame: k,
                non_finite,
                negative,
            });
        }
        let hash = frame_hash(spec, animation.size, format);
        write_frame(&dir.join(frame_name(k, format)), &out.image, format, &hash)?;
        gpu_ms += out.stats.gpu_ms;
        if let Some(bar) = &bar {
            bar.set_message(format!("frame {k}: {:.1} s", frame_started.elapsed().as_secs_f64()));
            bar.inc(1);
        }
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let all: Vec<(u32, String)> = manifest.frames.iter().map(|f| (f.index, f.hash.clone())).collect();
    let complete = selection.is_all() || present(dir, &all, format).len() == all.len();
    Ok(RunSummary {
        dir: dir.to_path_buf(),
        selected: selected.len(),
        skipped: done.len(),
        rendered: todo.len(),
        render_s: started.elapsed().as_secs_f64(),
        gpu_ms,
        complete,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn volumes_blend_voxel_by_voxel_on_one_grid_only() {
        let a = Volume::new([2, 1, 1], [1.0; 3], vec![0.0, 4.0]).unwrap();
        let b = Volume::new([2, 1, 1], [1.0; 3], vec![2.0, 0.0]).unwrap();
        let m = blend_volumes(&a, &b, 0.25).unwrap();
        assert_eq!(m.data, vec![0.5, 3.0]);
        assert_eq!(m.value_range, [0.5, 3.0]);
        let c = Volume::new([1, 2, 1], [1.0; 3], vec![0.0, 0.0]).unwrap();
        assert!(blend_volumes(&a, &c, 0.5).unwrap_err().contains("hold"));
    }
}
