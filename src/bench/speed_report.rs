//! The speed bench's Markdown tables and CSV files.

use std::fmt::Write as _;
use std::path::Path;

use super::dispatch::{DispatchCost, DispatchKind};
use super::speed::{SpeedFit, SpeedRow};

/// What the Markdown header says about the run.
pub struct Context<'a> {
    pub device: &'a str,
    pub frames: u32,
    /// Frames at the tiny viewport (`SpeedPlan::frames_at`).
    pub tiny_frames: u32,
    pub sizes: &'a [u32],
    pub tiny_size: u32,
    pub load_before: Option<&'a str>,
    pub load_after: Option<&'a str>,
    /// The device's own cost of a dispatch, measured apart (`dispatch::measure`).
    pub dispatch_cost: Option<&'a DispatchCost>,
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or_else(|| "–".to_string(), |v| format!("{v:.digits$}"))
}

fn sizes_text(sizes: &[u32]) -> String {
    let lo = sizes.iter().min().copied().unwrap_or(0);
    let hi = sizes.iter().max().copied().unwrap_or(0);
    format!("{lo}²–{hi}²")
}

pub fn write_markdown(path: &Path, rows: &[SpeedRow], fits: &[SpeedFit], c: &Context) -> Result<(), String> {
    let mut s = String::new();
    let _ = write!(
        s,
        "Device: {}. GPU ms: median (min–max) of {} frames from timestamp queries, after one untimed \
         frame per scene (texture upload, pipelines). Wall ms: median time of the whole render call \
         (recording, submission, read-back). ms/plane: median GPU ms over planes. Light / view / \
         listing: median GPU ms per frame of the light passes, the view passes and the listing of \
         the next plane's tiles with the deposit ring's clearing and the barriers, from as many \
         frames again timed with timestamps between the passes (the final pass is the rest; \
         on a CPU driver those timestamps take time of their own, which the GPU ms per frame \
         are timed without). Footprint: pixels \
         whose rays can meet the volume. Peak memory: the most allocated at once during a frame \
         (device-local: textures and state buffers; host-visible: parameters, brick flags, read-back \
         and, on a scene's first frame, staging).",
        c.device, c.frames
    );
    if let (Some(a), Some(b)) = (c.load_before, c.load_after) {
        let _ = write!(s, " Load average (1, 5, 15 min) before: {a}, after: {b}.");
    }
    s.push_str("\n\n");
    s.push_str(
        "| scene | features | viewport | planes | GPU ms per frame | wall ms | ms/plane | light / view / listing ms | light grid | light tile steps | footprint px | state MiB | textures MiB | peak device MiB | peak host MiB |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {}² | {} | {:.1} ({:.1}–{:.1}) | {:.1} | {:.3} | {:.1} / {:.1} / {:.1} | {}×{} | {} | {}×{} | {:.1} | {:.1} | {:.1} | {:.1} |",
            r.scene,
            r.features,
            r.size,
            r.planes,
            r.gpu_ms.median,
            r.gpu_ms.min,
            r.gpu_ms.max,
            r.wall_ms.median,
            r.ms_per_plane(),
            r.pass_ms[0],
            r.pass_ms[1],
            r.pass_ms[2],
            r.light_grid[0],
            r.light_grid[1],
            r.light_steps
                .map_or_else(|| "–".to_string(), |n| format!("{n} of {}²", r.tile)),
            r.footprint[0],
            r.footprint[1],
            mib(r.state_bytes),
            mib(r.texture_bytes),
            mib(r.peak_memory.device_local),
            mib(r.peak_memory.host_visible),
        );
    }
    let _ = write!(
        s,
        "\nScaling over {}: the exponent is the least-squares slope of log GPU ms against \
         log (viewport pixels × planes), 1 for cost linear in the work. ",
        sizes_text(c.sizes)
    );
    if c.tiny_size > 0 {
        let _ = write!(
            s,
            "Fixed cost: ms per plane at {0}×{0}, where the pixels cost next to nothing (the median of \
             {1} frames there). ",
            c.tiny_size, c.tiny_frames
        );
    }
    s.push_str(
        "Intercept and ns per pixel-plane: a straight line through ms per plane against viewport pixels, every size. \
         Edit: the render after an edit of the opacity curve at the smallest viewport of the fit, as in the viewer's editor \
         (the volume images kept): median wall ms of the render call (its GPU part; the rest is the CPU's), and the MiB copied in.\n\n",
    );
    let per_dispatch = c.dispatch_cost.and_then(DispatchCost::with_work_ms);
    if let Some(d) = c.dispatch_cost {
        let kinds: Vec<String> = DispatchKind::ALL
            .iter()
            .filter_map(|&k| d.ms_of(k).map(|ms| format!("{} {:.4} ms", k.describe(), ms)))
            .collect();
        let _ = write!(
            s,
            "Dispatch cost of this device: {} (a shader that adds 1 to a word per invocation, each \
             dispatch followed by a barrier; median of {} rounds of {} in one submission). \
             Dispatches per plane: the dispatch commands the sweep recorded at the tiny viewport \
             (indirect ones included, whether or not their lists hold work), over its planes. Fixed \
             cost in dispatches: the fixed ms per plane over the cost of a dispatch with work in \
             this run (the driver's hand-over moves between runs on a busy machine).\n\n",
            kinds.join(", "),
            d.rounds,
            d.per_round,
        );
    }
    s.push_str("| scene | exponent | fixed ms per plane | dispatches per plane | fixed cost in dispatches | intercept ms per plane | ns per pixel-plane | edit ms (GPU) | edit upload MiB |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|\n");
    for f in fits {
        let (edit, upload) = match &f.edit {
            Some(e) => (
                format!("{:.1} ({:.1}) at {}²", e.wall_ms.median, e.gpu_ms.median, e.size),
                format!("{:.2}", mib(e.upload_bytes)),
            ),
            None => ("–".to_string(), "–".to_string()),
        };
        let in_dispatches = match (f.fixed_ms_per_plane, per_dispatch) {
            (Some(f), Some(d)) if d > 0.0 => Some(f / d),
            _ => None,
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            f.scene,
            opt(f.exponent, 2),
            opt(f.fixed_ms_per_plane, 3),
            opt(f.fixed_dispatches_per_plane, 2),
            opt(in_dispatches, 2),
            opt(f.intercept_ms_per_plane, 3),
            opt(f.ns_per_pixel_plane, 1),
            edit,
            upload,
        );
    }
    std::fs::write(path, s).map_err(|e| e.to_string())
}

