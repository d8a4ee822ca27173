//! Multiple scattering by lattice-Boltzmann diffusion (Bernabei et al.; `shaders/lbm.wgsl`),
//! run before the sweep when `quality.multiple_scattering = "lbm"` and the particles scatter.
//!
//! Light marching deposits the light the particles scatter into an illumination grid one
//! cell per `quality.lbm.cell_voxels` voxels, then D3Q6 steps (collide, stream) run until the
//! fluence changes by less than `quality.lbm.residual` per step. The sweep's view rays read
//! the grid as isotropic in-scattering (`shaders/lbm_view.wgsl`). Unlike the sweep, this mode
//! keeps a light volume: six densities per cell, twice (the steps read one copy and write the
//! other), which [`LbmStats::bytes`] reports.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::gpu::{Buffer, ComputePipeline, Context, DescriptorSet, GpuError, Image, Recorder, Resource, Sampler};
use crate::gpu::{ShaderSource, Timestamps};
use crate::scene::LbmSettings;
use crate::transfer::{TransferFunctions, MAX_OPTICAL_DEPTH_PER_VOXEL, TABLE_SIZE};

use super::upload::{CachedTextures, PendingUpload};
use super::{PreparedScene, RenderError};

pub const SOURCE: &str = include_str!("../../shaders/lbm.wgsl");

/// Invocations per workgroup (`WG` in lbm.wgsl).
pub const WORKGROUP: u32 = 64;
/// Steps between two measurements of the residual (each costs a read-back).
const STEPS_PER_CHECK: u32 = 32;
/// Most workgroups of one dispatch (the passes dispatch along x only).
const MAX_GROUPS: u32 = 65535;

/// Mirrors `struct LbmParams` in `shaders/lbm.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LbmParams {
    /// Cells along x, y, z; sub-samples per cell edge.
    pub grid: [u32; 4],
    /// Volume extent in voxels (x, y, z); cell edge in voxels.
    pub volume: [f32; 4],
    /// Unit direction toward the light in voxel space; march step in voxels.
    pub to_light: [f32; 4],
    /// Entries of the coefficient table; unused.
    pub table: [f32; 4],
}

/// Mirrors the header of `struct LbmGrid` in `shaders/lbm_view.wgsl` (the fluence follows).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LbmGridHeader {
    pub dims: [u32; 4],
    /// Volume texture coordinates to cell coordinates, per axis.
    pub scale: [f32; 4],
}

/// What one diffusion did, for `render --timings`, the bench and the tests.
#[derive(Clone, Debug, Default)]
pub struct LbmStats {
    pub grid: [u32; 3],
    pub cell_voxels: u32,
    /// Steps taken, and the relative change of the fluence over the last one.
    pub iterations: u32,
    pub residual: f64,
    /// The residual fell under `quality.lbm.residual` (else `max_iterations` stopped it).
    pub converged: bool,
    /// Light scattered by the particles, as power over the light's irradiance (voxel²).
    pub deposited: f64,
    /// Per step, in the same units: what the particles scatter into the lattice, and what the
    /// last step streamed out of the grid and absorbed. source − leaving − absorbed is what
    /// the grid gained over that step, at most `residual` × Σφ.
    pub source: f64,
    pub leaving: f64,
    pub absorbed: f64,
    /// Device bytes of the lattice, the illumination grid and their tables.
    pub bytes: u64,
    pub gpu_ms: f64,
    /// Unit direction toward the light in the grid's voxel space (x, y, z as the volume's
    /// axes).
    pub to_light: [f32; 3],
    /// Scattered fluence per cell (x fastest), relative to the light's irradiance.
    pub fluence: Vec<f32>,
}

/// The solver's three passes.
pub struct Pipelines {
    deposit: Arc<ComputePipeline>,
    step: Arc<ComputePipeline>,
    measure: Arc<ComputePipeline>,
}

impl Pipelines {
    pub fn new(ctx: &Arc<Context>) -> Result<Self, GpuError> {
        let source = ShaderSource::parse("lbm.wgsl", SOURCE)?;
        let make = |entry: &str| -> Result<Arc<ComputePipeline>, GpuError> {
            let compiled = source.specialise(entry, &[])?;
            Ok(Arc::new(ComputePipeline::new(
                ctx,
                &format!("lbm.wgsl:{entry}"),
                &compiled,
            )?))
        };
        Ok(Pipelines {
            deposit: make("deposit_main")?,
            step: make("step_main")?,
            measure: make("measure_main")?,
        })
    }
}

