//! `caustica bench --scatter`: the Monte Carlo reference's beam spread in Premoze et al.'s
//! Fig. 4 medium (g = 0.9, a = 0.0003 per mm) against their Eq. 1 and Eq. 18, and the spread
//! of all the light after a path length against its exact moments (CPU); then the renderer's
//! multiple-scattering modes on a narrow-beam slab against the Monte Carlo light, with their
//! GPU time ([`super::scatter_modes`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use crate::gpu::Context;

use crate::reference::scatter::{beam_widths, path_moments, transverse_moment, Centred, Slab};
use crate::transfer::scattering::{mean_square_angle, premoze_eq1, premoze_eq18, SpreadMoments};

use super::scatter_modes::{self, ModeRow, ModesPlan};
use super::{plot, write_err, BenchError};

/// Premoze et al.'s Fig. 4 medium.
const G: f64 = 0.9;
const ABSORPTION_PER_MM: f64 = 0.0003;
/// Light within this angle of the beam counts as going its way (their Monte Carlo's selection).
const FORWARD_RAD: f64 = 0.1;

/// What `bench --scatter` runs.
#[derive(Clone, Debug)]
pub struct ScatterPlan {
    /// Photons per medium of the Monte Carlo tables against Premoze et al.
    pub premoze_photons: u64,
    pub modes: ModesPlan,
}

impl ScatterPlan {
    pub fn full() -> ScatterPlan {
        ScatterPlan {
            premoze_photons: 200_000,
            modes: ModesPlan::full(),
        }
    }

    /// Minutes on a CPU driver.
    pub fn quick() -> ScatterPlan {
        ScatterPlan {
            premoze_photons: 20_000,
            modes: ModesPlan::quick(),
        }
    }
}

/// The results and where they were written.
pub struct ScatterReport {
    pub rows: Vec<ModeRow>,
    pub markdown: PathBuf,
    pub csv: PathBuf,
    pub plot: PathBuf,
}

/// Runs `plan` and writes `scatter.md`, `scatter.csv` (the modes' rows) and `scatter.png`
/// (their error against GPU time) into `out`.
pub fn run(ctx: Arc<Context>, plan: &ScatterPlan, out: &Path, progress: bool) -> Result<ScatterReport, BenchError> {
    std::fs::create_dir_all(out).map_err(|e| write_err(out)(e.to_string()))?;
    let device = super::device_label(&ctx);
    let rows = scatter_modes::run(ctx, &plan.modes, progress)?;
    let mut md = premoze_tables(plan.premoze_photons);
    md.push_str(&scatter_modes::markdown(&rows, &plan.modes, &device));
    md.push_str(&scatter_modes::crossing_orders(&plan.modes));
    let markdown = out.join("scatter.md");
    let csv = out.join("scatter.csv");
    let plot_path = out.join("scatter.png");
    std::fs::write(&markdown, &md).map_err(|e| write_err(&markdown)(e.to_string()))?;
    std::fs::write(&csv, scatter_modes::csv(&rows)).map_err(|e| write_err(&csv)(e.to_string()))?;
    // One series per mode, a point per quality setting; the profile's error, which every mode
    // has (the width's baseline plane already holds the lattice's glow in lbm).
    let summaries = scatter_modes::summarise(&rows, &plan.modes.variants);
    let mut modes: Vec<&str> = Vec::new();
    for s in &summaries {
        if !modes.contains(&s.variant.mode.name()) {
            modes.push(s.variant.mode.name());
        }
    }
    let series: Vec<plot::Series> = modes
        .iter()
        .map(|&name| plot::Series {
            name,
            points: summaries
                .iter()
                .filter(|s| s.variant.mode.name() == name)
                .map(|s| (s.gpu_ms, s.profile_l1.max(1e-4)))
                .collect(),
        })
        .collect();
    plot::write(
        &plot_path,
        &series,
        "GPU ms per render",
        "radial profile rel. L1 vs Monte Carlo (mean)",
        plot::Join::ParetoFront,
    )
    .map_err(write_err(&plot_path))?;
    Ok(ScatterReport {
        rows,
        markdown,
        csv,
        plot: plot_path,
    })
}

