//! The WGSL sources (embedded from `shaders/`) and their passes. Bindings, the immediate block
//! and workgroup sizes are read from the parsed modules (`gpu::ShaderLayout`), not kept here.

use crate::gpu::{GpuError, ShaderSource};

pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
pub const OPTICS: &str = include_str!("../../shaders/optics.wgsl");
/// The two light transports and the view rays, shared by every pass.
pub const BEAMS: &str = include_str!("../../shaders/beams.wgsl");
pub const BACKWARD: &str = include_str!("../../shaders/backward.wgsl");
pub const VIEW: &str = include_str!("../../shaders/view.wgsl");
/// The view's side of the lattice-Boltzmann mode (its solver is `render::lbm`).
pub const LBM_VIEW: &str = include_str!("../../shaders/lbm_view.wgsl");

/// The compute passes of one render: init, then per plane the light and the view rays, then
/// finish.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pass {
    Init,
    Light,
    View,
    /// Per view tile: clears the next plane's deposits and lists the tiles it needs (and the
    /// light tiles, when they are listed).
    Tiles,
    Finish,
    /// Beams with light tiles listed: the listed tiles whose beams and neighbours are all on
    /// the plane before.
    LightListed,
    /// Beams with light tiles listed: the listed tiles that start, or border tiles not stepped.
    LightEdge,
}

impl Pass {
    pub const ALL: [Pass; 7] = [
        Pass::Init,
        Pass::Light,
        Pass::View,
        Pass::Tiles,
        Pass::Finish,
        Pass::LightListed,
        Pass::LightEdge,
    ];

    pub fn file(self) -> &'static str {
        match self {
            Pass::Init => "init.wgsl",
            Pass::Light | Pass::View | Pass::Tiles | Pass::LightListed | Pass::LightEdge => "sweep.wgsl",
            Pass::Finish => "finish.wgsl",
        }
    }

    /// The compute entry point of the pass in its file.
    pub fn entry(self) -> &'static str {
        match self {
            Pass::Light => "light_main",
            Pass::View => "view_main",
            Pass::Tiles => "tiles_main",
            Pass::LightListed => "light_listed_main",
            Pass::LightEdge => "light_edge_main",
            Pass::Init | Pass::Finish => "main",
        }
    }

    fn body(self) -> &'static str {
        match self {
            Pass::Init => include_str!("../../shaders/init.wgsl"),
            Pass::Light | Pass::View | Pass::Tiles | Pass::LightListed | Pass::LightEdge => {
                include_str!("../../shaders/sweep.wgsl")
            }
            Pass::Finish => include_str!("../../shaders/finish.wgsl"),
        }
    }

    /// The full source: shared declarations, optics, the light transports, view rays, then the
    /// pass. Precision, transport and features are `override` constants. With the environment
    /// variable `CAUSTICA_SHADER_DIR` set, the files are read from that directory instead of
    /// the copies built into the binary (for working on the shaders without rebuilding).
    pub fn source(self) -> String {
        if let Some(dir) = std::env::var_os("CAUSTICA_SHADER_DIR") {
            let dir = std::path::PathBuf::from(dir);
            let read = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap_or_default();
            return [
                "common.wgsl",
                "optics.wgsl",
                "beams.wgsl",
                "backward.wgsl",
                "view.wgsl",
                "lbm_view.wgsl",
                self.file(),
            ]
            .map(read)
            .join("\n");
        }
        format!(
            "{COMMON}\n{OPTICS}\n{BEAMS}\n{BACKWARD}\n{VIEW}\n{LBM_VIEW}\n{}",
            self.body()
        )
    }

    pub fn parse(self) -> Result<ShaderSource, GpuError> {
        ShaderSource::parse(self.file(), &self.source())
    }

    /// Invocations per side of the square tiles the passes' workgroups work on (the `TILE`
    /// override in common.wgsl), and which the sweep lists, skips and ends as one: a GPU's
    /// warp or wavefront is 32 or 64 invocations wide, so a workgroup is no smaller there.
    pub const TILE: u32 = 8;

    /// The tile side on a CPU driver, where a workgroup is a loop over SIMD batches of 8
    /// invocations and smaller tiles follow the volume's outline more closely: fewer beams
    /// stepped before the light reaches anything or after no ray can read it, fewer rays
    /// stepped through empty space (`state::plan` picks it where its tiles fit a
    /// dispatch). The CT head at 256² (`compare.sh`): plain 485–502 → 387–403 ms, the same
    /// image to the bit.
    pub const CPU_TILE: u32 = 4;

    /// The side of the finish pass's workgroups (`@workgroup_size(8, 8, 1)` in finish.wgsl).
    pub const FINISH_TILE: u32 = 8;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tile_size_matches_the_shaders() {
        let line = format!("override TILE: u32 = {}u;", Pass::TILE);
        assert!(COMMON.contains(&line), "common.wgsl lacks '{line}'");
        let line = format!(
            "const LIST_PLANES: u32 = {}u;",
            crate::render::state::VIEW_PLANES_PER_PASS
        );
        assert!(BEAMS.contains(&line), "beams.wgsl lacks '{line}'");
        // The sweep's workgroups are a tile of either side (the render's `TILE` override);
        // the finish pass's are its own.
        for tile in [Pass::TILE, Pass::CPU_TILE] {
            for pass in [
                Pass::Init,
                Pass::Light,
                Pass::View,
                Pass::Tiles,
                Pass::LightListed,
                Pass::LightEdge,
                Pass::Finish,
            ] {
                let mut constants = crate::render::Features::default()
                    .constants(crate::render::DebugView::Image, crate::scene::Precision::F16);
                for c in constants.iter_mut().filter(|c| c.0 == "TILE") {
                    c.1 = tile as f64;
                }
                let compiled = pass.parse().unwrap().specialise(pass.entry(), &constants).unwrap();
                let expected = if pass == Pass::Finish {
                    [Pass::FINISH_TILE, Pass::FINISH_TILE, 1]
                } else {
                    [tile * tile, 1, 1]
                };
                assert_eq!(compiled.workgroup_size, expected, "{pass:?} at tile {tile}");
            }
        }
    }

    /// The first statement of each entry point in `source` (the line after `@compute` and the
    /// function's opening line).
    fn entry_starts(source: &str) -> Vec<(&str, &str)> {
        let lines: Vec<&str> = source.lines().collect();
        lines
            .iter()
            .enumerate()
            .filter(|(_, l)| l.starts_with("@compute"))
            .map(|(i, _)| (lines[i + 1], lines[i + 2].trim()))
            .collect()
    }

    /// The parameters are read from a private copy that every entry point makes before
    /// anything else (`P` in common.wgsl, `L` in lbm.wgsl); an entry point without it would
    /// read zeros, or, with the copy further down, pay for the loads it was made to avoid.
    #[test]
    fn every_entry_point_first_copies_its_parameters() {
        let mut entries = 0;
        for pass in [Pass::Init, Pass::Light, Pass::Finish] {
            for (entry, first) in entry_starts(pass.body()) {
                assert_eq!(first, "P = params;", "{entry}");
                entries += 1;
            }
        }
        for (entry, first) in entry_starts(crate::render::lbm::SOURCE) {
            assert_eq!(first, "L = lbm_params;", "{entry}");
            entries += 1;
        }
        // init, finish, the sweep's five (light, listed light, edge light, view, tiles), the
        // lattice's three.
        assert_eq!(entries, 10);
    }
}