/// The lattice's coefficients per data value (TABLE_SIZE entries over [0, 1]): σ_t per voxel
/// from the opacity (α per voxel, as the sweep's), albedo ω, anisotropy g, 0.
pub fn coefficient_table(tf: &TransferFunctions) -> Vec<[f32; 4]> {
    (0..TABLE_SIZE)
        .map(|i| {
            let x = i as f32 / (TABLE_SIZE - 1) as f32;
            let alpha = tf.opacity.eval(x).clamp(0.0, 1.0);
            let sigma = if alpha >= 1.0 {
                MAX_OPTICAL_DEPTH_PER_VOXEL
            } else {
                (-(1.0 - alpha).ln()).min(MAX_OPTICAL_DEPTH_PER_VOXEL)
            };
            [sigma, tf.albedo_at(x), tf.anisotropy_at(x), 0.0]
        })
        .collect()
}

/// The illumination grid the view reads, and what the diffusion did.
pub struct LbmLight {
    /// Header and fluence (`lbm_grid` in lbm_view.wgsl).
    pub grid: Buffer,
    /// `coefficient_table` (`lbm_albedo` in lbm_view.wgsl).
    pub table: Buffer,
    pub stats: LbmStats,
}

/// Placeholders for the view's two bindings when the scene does not use the mode.
pub fn unused(ctx: &Arc<Context>) -> Result<(Buffer, Buffer), GpuError> {
    Ok((
        Buffer::new_storage(ctx, "lbm grid (unused)", 48)?,
        Buffer::new_storage(ctx, "lbm table (unused)", 32)?,
    ))
}

/// The volume as the solver sees it.
pub struct VolumeInput<'a> {
    pub texture: &'a Image,
    pub sampler: &'a Sampler,
    pub dims: [usize; 3],
    pub spacing: [f32; 3],
    /// Direction the light travels, in volume texture coordinates (any length).
    pub light_in_texture: Vec3,
}

/// Deposits, diffuses to the residual, and returns the grid for the view.
pub fn solve(
    ctx: &Arc<Context>,
    pipelines: &Pipelines,
    volume: &VolumeInput,
    tf: &TransferFunctions,
    settings: &LbmSettings,
) -> Result<LbmLight, RenderError> {
    let min_spacing = volume.spacing.iter().copied().fold(f32::INFINITY, f32::min);
    let extent = Vec3::from_array(std::array::from_fn(|a| {
        volume.dims[a] as f32 * volume.spacing[a] / min_spacing
    }));
    let edge = settings.cell_voxels as f32;
    let grid: [u32; 3] = std::array::from_fn(|a| (extent[a] / edge).ceil().max(1.0) as u32);
    let cells = grid.iter().map(|&n| n as u64).product::<u64>();
    if cells > (MAX_GROUPS * WORKGROUP) as u64 {
        return Err(RenderError::Setup(format!(
            "quality.lbm.cell_voxels {} gives {}×{}×{} illumination cells, more than the {} one pass handles; use larger cells",
            settings.cell_voxels,
            grid[0],
            grid[1],
            grid[2],
            MAX_GROUPS * WORKGROUP
        )));
    }
    let to_light = -(volume.light_in_texture * extent).normalize_or_zero();
    if to_light == Vec3::ZERO {
        return Err(RenderError::Setup(
            "internal: no light direction for the lattice".into(),
        ));
    }
    let table = coefficient_table(tf);
    let params = LbmParams {
        grid: [grid[0], grid[1], grid[2], settings.cell_voxels],
        volume: [extent.x, extent.y, extent.z, edge],
        to_light: [to_light.x, to_light.y, to_light.z, 1.0],
        table: [TABLE_SIZE as f32, 0.0, 0.0, 0.0],
    };
    let lattice = Lattice {
        params: Buffer::new_storage_from(ctx, "lbm params", bytemuck::bytes_of(&params))?,
        table: Buffer::new_storage_from(ctx, "lbm table", bytemuck::cast_slice(&table))?,
        cells: Buffer::new_storage(ctx, "lbm cells", cells * 16)?,
        f: [
            Buffer::new_storage(ctx, "lbm densities a", cells * 6 * 4)?,
            Buffer::new_storage(ctx, "lbm densities b", cells * 6 * 4)?,
        ],
        measure: Buffer::new_storage(ctx, "lbm measure", cells * 16)?,
        source_g: Buffer::new_storage(ctx, "lbm source anisotropy", cells * 4)?,
    };
    let Run {
        iterations: done,
        residual,
        deposited,
        source,
        leaving,
        absorbed,
        gpu_ms,
        fluence,
    } = iterate(ctx, pipelines, &lattice, volume, cells, settings)?;
    let converged = residual < settings.residual as f64;
    if !converged {
        log::warn!(
            "lattice-Boltzmann diffusion stopped at quality.lbm.max_iterations = {} with residual {residual:.2e} (target {:.0e})",
            settings.max_iterations,
            settings.residual
        );
    }
    let header = LbmGridHeader {
        dims: [grid[0], grid[1], grid[2], 0],
        scale: [extent.x / edge, extent.y / edge, extent.z / edge, 0.0],
    };
    let mut bytes = bytemuck::bytes_of(&header).to_vec();
    bytes.extend_from_slice(bytemuck::cast_slice(&fluence));
    let grid_buffer = Buffer::new_storage_from(ctx, "lbm grid", &bytes)?;
    let lattice_bytes = cells * (16 + 2 * 6 * 4 + 16 + 4) + bytes.len() as u64 + (table.len() * 16) as u64;
    Ok(LbmLight {
        grid: grid_buffer,
        table: lattice.table,
        stats: LbmStats {
            grid,
            cell_voxels: settings.cell_voxels,
            iterations: done,
            residual,
            converged,
            deposited,
            source,
            leaving,
            absorbed,
            bytes: lattice_bytes,
            gpu_ms,
            to_light: to_light.to_array(),
            fluence,
        },
    })
}

