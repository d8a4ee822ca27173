//! The bench's Markdown table and CSV file.

use std::fmt::Write as _;
use std::path::Path;

use super::{plot::pareto_front, Plan, Row};
use crate::scene::LightTransport;

fn on(b: bool) -> &'static str {
    if b {
        "on"
    } else {
        "off"
    }
}

/// The light's transport, and for the backward one whether its intensity law is off.
fn light(t: &super::Setting) -> &'static str {
    match (t.light_transport, t.intensity_correction) {
        (LightTransport::Backward, false) => "backward, no intensity law",
        (transport, _) => transport.name(),
    }
}

/// Indices of the rows on their scene's Pareto front (time vs relative L1).
fn front_rows(rows: &[Row]) -> Vec<bool> {
    let mut on_front = vec![false; rows.len()];
    let mut scenes: Vec<&str> = rows.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for scene in scenes {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].scene == scene).collect();
        let points: Vec<(f64, f64)> = idx.iter().map(|&i| (rows[i].ms_median, rows[i].error.rel_l1)).collect();
        for k in pareto_front(&points) {
            on_front[idx[k]] = true;
        }
    }
    on_front
}

pub fn write_markdown(path: &Path, rows: &[Row], device: &str, plan: &Plan) -> Result<(), String> {
    let mut s = String::new();
    let r = &plan.reference;
    let _ = writeln!(
        s,
        "Device: {device}. Volumes: built-in scenes at {} voxels along the longest axis, highlights {}. \
         GPU time: median (min–max) of {} frames after an untimed one, from timestamp queries. Error: against the reference \
         renderer at {}² ({} rays/voxel², RK4 steps {} voxel light / {} voxel view, {}² rays per pixel), \
         larger viewports box-filtered to that size. ★ = on the scene's Pareto front.\n",
        plan.resolution,
        on(plan.highlights),
        plan.frames,
        plan.reference_size,
        r.photons.rays_per_voxel2,
        r.photons.step_voxels,
        r.view_step_voxels,
        r.samples_per_axis
    );
    s.push_str("| scene | setting | Δs | viewport | filter | precision | light | gradient | beams per texel (light grid) | planes | GPU ms | rel. L1 | RMSE | peak Δ px | |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    let front = front_rows(rows);
    for (row, star) in rows.iter().zip(front) {
        let t = &row.setting;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {}² | {} | {} | {} | {} | {} ({}×{}) | {} | {:.1} ({:.1}–{:.1}) | {:.4} | {:.4} | {:.1} | {} |",
            row.scene,
            t.label,
            t.sample_distance,
            t.size,
            on(t.light_filter),
            t.precision.name(),
            light(t),
            t.gradient.name(),
            t.beams_per_texel,
            row.light_grid[0],
            row.light_grid[1],
            row.planes,
            row.ms_median,
            row.ms_min,
            row.ms_max,
            row.error.rel_l1,
            row.error.rmse,
            row.error.peak_px,
            if star { "★" } else { "" }
        );
    }
    let mut scattering: Vec<&str> = rows.iter().filter(|r| r.scatters).map(|r| r.scene.as_str()).collect();
    scattering.dedup();
    if !scattering.is_empty() {
        let _ = writeln!(
            s,
            "\nThe particles of {} scatter light, which the reference does not model (its photons are \
             absorbed, never scattered): their rows count the scattered light as error. `caustica bench \
             --scatter` measures it against a Monte Carlo reference that has it.",
            scattering.join(", ")
        );
    }
    std::fs::write(path, s).map_err(|e| e.to_string())
}

pub fn write_csv(path: &Path, rows: &[Row]) -> Result<(), String> {
    let mut s = String::from(
        "scene,setting,sample_distance,viewport,light_filter,precision,intensity_correction,gradient,planes,ms_median,ms_min,ms_max,rel_l1,rmse,peak_px,pareto,beams_per_texel,light_grid_x,light_grid_y,light_transport\n",
    );
    let front = front_rows(rows);
    for (row, star) in rows.iter().zip(front) {
        let t = &row.setting;
        let _ = writeln!(
            s,
            "{},\"{}\",{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.6},{:.6},{:.2},{},{},{},{},{}",
            row.scene,
            t.label,
            t.sample_distance,
            t.size,
            t.light_filter,
            t.precision.name(),
            t.intensity_correction,
            t.gradient.name(),
            row.planes,
            row.ms_median,
            row.ms_min,
            row.ms_max,
            row.error.rel_l1,
            row.error.rmse,
            row.error.peak_px,
            star,
            t.beams_per_texel,
            row.light_grid[0],
            row.light_grid[1],
            t.light_transport.name()
        );
    }
    std::fs::write(path, s).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::super::{ImageError, Plan, Row, Setting};

    fn row(scene: &str, scatters: bool) -> Row {
        Row {
            scene: scene.into(),
            setting: Setting::base(128),
            planes: 60,
            light_grid: [64, 64],
            scatters,
            ms_median: 100.0,
            ms_min: 90.0,
            ms_max: 110.0,
            error: ImageError {
                rel_l1: 0.05,
                rmse: 0.06,
                peak_px: 1.0,
            },
        }
    }

    #[test]
    fn the_table_says_which_scenes_scatter_light_the_reference_leaves_out() {
        let dir = std::env::temp_dir().join(format!("caustica-report-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bench.md");
        let plan = Plan::quick(vec!["ball-lens".into(), "milk-glass".into()]);
        let rows = [
            row("ball-lens", false),
            row("milk-glass", true),
            row("milk-glass", true),
        ];
        super::write_markdown(&path, &rows, "test", &plan).unwrap();
        let md = std::fs::read_to_string(&path).unwrap();
        let note: Vec<&str> = md.lines().filter(|l| l.contains("scatter light")).collect();
        assert_eq!(note.len(), 1, "{md}");
        assert!(note[0].starts_with("The particles of milk-glass scatter light"), "{md}");
        super::write_markdown(&path, &rows[..1], "test", &plan).unwrap();
        let md = std::fs::read_to_string(&path).unwrap();
        assert!(!md.contains("scatter light"), "{md}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
