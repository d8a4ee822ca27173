//! The sweep itself: ping-pong state buffers, the per-plane dispatches and read-back
//! (Algorithm 1).

use std::io::IsTerminal;
use std::sync::Arc;

use ash::vk;
use glam::Mat4;

use crate::gpu::{
    Buffer, ComputePipeline, Context, DescriptorSet, Format, GpuError, Image, ImageDesc, Recorder, Resource, Timestamps,
};

use super::geometry::{light_direction, ViewSetup, MAX_LIGHT_VALUE, MIN_LIGHT_DIR_Z, MIN_VIEW_DIR_Z};
use super::upload::{CachedTextures, SceneTextures, TexturesKey, ETA_TABLE_SIZE};
use super::{
    background, DebugView, Features, Immediates, Params, PreparedScene, RenderError, RenderOutput, RenderRequest,
    RenderStats, RenderedImage,
};
use crate::scene::Precision;

/// Planes recorded per submission at most: keeps each submission short (progress,
/// responsiveness, watchdogs) while the per-submission overhead stays negligible.
const PLANES_PER_SUBMIT: u32 = 128;
/// Texel updates per submission at most (planes × pixels), so that one submission stays far
/// below the fence timeout (`gpu::FENCE_TIMEOUT`) even at the device's largest image on a CPU
/// driver: 2^24 texels take about 5 s on lavapipe on two cores.
const TEXELS_PER_SUBMIT: u64 = 1 << 24;
/// Pixel-planes per submission of a cancellable render (between 1 and 8 planes): a view
/// change stops it within about one plane of a 1024×768 image.
const PIXEL_PLANES_PER_SUBMIT_CANCELLABLE: u32 = 1 << 20;

/// The bindings of the six state buffers in `shaders/common.wgsl`, (read side, write side),
/// in the order of [`state_formats`].
const STATE_BINDINGS: [(&str, &str); 6] = [
    ("light_in", "light_out"),
    ("light_dir_in", "light_dir_out"),
    ("view_pos_in", "view_pos_out"),
    ("view_dir_in", "view_dir_out"),
    ("color_in", "color_out"),
    ("medium_in", "medium_out"),
];

/// The six state buffers of Algorithm 1 with their storage formats at `precision` (those the
/// write-side bindings of [`super::shaders::Pass::parse`] declare; a test compares them).
/// Buffers the scene does not need get a 1×1 placeholder.
fn state_formats(precision: Precision) -> [(&'static str, Format); 6] {
    let colour = match precision {
        Precision::F16 => Format::R16G16B16A16_SFLOAT,
        Precision::F32 => Format::R32G32B32A32_SFLOAT,
    };
    [
        ("light", colour),
        ("light direction", Format::R32G32B32A32_SFLOAT),
        ("view position", Format::R32G32B32A32_SFLOAT),
        ("view direction", Format::R32G32B32A32_SFLOAT),
        ("colour+opacity", colour),
        ("medium", colour),
    ]
}

fn needed(features: &Features, index: usize) -> bool {
    match index {
        1 | 2 => features.refraction,
        5 => features.medium,
        _ => true,
    }
}

fn cols(m: Mat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d()
}

fn make_params(prepared: &PreparedScene, view: &ViewSetup, req: &RenderRequest, env_levels: u32) -> Params {
    let scene = &prepared.scene;
    let vol = &prepared.volume;
    let ld = light_direction(&scene.light);
    let l = &scene.light;
    let clip = scene
        .clip
        .as_ref()
        .map(|c| view.clip_plane(c.normal, c.offset).to_array())
        .unwrap_or([0.0, 0.0, 0.0, -1.0]);
    let env_intensity = match &scene.environment {
        crate::scene::Environment::Studio { intensity } | crate::scene::Environment::Image { intensity, .. } => {
            *intensity
        }
        crate::scene::Environment::Color { .. } => 1.0,
    };
    let rotation = Mat4::from_mat3(glam::Mat3::from_mat4(view.world_from_view));
    Params {
        volume_from_view: cols(view.volume_from_view()),
        gradient_to_view: cols(view.gradient_to_view(vol.spacing)),
        world_from_view: cols(rotation),
        clip_plane: clip,
        projection: view.projection,
        plane: [
            view.z_first,
            view.step,
            view.planes as f32,
            scene.quality.sample_distance,
        ],
        light_dir: [ld.x, ld.y, ld.z, l.softness * view.step],
        light_color: [
            l.color[0] * l.intensity,
            l.color[1] * l.intensity,
            l.color[2] * l.intensity,
            scene.quality.max_intensity_ratio,
        ],
        shading: [
            scene.shading.specular,
            scene.shading.roughness,
            scene.quality.termination_opacity,
            env_intensity,
        ],
        size: [
            req.width as f32,
            req.height as f32,
            1.0 / req.width as f32,
            1.0 / req.height as f32,
        ],
        texel: [
            1.0 / vol.dims[0] as f32,
            1.0 / vol.dims[1] as f32,
            1.0 / vol.dims[2] as f32,
            ETA_TABLE_SIZE as f32,
        ],
        background: background(&scene.environment),
        limits: [MIN_LIGHT_DIR_Z, MIN_VIEW_DIR_Z, MAX_LIGHT_VALUE, env_levels as f32],
        budget: [scene.quality.max_concentration, 0.0, 0.0, 0.0],
    }
}

fn progress_bar(show: bool, planes: u64) -> Option<indicatif::ProgressBar> {
    if !show || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(planes);
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} planes {pos}/{len} {wide_bar} {eta}") {
        bar.set_style(style);
    }
    Some(bar)
}