/// The solver's device buffers.
struct Lattice {
    params: Buffer,
    table: Buffer,
    cells: Buffer,
    f: [Buffer; 2],
    measure: Buffer,
    source_g: Buffer,
}

/// What [`iterate`] measured.
struct Run {
    iterations: u32,
    residual: f64,
    deposited: f64,
    source: f64,
    leaving: f64,
    absorbed: f64,
    gpu_ms: f64,
    fluence: Vec<f32>,
}

fn lattice_set<'a>(
    ctx: &Arc<Context>,
    p: &'a ComputePipeline,
    lattice: &'a Lattice,
    volume: &VolumeInput<'a>,
    from: usize,
    label: &str,
) -> Result<DescriptorSet<'a>, GpuError> {
    let mut s = DescriptorSet::new(ctx, p, label)?;
    s.write(&[
        ("lbm_params", Resource::Buffer(&lattice.params)),
        ("volume_tex", Resource::Image(volume.texture)),
        ("volume_sampler", Resource::Sampler(volume.sampler)),
        ("lbm_table", Resource::Buffer(&lattice.table)),
        ("cells", Resource::Buffer(&lattice.cells)),
        ("f_in", Resource::Buffer(&lattice.f[from])),
        ("f_out", Resource::Buffer(&lattice.f[1 - from])),
        ("measure", Resource::Buffer(&lattice.measure)),
        ("source_g", Resource::Buffer(&lattice.source_g)),
    ])?;
    Ok(s)
}

/// Deposits, then steps until the residual or the step limit is reached, measuring every
/// `STEPS_PER_CHECK` steps.
fn iterate(
    ctx: &Arc<Context>,
    pipelines: &Pipelines,
    lattice: &Lattice,
    volume: &VolumeInput,
    cells: u64,
    settings: &LbmSettings,
) -> Result<Run, RenderError> {
    let mut readback = Buffer::new_readback(ctx, "lbm measure readback", cells * 16)?;
    let ts = Timestamps::new(ctx, 2)?;
    let deposit = lattice_set(ctx, &pipelines.deposit, lattice, volume, 0, "lbm deposit")?;
    let steps = [
        lattice_set(ctx, &pipelines.step, lattice, volume, 0, "lbm step a→b")?,
        lattice_set(ctx, &pipelines.step, lattice, volume, 1, "lbm step b→a")?,
    ];
    // Measures the latest densities (f_in) against the step before (f_out).
    let measures = [
        lattice_set(ctx, &pipelines.measure, lattice, volume, 0, "lbm measure a")?,
        lattice_set(ctx, &pipelines.measure, lattice, volume, 1, "lbm measure b")?,
    ];
    let groups = [(cells as u32).div_ceil(WORKGROUP), 1, 1];
    let mut run = Run {
        iterations: 0,
        residual: f64::INFINITY,
        deposited: 0.0,
        source: 0.0,
        leaving: 0.0,
        absorbed: 0.0,
        gpu_ms: 0.0,
        fluence: Vec::new(),
    };
    loop {
        let first = run.iterations == 0;
        let mut r = Recorder::new(ctx, "lbm")?;
        r.reset_timestamps(&ts);
        r.timestamp(&ts, 0);
        if first {
            r.fill(&lattice.f[0], 0);
            r.fill(&lattice.f[1], 0);
            r.dispatch(&pipelines.deposit, &deposit, &[], groups)?;
            r.compute_to_compute();
        }
        let done = run.iterations;
        let batch = STEPS_PER_CHECK.min(settings.max_iterations - done);
        for k in done..done + batch {
            r.dispatch(&pipelines.step, &steps[(k % 2) as usize], &[], groups)?;
            r.compute_to_compute();
        }
        run.iterations += batch;
        // After an odd number of steps the latest densities are in b.
        r.dispatch(
            &pipelines.measure,
            &measures[(run.iterations % 2) as usize],
            &[],
            groups,
        )?;
        r.compute_to_transfer();
        r.copy_buffer(&lattice.measure, &mut readback, cells * 16);
        r.timestamp(&ts, 1);
        r.submit_and_wait()?;
        run.gpu_ms += ts.read_ms()?.iter().sum::<f64>();
        let m: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(readback.read()?);
        let (mut now, mut change) = (0.0f64, 0.0f64);
        (run.leaving, run.absorbed) = (0.0, 0.0);
        for v in &m {
            now += v[0] as f64;
            change += v[1] as f64;
            run.leaving += v[2] as f64;
            run.absorbed += v[3] as f64;
        }
        run.residual = if now > 0.0 { change / now } else { 0.0 };
        if first {
            // The sources do not change: read them once.
            let c = read_cells(ctx, &lattice.cells, cells)?;
            run.source = c.iter().map(|v| v[0] as f64).sum();
            run.deposited = c.iter().map(|v| v[3] as f64).sum();
        }
        if run.residual < settings.residual as f64 || run.iterations >= settings.max_iterations {
            run.fluence = m.iter().map(|v| v[0]).collect();
            return Ok(run);
        }
    }
}

