//! The WGSL sources (embedded from `shaders/`) and their passes. Bindings, the immediate block
//! and workgroup sizes are read from the parsed modules (`gpu::ShaderLayout`), not kept here.

use crate::gpu::{Format, GpuError, ShaderSource};
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

    /// The full source: shared declarations, optics helpers, then the pass.
    pub fn source(self) -> String {
        format!("{COMMON}\n{OPTICS}\n{}", self.body())
    }

    /// The parsed pass at `precision`: the storage format of the write side of the light,
    /// colour and medium buffers (the alias [`COLOUR_STATE`]) follows it; the read side is
    /// format-agnostic.
    pub fn parse(self, precision: Precision) -> Result<ShaderSource, GpuError> {
        let source = ShaderSource::parse(self.file(), &self.source())?;
        match precision {
            Precision::F16 => Ok(source),
            Precision::F32 => source.set_storage_format(COLOUR_STATE, Format::R32G32B32A32_SFLOAT),
        }
    }
}

/// The WGSL alias of the storage texture type whose texel format follows the precision.
pub const COLOUR_STATE: &str = "ColourState";
