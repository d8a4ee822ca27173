//! The WGSL sources (embedded from `shaders/`), their passes and bindings.

use crate::gpu::shader::ShaderSource;
use crate::gpu::{Binding, BindingKind, GpuError};
use crate::scene::Precision;

pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
pub const OPTICS: &str = include_str!("../../shaders/optics.wgsl");

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
            Pass::Propagate => "propagate.wgsl",
            Pass::Finish => "finish.wgsl",
        }
    }

    fn body(self) -> &'static str {
        match self {
            Pass::Init => include_str!("../../shaders/init.wgsl"),
            Pass::Propagate => include_str!("../../shaders/propagate.wgsl"),
            Pass::Finish => include_str!("../../shaders/finish.wgsl"),
        }
    }

    /// The full source: shared declarations, optics helpers, then the pass. The storage
    /// format of the write side of the state buffers follows `precision` (the read side is
    /// format-agnostic).
    pub fn source(self, precision: Precision) -> String {
        let common = match precision {
            Precision::F16 => COMMON.to_string(),
            Precision::F32 => COMMON.replace("rgba16float", "rgba32float"),
        };
        format!("{common}\n{OPTICS}\n{}", self.body())
    }

    pub fn parse(self, precision: Precision) -> Result<ShaderSource, GpuError> {
        ShaderSource::parse(self.file(), &self.source(precision))
    }
}

/// Binding slots, as declared in `shaders/common.wgsl`.
pub mod slot {
    pub const PARAMS: u32 = 0;
    pub const VOLUME: u32 = 1;
    pub const LINEAR_CLAMP: u32 = 2;
    pub const VOLUME_SAMPLER: u32 = 3;
    pub const ETA_VOLUME: u32 = 4;
    pub const PARTICLE_TABLE: u32 = 5;
    pub const MEDIUM_TABLE: u32 = 6;
    pub const ETA_TABLE: u32 = 7;
    pub const ENV: u32 = 8;
    pub const ENV_SAMPLER: u32 = 9;
    /// First of the six read-side state buffers; the write side follows at +6.
    pub const STATE_IN: u32 = 10;
    pub const STATE_OUT: u32 = 16;
    pub const IMAGE_OUT: u32 = 22;
}

pub fn bindings() -> Vec<Binding> {
    use BindingKind::*;
    let mut b = vec![
        Binding {
            index: slot::PARAMS,
            kind: StorageBuffer,
        },
        Binding {
            index: slot::VOLUME,
            kind: SampledImage,
        },
        Binding {
            index: slot::LINEAR_CLAMP,
            kind: Sampler,
        },
        Binding {
            index: slot::VOLUME_SAMPLER,
            kind: Sampler,
        },
        Binding {
            index: slot::ETA_VOLUME,
            kind: SampledImage,
        },
        Binding {
            index: slot::PARTICLE_TABLE,
            kind: SampledImage,
        },
        Binding {
            index: slot::MEDIUM_TABLE,
            kind: SampledImage,
        },
        Binding {
            index: slot::ETA_TABLE,
            kind: SampledImage,
        },
        Binding {
            index: slot::ENV,
            kind: SampledImage,
        },
        Binding {
            index: slot::ENV_SAMPLER,
            kind: Sampler,
        },
    ];
    for i in 0..6 {
        b.push(Binding {
            index: slot::STATE_IN + i,
            kind: SampledImage,
        });
        b.push(Binding {
            index: slot::STATE_OUT + i,
            kind: StorageImage,
        });
    }
    b.push(Binding {
        index: slot::IMAGE_OUT,
        kind: StorageImage,
    });
    b
}
