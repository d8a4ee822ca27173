//! The WGSL sources (embedded from `shaders/`), their passes and bindings.

use crate::gpu::shader::ShaderSource;
use crate::gpu::{Binding, BindingKind, GpuError};

pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
pub const OPTICS: &str = include_str!("../../shaders/optics.wgsl");
/// The two light transports and the view rays, shared by every pass.
pub const BEAMS: &str = include_str!("../../shaders/beams.wgsl");
pub const BACKWARD: &str = include_str!("../../shaders/backward.wgsl");
pub const VIEW: &str = include_str!("../../shaders/view.wgsl");

/// The compute passes of one render.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pass {
    Init,
    Propagate,
    Finish,
}

impl Pass {
    pub const ALL: [Pass; 3] = [Pass::Init, Pass::Propagate, Pass::Finish];

    pub fn file(self) -> &'static str {
        match self {
            Pass::Init => "init.wgsl",
            Pass::Propagate => "sweep.wgsl",
            Pass::Finish => "finish.wgsl",
        }
    }

    fn body(self) -> &'static str {
        match self {
            Pass::Init => include_str!("../../shaders/init.wgsl"),
            Pass::Propagate => include_str!("../../shaders/sweep.wgsl"),
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
            return ["common.wgsl", "optics.wgsl", "beams.wgsl", "backward.wgsl", "view.wgsl", self.file()]
                .map(read)
                .join("\n");
        }
        format!("{COMMON}\n{OPTICS}\n{BEAMS}\n{BACKWARD}\n{VIEW}\n{}", self.body())
    }

    pub fn parse(self) -> Result<ShaderSource, GpuError> {
        ShaderSource::parse(self.file(), &self.source())
    }

    /// Workgroups per dispatch are counted in tiles of 8×8 invocations.
    pub const TILE: u32 = 8;
}

/// Binding slots, as declared in `shaders/common.wgsl`.
pub mod slot {
    pub const PARAMS: u32 = 0;
    pub const VOLUME: u32 = 1;
    pub const LINEAR_CLAMP: u32 = 2;
    pub const VOLUME_SAMPLER: u32 = 3;
    pub const GRADIENT: u32 = 4;
    pub const PARTICLE_TABLE: u32 = 5;
    pub const MEDIUM_TABLE: u32 = 6;
    pub const VIEW_LIGHT: u32 = 7;
    pub const ENV: u32 = 8;
    pub const ENV_SAMPLER: u32 = 9;
    pub const VIEW_RAY: u32 = 10;
    pub const VIEW_AUX: u32 = 11;
    pub const VIEW_COLOR: u32 = 12;
    pub const VIEW_MEDIUM: u32 = 13;
    pub const BEAM_POS: u32 = 14;
    pub const BEAM_AUX: u32 = 15;
    pub const BEAM_POWER: u32 = 16;
    pub const LIGHT_ACC: u32 = 17;
    pub const BACK_LIGHT: u32 = 18;
    pub const BACK_DIR: u32 = 19;
    pub const IMAGE_OUT: u32 = 20;
}

pub fn bindings() -> Vec<Binding> {
    use BindingKind::*;
    let kinds = [
        (slot::PARAMS, StorageBuffer),
        (slot::VOLUME, SampledImage),
        (slot::LINEAR_CLAMP, Sampler),
        (slot::VOLUME_SAMPLER, Sampler),
        (slot::GRADIENT, SampledImage),
        (slot::PARTICLE_TABLE, SampledImage),
        (slot::MEDIUM_TABLE, SampledImage),
        (slot::VIEW_LIGHT, StorageBuffer),
        (slot::ENV, SampledImage),
        (slot::ENV_SAMPLER, Sampler),
    ];
    let mut b: Vec<Binding> = kinds.iter().map(|&(index, kind)| Binding { index, kind }).collect();
    for index in slot::VIEW_RAY..=slot::IMAGE_OUT {
        b.push(Binding {
            index,
            kind: StorageBuffer,
        });
    }
    b
}