/// The lattice-Boltzmann pass before the sweep: the scene textures' upload (if still pending)
/// executes first, since the lattice's light marching reads the volume.
pub(super) fn solve_for_scene(
    ctx: &Arc<Context>,
    pipelines: &Pipelines,
    prepared: &PreparedScene,
    view: &crate::scene::ViewSetup,
    cached: &CachedTextures,
    pending: Option<PendingUpload>,
    light: glam::Vec3,
) -> Result<LbmLight, RenderError> {
    if let Some(upload) = pending {
        let mut r = Recorder::new(ctx, "render: upload")?;
        cached.textures.record_upload(&mut r, upload);
        r.submit_and_wait()?;
        cached.uploaded();
    }
    let vol = &prepared.volume;
    let input = VolumeInput {
        texture: &cached.textures.volume,
        sampler: &cached.textures.volume_sampler,
        dims: vol.dims,
        spacing: vol.spacing,
        light_in_texture: view.volume_from_view().transform_vector3(light),
    };
    solve(ctx, pipelines, &input, &prepared.tf, &prepared.scene.quality.lbm)
}

fn read_cells(ctx: &Arc<Context>, cells: &Buffer, count: u64) -> Result<Vec<[f32; 4]>, GpuError> {
    let mut readback = Buffer::new_readback(ctx, "lbm cells readback", count * 16)?;
    let mut r = Recorder::new(ctx, "lbm cells readback")?;
    r.copy_buffer(cells, &mut readback, count * 16);
    r.submit_and_wait()?;
    Ok(bytemuck::pod_collect_to_vec(readback.read()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The WGSL structs must have the Rust ones' sizes and offsets.
    #[test]
    fn lbm_structs_match_wgsl() {
        let module = naga::front::wgsl::parse_str(SOURCE).expect("lbm.wgsl parses");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let (h, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("LbmParams"))
            .unwrap();
        assert_eq!(layouter[h].size as usize, std::mem::size_of::<LbmParams>());
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!()
        };
        let offsets: Vec<u32> = members.iter().map(|m| m.offset).collect();
        assert_eq!(offsets, [0, 16, 32, 48]);
        assert!(SOURCE.contains(&format!("const WG: u32 = {WORKGROUP}u;")));

        let view = format!(
            "{}\n{}\n@compute @workgroup_size(1) fn main() {{ _ = lbm_in_scattering(vec3<f32>(0.0), 0.0); }}",
            crate::render::shaders::COMMON,
            crate::render::shaders::LBM_VIEW
        );
        let module = naga::front::wgsl::parse_str(&view).expect("lbm_view.wgsl parses");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let (_, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("LbmGrid"))
            .unwrap();
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!()
        };
        let offsets: Vec<u32> = members.iter().map(|m| m.offset).collect();
        assert_eq!(offsets, [0, 16, std::mem::size_of::<LbmGridHeader>() as u32]);
    }

    #[test]
    fn the_coefficient_table_follows_the_opacity_and_albedo() {
        let tf = TransferFunctions {
            opacity: crate::transfer::Curve::constant(0.5),
            albedo: Some(crate::transfer::Curve::constant(0.8)),
            ..TransferFunctions::default()
        };
        let t = coefficient_table(&tf);
        assert_eq!(t.len(), TABLE_SIZE);
        for e in t {
            // −ln(1 − 0.5) in f32: within 1e-6.
            assert!((e[0] - std::f32::consts::LN_2).abs() < 1e-6, "{e:?}");
            assert_eq!(e[1], 0.8);
        }
    }
}
