//! The reference renderer's own convergence: its image error against a much finer run of
//! itself, as the photon lattice gets denser and the RK4 steps shorter.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use super::{bench_scene, compare, BenchError, Linear};
use crate::reference::photons::PhotonSettings;
use crate::reference::{self, ReferenceSettings};

/// One run of the reference.
#[derive(Clone, Debug)]
pub struct ConvergenceRow {
    pub rays_per_voxel2: f64,
    pub step_voxels: f64,
    pub seconds: f64,
    pub rel_l1: f64,
    pub rmse: f64,
}

fn settings(rays: f64, step: f64) -> ReferenceSettings {
    ReferenceSettings {
        photons: PhotonSettings {
            rays_per_voxel2: rays,
            step_voxels: step,
            ..PhotonSettings::default()
        },
        view_step_voxels: step,
        ..ReferenceSettings::default()
    }
}

/// Renders `scene` at `size`² with the reference at each (rays per voxel², step) pair and
/// compares every image with a run at `truth`; writes a Markdown table to `path`.
pub fn run(
    scene: &str,
    resolution: usize,
    size: u32,
    runs: &[(f64, f64)],
    truth: (f64, f64),
    path: &Path,
) -> Result<Vec<ConvergenceRow>, BenchError> {
    let prepared = bench_scene(scene, resolution, true)?;
    let start = Instant::now();
    let best = reference::render(&prepared, size, size, &settings(truth.0, truth.1), false)?;
    let truth_seconds = start.elapsed().as_secs_f64();
    let best = Linear::from_image(&best);
    let mut rows = Vec::new();
    for &(rays, step) in runs {
        let start = Instant::now();
        let img = reference::render(&prepared, size, size, &settings(rays, step), false)?;
        let seconds = start.elapsed().as_secs_f64();
        let e = compare(&Linear::from_image(&img), &best).ok_or_else(|| BenchError::Plan("size mismatch".into()))?;
        rows.push(ConvergenceRow {
            rays_per_voxel2: rays,
            step_voxels: step,
            seconds,
            rel_l1: e.rel_l1,
            rmse: e.rmse,
        });
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Reference convergence: {scene} at {resolution} voxels, {size}² pixels, against a run with {} rays/voxel² and {}-voxel steps ({truth_seconds:.0} s).\n",
        truth.0, truth.1
    );
    s.push_str("| rays per voxel² | RK4 step (voxels) | time (s) | rel. L1 | RMSE |\n|---|---|---|---|---|\n");
    for r in &rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.4} | {:.4} |",
            r.rays_per_voxel2, r.step_voxels, r.seconds, r.rel_l1, r.rmse
        );
    }
    std::fs::write(path, s).map_err(|e| BenchError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(rows)
}
