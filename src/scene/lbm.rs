//! Settings of the lattice-Boltzmann multiple scattering (`quality.multiple_scattering =
//! "lbm"`, `[quality.lbm]` in a scene file) and their range checks.

use serde::{Deserialize, Serialize};

/// Largest illumination-grid cell, in voxels per edge: beyond it the grid cannot resolve a
/// diffusion length of a few voxels, and the deposit's sub-samples (cell_voxels³ per cell)
/// make each cell's work large.
pub const MAX_LBM_CELL_VOXELS: u32 = 16;
/// Most lattice steps one render may take.
pub const MAX_LBM_ITERATIONS: u32 = 100_000;

/// The illumination grid and when its diffusion counts as converged.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LbmSettings {
    /// Voxels per edge of one illumination-grid cell (the grid is this many times coarser
    /// than the volume along each axis).
    pub cell_voxels: u32,
    /// Relative change of the fluence per step, Σ|φₙ − φₙ₋₁| / Σφₙ, under which the
    /// diffusion stops.
    pub residual: f32,
    /// Steps after which it stops regardless (the render reports the residual reached).
    pub max_iterations: u32,
}

impl Default for LbmSettings {
    fn default() -> Self {
        LbmSettings {
            cell_voxels: 2,
            residual: 1e-4,
            max_iterations: 4000,
        }
    }
}

impl LbmSettings {
    pub fn is_default(&self) -> bool {
        *self == LbmSettings::default()
    }

    /// The first setting out of range, as a message naming it.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_LBM_CELL_VOXELS).contains(&self.cell_voxels) {
            return Err(format!(
                "quality.lbm.cell_voxels {} must be in [1, {MAX_LBM_CELL_VOXELS}]",
                self.cell_voxels
            ));
        }
        if !(self.residual.is_finite() && self.residual > 0.0 && self.residual <= 0.1) {
            return Err(format!("quality.lbm.residual {} must be in (0, 0.1]", self.residual));
        }
        if !(1..=MAX_LBM_ITERATIONS).contains(&self.max_iterations) {
            return Err(format!(
                "quality.lbm.max_iterations {} must be in [1, {MAX_LBM_ITERATIONS}]",
                self.max_iterations
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_lbm_settings_are_named() {
        assert!(LbmSettings::default().check().is_ok());
        let cases: [(&str, LbmSettings); 5] = [
            (
                "cell_voxels",
                LbmSettings {
                    cell_voxels: 0,
                    ..Default::default()
                },
            ),
            (
                "cell_voxels",
                LbmSettings {
                    cell_voxels: 17,
                    ..Default::default()
                },
            ),
            (
                "residual",
                LbmSettings {
                    residual: 0.0,
                    ..Default::default()
                },
            ),
            (
                "residual",
                LbmSettings {
                    residual: f32::NAN,
                    ..Default::default()
                },
            ),
            (
                "max_iterations",
                LbmSettings {
                    max_iterations: 0,
                    ..Default::default()
                },
            ),
        ];
        for (name, s) in cases {
            let err = s.check().expect_err(name);
            assert!(err.contains(&format!("quality.lbm.{name}")), "{err}");
        }
    }

    #[test]
    fn lbm_settings_read_from_a_scene_file() {
        let q: crate::scene::Quality =
            toml::from_str("multiple_scattering = \"lbm\"\n[lbm]\ncell_voxels = 4\nresidual = 1e-3").unwrap();
        assert_eq!(q.lbm.cell_voxels, 4);
        assert_eq!(q.lbm.residual, 1e-3);
        assert_eq!(q.lbm.max_iterations, LbmSettings::default().max_iterations);
        assert!(toml::from_str::<crate::scene::Quality>("[lbm]\ncells = 4").is_err());
        // Left out of written scenes at the defaults.
        let written = toml::to_string(&crate::scene::Quality::default()).unwrap();
        assert!(!written.contains("lbm"), "{written}");
    }
}