/// The Monte Carlo reference against Premoze et al.'s Eq. 1 and 18 (Markdown); `photons` per
/// medium.
pub fn premoze_tables(photons: u64) -> String {
    let mut md = String::new();
    let theta2 = mean_square_angle(G);
    let _ = writeln!(
        md,
        "# Beam spread: Monte Carlo reference against Premoze et al.\n\n\
         A pencil beam enters a slab (g = {G}, a = {ABSORPTION_PER_MM} /mm, ⟨θ²⟩ = 2(1 − g) = {theta2:.2}); \
         {photons} photons per b, seed 1. w² is the width per axis of the light within {FORWARD_RAD} rad of \
         the beam direction that has scattered at least once (fluence over layers 0.5 mm thick), \
         as Premoze et al.'s Monte Carlo selected it: from its median r² (a Gaussian's is 2 ln 2 w²), \
         robust against the few photons turned far out, and, for comparison, half its mean r². Eq. 1 is theirs as printed, Eq. 18 with their 2/3 \
         correction (Tessendorf's b⟨θ²⟩S³/24 without absorption).\n\n\
         | b /mm | S mm | b(1−g)S | MC w² (median) mm² | MC w² (mean) | Eq. 1 | Eq. 18 | MC / Eq. 18 | s |\n|---|---|---|---|---|---|---|---|---|"
    );
    for b in [0.05, 0.1, 0.2, 0.5] {
        let depths = [5.0, 10.0, 20.0, 40.0];
        let slab = Slab {
            thickness: 45.0,
            half_width: 400.0,
            absorption: ABSORPTION_PER_MM,
            scattering: b,
            g: G,
        };
        let start = Instant::now();
        let widths = beam_widths(&slab, &depths, 0.5, Some(FORWARD_RAD), photons, 1);
        let seconds = start.elapsed().as_secs_f64();
        for w in widths {
            let s = w.depth;
            let mc = w.scattered_median_r2 / (2.0 * std::f64::consts::LN_2);
            let mean = 0.5 * w.scattered_mean_r2;
            let (e1, e18) = (
                premoze_eq1(ABSORPTION_PER_MM, b, theta2, s),
                premoze_eq18(ABSORPTION_PER_MM, b, theta2, s),
            );
            let _ = writeln!(
                md,
                "| {b} | {s} | {:.2} | {mc:.4} | {mean:.4} | {e1:.4} | {e18:.4} | {:.2} | {seconds:.1} |",
                b * (1.0 - G) * s,
                mc / e18
            );
        }
    }
    let _ = writeln!(
        md,
        "\nAll the light after a path length s (time-resolved), E[x² + y²] against the exact moment \
         (4/3)∫₀ˢ(1 − e^(−b(1−g²)t))(1 − e^(−b(1−g)(s−t)))/(b(1−g)) dt, and E[(x² + y²)²] against the \
         fourth-moment recurrence (`transfer::scattering::SpreadMoments`) with the kurtosis across the beam \
         of the light that has scattered (1 for a Gaussian cloud), b = 1 /mm:\n\n\
         | s mm | b(1−g)s | MC E[r²] | ± | exact | MC / exact | MC E[r⁴] | ± | moments | kurtosis |\n\
         |---|---|---|---|---|---|---|---|---|---|"
    );
    let b = 1.0;
    let lengths = [1.0, 5.0, 10.0, 20.0, 50.0];
    let size = 51.0;
    let slab = Slab {
        thickness: 2.0 * size,
        half_width: size,
        absorption: ABSORPTION_PER_MM,
        scattering: b,
        g: G,
    };
    let moments = path_moments(&Centred(slab), &lengths, photons, 1);
    for m in moments {
        let exact = transverse_moment(b, G, m.path_length);
        let mut fourth = SpreadMoments::default();
        fourth.step(b, G, m.path_length);
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.3} | {:.3} | {exact:.3} | {:.3} | {:.4e} | {:.1e} | {:.4e} | {:.2} |",
            m.path_length,
            b * (1.0 - G) * m.path_length,
            m.mean_r2,
            m.mean_r2_error,
            m.mean_r2 / exact,
            m.mean_r4,
            m.mean_r4_error,
            fourth.r4,
            fourth.scattered_kurtosis()
        );
    }
    md
}
