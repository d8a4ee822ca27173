//! WGSL → SPIR-V with naga, one specialised module per set of `override` constants.
//!
//! Overrides are resolved by naga (`process_overrides`) before SPIR-V is written, so each
//! feature variant is a separate, fully constant-folded module: disabled features cost nothing.

use naga::back::spv;
use naga::valid::{Capabilities, ValidationFlags, Validator};

use super::GpuError;

/// A parsed and validated WGSL module, ready to be specialised.
pub struct ShaderSource {
    pub name: String,
    module: naga::Module,
    info: naga::valid::ModuleInfo,
}

fn validator() -> Validator {
    Validator::new(
        ValidationFlags::all(),
        // pack2x16float / unpack2x16float keep the 16-bit state; SPIR-V has them as
        // GLSL.std.450 instructions on 32-bit values, available on every Vulkan device.
        Capabilities::IMMEDIATES | Capabilities::SHADER_FLOAT16_IN_FLOAT32,
    )
}

impl ShaderSource {
    /// Parses and validates WGSL. Errors carry naga's annotated message.
    pub fn parse(name: &str, wgsl: &str) -> Result<Self, GpuError> {
        let module = naga::front::wgsl::parse_str(wgsl).map_err(|e| GpuError::Shader {
            name: name.into(),
            message: e.emit_to_string_with_path(wgsl, name),
        })?;
        let info = validator().validate(&module).map_err(|e| GpuError::Shader {
            name: name.into(),
            message: e.emit_to_string_with_path(wgsl, name),
        })?;
        Ok(ShaderSource {
            name: name.into(),
            module,
            info,
        })
    }

    /// Names of the `override` constants the module declares.
    pub fn override_names(&self) -> Vec<String> {
        self.module
            .overrides
            .iter()
            .filter_map(|(_, o)| o.name.clone())
            .collect()
    }

    /// Resolves `constants` (bools as 0/1) and writes SPIR-V for the compute entry point `entry`.
    pub fn specialise(&self, entry: &str, constants: &[(&str, f64)]) -> Result<Vec<u32>, GpuError> {
        let err = |message: String| GpuError::Shader {
            name: format!("{}:{entry}", self.name),
            message,
        };
        let mut map = naga::back::PipelineConstants::default();
        for (k, v) in constants {
            map.insert((*k).to_string(), *v);
        }
        let (module, info) = naga::back::pipeline_constants::process_overrides(
            &self.module,
            &self.info,
            Some((naga::ShaderStage::Compute, entry)),
            &map,
        )
        .map_err(|e| err(format!("resolving overrides: {e}")))?;
        // Re-validate the specialised module: a variant can be invalid even when the generic
        // module is not (e.g. a constant-folded division by zero).
        let info = validator()
            .validate(&module)
            .map_err(|e| err(format!("specialised module invalid: {e:?}")))
            .map(|_| info)?;
        let mut options = spv::Options {
            lang_version: (1, 3),
            ..Default::default()
        };
        options.flags.remove(spv::WriterFlags::ADJUST_COORDINATE_SPACE);
        options.flags.remove(spv::WriterFlags::DEBUG);
        let pipeline = spv::PipelineOptions {
            shader_stage: naga::ShaderStage::Compute,
            entry_point: entry.into(),
        };
        spv::write_vec(&module, &info, &options, Some(&pipeline)).map_err(|e| err(format!("SPIR-V output: {e}")))
    }
}