pub(super) fn run(
    ctx: &Arc<Context>,
    prepared: &PreparedScene,
    req: &RenderRequest,
    features: Features,
    precision: Precision,
    pipelines: &[Arc<ComputePipeline>; 3],
    cache: &mut Option<CachedTextures>,
) -> Result<RenderOutput, RenderError> {
    let (w, h) = (req.width, req.height);
    let max_2d = ctx.limits().max_image_dimension2_d;
    if w == 0 || h == 0 || w > max_2d || h > max_2d {
        return Err(RenderError::Setup(format!(
            "image size {w}×{h} must be between 1×1 and {max_2d}×{max_2d} on this device"
        )));
    }
    let vol = &prepared.volume;
    let view = ViewSetup::new(&prepared.scene, vol.dims, vol.spacing, w, h).map_err(RenderError::Setup)?;
    let planes_run = if req.debug_view == DebugView::Image {
        view.planes
    } else {
        1 + (req.debug_depth.clamp(0.0, 1.0) * (view.planes - 1) as f32).round() as u32
    };

    let window = prepared.window();
    let eta = match (&prepared.eta_volume, features.eta_volume) {
        (Some(v), true) => Some((v.as_ref(), v.value_range)),
        _ => None,
    };
    // Scene textures are kept between renders while what they hold is unchanged (an
    // interactive view changes mostly the camera and light).
    let key = TexturesKey::new(prepared, features.eta_volume);
    let mut pending = None;
    if !cache.as_ref().is_some_and(|c| c.matches(&key)) {
        *cache = None; // free the old textures before allocating new ones
        let (textures, upload) = SceneTextures::upload(
            ctx,
            vol,
            window,
            eta,
            &prepared.tf,
            prepared.scene.quality.sample_distance,
            prepared.env.as_ref(),
        )?;
        *cache = Some(CachedTextures::new(key, textures));
        pending = Some(upload);
    }
    let cached = cache
        .as_ref()
        .ok_or_else(|| RenderError::Setup("internal: scene textures missing".into()))?;

    let mut uniform = Buffer::new_upload(
        ctx,
        "params",
        std::mem::size_of::<Params>() as u64,
        vk::BufferUsageFlags::UNIFORM_BUFFER,
    )?;
    uniform.write(bytemuck::bytes_of(&make_params(
        prepared,
        &view,
        req,
        cached.textures.env_levels,
    )))?;

    // Ping-pong state: state[side][k]; placeholders for buffers the scene does not need.
    let mut state_bytes = 0u64;
    let mut state: [Vec<Image>; 2] = [Vec::new(), Vec::new()];
    for (side, images) in state.iter_mut().enumerate() {
        for (k, (name, format)) in state_formats(precision).iter().enumerate() {
            let (iw, ih) = if needed(&features, k) { (w, h) } else { (1, 1) };
            let label = format!("{name} {}", ["A", "B"][side]);
            let img = Image::new(ctx, ImageDesc::storage_2d(&label, *format, iw, ih))?;
            let texel_bytes = if *format == Format::R32G32B32A32_SFLOAT { 16 } else { 8 };
            state_bytes += (iw * ih) as u64 * texel_bytes;
            images.push(img);
        }
    }
    let output = Image::new(ctx, ImageDesc::storage_2d("output", Format::R32G32B32A32_SFLOAT, w, h))?;
    let mut readback = Buffer::new_readback(ctx, "output readback", (w * h) as u64 * 16)?;
    let ts = Timestamps::new(ctx, 2)?;

    // sets[p][r]: pipeline p, reading side r and writing side 1 - r.
    let mut sets: Vec<[DescriptorSet; 2]> = Vec::new();
    for p in pipelines {
        let make = |read: usize| -> Result<DescriptorSet, GpuError> {
            let mut set = DescriptorSet::new(ctx, p, &format!("{} reads {}", p.label, ["A", "B"][read]))?;
            let t = &cached.textures;
            let mut writes = vec![
                ("P", Resource::Buffer(&uniform)),
                ("volume_tex", Resource::Image(&t.volume)),
                ("linear_clamp", Resource::Sampler(&t.linear_clamp)),
                ("volume_sampler", Resource::Sampler(&t.volume_sampler)),
                (
                    "eta_volume_tex",
                    Resource::Image(t.eta_volume.as_ref().unwrap_or(&t.volume)),
                ),
                ("particle_table", Resource::Image(&t.particle_table)),
                ("medium_table", Resource::Image(&t.medium_table)),
                ("eta_table", Resource::Image(&t.eta_table)),
                ("env_tex", Resource::Image(&t.env)),
                ("env_sampler", Resource::Sampler(&t.env_sampler)),
                ("image_out", Resource::Image(&output)),
            ];
            for ((input, output), (name_in, name_out)) in state[read].iter().zip(&state[1 - read]).zip(STATE_BINDINGS) {
                writes.push((name_in, Resource::Image(input)));
                writes.push((name_out, Resource::Image(output)));
            }
            set.write(&writes)?;
            Ok(set)
        };
        sets.push([make(0)?, make(1)?]);
    }

    // Everything the commands use is created above: the recorders borrow it.
    let mut rec = Recorder::new(ctx, "render: upload and init")?;
    if let Some(upload) = pending {
        cached.textures.record_upload(&mut rec, upload);
    }
    let mut all: Vec<&Image> = state.iter().flatten().collect();
    all.push(&output);
    rec.init_layout(&all);

    let groups = |p: &ComputePipeline| p.groups_for([w, h, 1]);
    let planes_per_submit = (TEXELS_PER_SUBMIT / (w as u64 * h as u64)).clamp(1, PLANES_PER_SUBMIT as u64) as u32;
    let push = |plane: u32| Immediates {
        plane_index: plane,
        seed: 0x9e37_79b9,
        pad: [0; 2],
    };

    // Init writes side A (set reading B); plane i reads side (i-1) % 2.
    rec.dispatch(
        &pipelines[0],
        &sets[0][1],
        bytemuck::bytes_of(&push(0)),
        groups(&pipelines[0]),
    )?;
    rec.compute_to_compute();
    let bar = progress_bar(req.progress, planes_run as u64);
    let mut gpu_ms = 0.0;
    let mut plane = 1u32;
    let mut rec = Some(rec);
    let chunk = if req.cancel.is_some() {
        (PIXEL_PLANES_PER_SUBMIT_CANCELLABLE / (w * h).max(1)).clamp(1, 8)
    } else {
        planes_per_submit
    };
    loop {
        if req
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
        {
            return Err(RenderError::Cancelled);
        }
        let mut r = match rec.take() {
            Some(r) => r,
            None => Recorder::new(ctx, "render: planes")?,
        };
        r.reset_timestamps(&ts);
        r.timestamp(&ts, 0);
        let end = (plane + chunk).min(planes_run);
        while plane < end {
            let read = ((plane - 1) % 2) as usize;
            r.dispatch(
                &pipelines[1],
                &sets[1][read],
                bytemuck::bytes_of(&push(plane)),
                groups(&pipelines[1]),
            )?;
            r.compute_to_compute();
            plane += 1;
        }
        let last = plane >= planes_run;
        if last {
            let read = ((planes_run - 1) % 2) as usize;
            r.dispatch(
                &pipelines[2],
                &sets[2][read],
                bytemuck::bytes_of(&push(planes_run)),
                groups(&pipelines[2]),
            )?;
            r.compute_to_transfer();
            r.copy_to_buffer(&output, &mut readback);
        }
        r.timestamp(&ts, 1);
        r.submit_and_wait()?;
        cached.uploaded();
        gpu_ms += ts.read_ms()?.iter().sum::<f64>();
        if let Some(b) = &bar {
            b.set_position(plane as u64);
        }
        if last {
            if let Some(b) = bar {
                b.finish_and_clear();
            }
            let bytes = readback.read()?;
            let pixels: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(bytes);
            return Ok(RenderOutput {
                image: RenderedImage {
                    width: w,
                    height: h,
                    pixels,
                },
                stats: RenderStats {
                    features,
                    planes: view.planes,
                    planes_run,
                    gpu_ms,
                    ms_per_plane: gpu_ms / planes_run.max(1) as f64,
                    state_bytes,
                    precision,
                    reductions: Vec::new(),
                },
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::BindingKind;
    use crate::render::shaders::Pass;

    /// The image formats allocated for the state buffers are those the shaders declare for
    /// their write side, at both precisions, and every state binding exists on both sides.
    #[test]
    fn state_formats_are_the_declared_ones() {
        for precision in [Precision::F16, Precision::F32] {
            for pass in Pass::ALL {
                let source = pass.parse(precision).unwrap();
                let layout = source.layout();
                for ((name, format), (read, write)) in state_formats(precision).iter().zip(STATE_BINDINGS) {
                    assert_eq!(
                        layout.binding(read).map(|b| b.kind),
                        Some(BindingKind::SampledImage),
                        "{read}"
                    );
                    let Some(BindingKind::StorageImage { format: declared, .. }) =
                        layout.binding(write).map(|b| b.kind)
                    else {
                        panic!("{write} is not a storage image in {pass:?}");
                    };
                    assert_eq!(declared, *format, "{name} at {precision:?} in {pass:?}");
                }
                assert_eq!(layout.immediate_bytes as usize, std::mem::size_of::<Immediates>());
            }
        }
    }
}