pub fn write_csv(path: &Path, rows: &[SpeedRow]) -> Result<(), String> {
    let mut s = String::from(
        "scene,features,viewport,tiny,planes,gpu_ms_median,gpu_ms_min,gpu_ms_max,wall_ms_median,ms_per_plane,\
         light_grid_w,light_grid_h,light_tile_steps,footprint_w,footprint_h,state_bytes,texture_bytes,\
         peak_device_local_bytes,peak_host_visible_bytes,light_ms,view_ms,listing_ms,finish_ms,\
         pass_frames_gpu_ms_median,tile_side\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.5},{},{},{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{}",
            r.scene,
            r.features,
            r.size,
            r.tiny,
            r.planes,
            r.gpu_ms.median,
            r.gpu_ms.min,
            r.gpu_ms.max,
            r.wall_ms.median,
            r.ms_per_plane(),
            r.light_grid[0],
            r.light_grid[1],
            r.light_steps.map_or_else(String::new, |n| n.to_string()),
            r.footprint[0],
            r.footprint[1],
            r.state_bytes,
            r.texture_bytes,
            r.peak_memory.device_local,
            r.peak_memory.host_visible,
            r.pass_ms[0],
            r.pass_ms[1],
            r.pass_ms[2],
            r.pass_ms[3],
            r.pass_frames_ms.median,
            r.tile,
        );
    }
    std::fs::write(path, s).map_err(|e| e.to_string())
}

pub fn write_fit_csv(path: &Path, fits: &[SpeedFit], dispatch: Option<&DispatchCost>) -> Result<(), String> {
    let mut s = String::from(
        "scene,exponent,fixed_ms_per_plane,intercept_ms_per_plane,ns_per_pixel_plane,\
         edit_viewport,edit_wall_ms_median,edit_gpu_ms_median,edit_upload_bytes,\
         fixed_dispatches_per_plane,dispatch_ms\n",
    );
    let dispatch_ms = dispatch.and_then(DispatchCost::with_work_ms);
    let field = |v: Option<f64>| {
        v.filter(|v| v.is_finite())
            .map_or_else(String::new, |v| format!("{v:.5}"))
    };
    for f in fits {
        let edit = f.edit.map_or_else(
            || ",,,".to_string(),
            |e| {
                format!(
                    "{},{:.3},{:.3},{}",
                    e.size, e.wall_ms.median, e.gpu_ms.median, e.upload_bytes
                )
            },
        );
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{}",
            f.scene,
            field(f.exponent),
            field(f.fixed_ms_per_plane),
            field(f.intercept_ms_per_plane),
            field(f.ns_per_pixel_plane),
            edit,
            field(f.fixed_dispatches_per_plane),
            field(dispatch_ms),
        );
    }
    std::fs::write(path, s).map_err(|e| e.to_string())
}
