//! WGSL → SPIR-V with naga, one specialised module per set of `override` constants, and the
//! pipeline layout read from the module itself (bindings, immediate size, workgroup size).
//!
//! Overrides are resolved by naga (`process_overrides`) before SPIR-V is written, so each
//! feature variant is a separate, fully constant-folded module: disabled features cost nothing.
//! What WGSL cannot make an override (the texel format of a storage texture) is set by name on
//! the parsed module: [`ShaderSource::set_storage_format`] retypes one `alias`.

use ash::vk;
use naga::back::spv;
use naga::valid::{Capabilities, ValidationFlags, Validator};

use super::GpuError;

/// What a binding slot holds, as the shader declares it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    /// `var<uniform>`.
    UniformBuffer,
    /// `var<storage, read>` or `var<storage, read_write>`.
    StorageBuffer { writable: bool },
    /// `texture_2d<f32>`, `texture_3d<f32>`, ...
    SampledImage,
    /// `texture_storage_*<format, access>`: written, read or both; views bound here must
    /// have `format`.
    StorageImage {
        format: vk::Format,
        readable: bool,
        writable: bool,
    },
    /// `sampler`.
    Sampler,
}

impl BindingKind {
    pub(crate) fn descriptor_type(self) -> vk::DescriptorType {
        match self {
            BindingKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            BindingKind::StorageBuffer { .. } => vk::DescriptorType::STORAGE_BUFFER,
            BindingKind::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
            BindingKind::StorageImage { .. } => vk::DescriptorType::STORAGE_IMAGE,
            BindingKind::Sampler => vk::DescriptorType::SAMPLER,
        }
    }
}

/// One slot of the pipeline's descriptor set (`@group(0) @binding(index) var name`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Binding {
    pub name: String,
    pub index: u32,
    pub kind: BindingKind,
}

/// The interface of a module as Vulkan sees it: one descriptor set and one push-constant
/// (immediate) block.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ShaderLayout {
    /// Every resource the module declares, in binding order.
    pub bindings: Vec<Binding>,
    /// Size of the `var<immediate>` block in bytes (0 without one).
    pub immediate_bytes: u32,
}

impl ShaderLayout {
    pub fn binding(&self, name: &str) -> Option<&Binding> {
        self.bindings.iter().find(|b| b.name == name)
    }
}

/// One specialised entry point: SPIR-V, its layout and its workgroup size.
#[derive(Clone, Debug)]
pub struct CompiledShader {
    /// `file:entry`, for messages and debug names.
    pub name: String,
    pub entry: String,
    pub spirv: Vec<u32>,
    pub layout: ShaderLayout,
    /// `@workgroup_size` of the entry point, after overrides.
    pub workgroup_size: [u32; 3],
}

/// A parsed and validated WGSL module, ready to be specialised.
pub struct ShaderSource {
    pub name: String,
    module: naga::Module,
    info: naga::valid::ModuleInfo,
    layout: ShaderLayout,
}

fn validator() -> Validator {
    Validator::new(ValidationFlags::all(), Capabilities::IMMEDIATES)
}

/// WGSL storage texel formats and their Vulkan formats.
const STORAGE_FORMATS: [(naga::StorageFormat, vk::Format); 28] = {
    use naga::StorageFormat as S;
    [
        (S::R8Unorm, vk::Format::R8_UNORM),
        (S::R8Snorm, vk::Format::R8_SNORM),
        (S::R8Uint, vk::Format::R8_UINT),
        (S::R8Sint, vk::Format::R8_SINT),
        (S::R16Uint, vk::Format::R16_UINT),
        (S::R16Sint, vk::Format::R16_SINT),
        (S::R16Float, vk::Format::R16_SFLOAT),
        (S::R16Unorm, vk::Format::R16_UNORM),
        (S::R32Uint, vk::Format::R32_UINT),
        (S::R32Sint, vk::Format::R32_SINT),
        (S::R32Float, vk::Format::R32_SFLOAT),
        (S::Rg8Unorm, vk::Format::R8G8_UNORM),
        (S::Rg16Float, vk::Format::R16G16_SFLOAT),
        (S::Rg32Uint, vk::Format::R32G32_UINT),
        (S::Rg32Sint, vk::Format::R32G32_SINT),
        (S::Rg32Float, vk::Format::R32G32_SFLOAT),
        (S::Rgba8Unorm, vk::Format::R8G8B8A8_UNORM),
        (S::Rgba8Snorm, vk::Format::R8G8B8A8_SNORM),
        (S::Rgba8Uint, vk::Format::R8G8B8A8_UINT),
        (S::Rgba8Sint, vk::Format::R8G8B8A8_SINT),
        (S::Rgba16Uint, vk::Format::R16G16B16A16_UINT),
        (S::Rgba16Sint, vk::Format::R16G16B16A16_SINT),
        (S::Rgba16Float, vk::Format::R16G16B16A16_SFLOAT),
        (S::Rgba16Unorm, vk::Format::R16G16B16A16_UNORM),
        (S::Rgba32Uint, vk::Format::R32G32B32A32_UINT),
        (S::Rgba32Sint, vk::Format::R32G32B32A32_SINT),
        (S::Rgba32Float, vk::Format::R32G32B32A32_SFLOAT),
        (S::R64Uint, vk::Format::R64_UINT),
    ]
};

/// The Vulkan format of a WGSL storage texel format.
fn vk_format(format: naga::StorageFormat) -> Option<vk::Format> {
    STORAGE_FORMATS.iter().find(|(n, _)| *n == format).map(|(_, v)| *v)
}

/// The WGSL storage texel format of a Vulkan format.
fn storage_format(format: vk::Format) -> Option<naga::StorageFormat> {
    STORAGE_FORMATS.iter().find(|(_, v)| *v == format).map(|(n, _)| *n)
}

/// Reads the bindings and the immediate block of `module`.
fn reflect(module: &naga::Module) -> Result<ShaderLayout, String> {
    let mut layout = ShaderLayout::default();
    for (_, var) in module.global_variables.iter() {
        let name = var.name.clone().unwrap_or_else(|| "(unnamed)".into());
        let inner = &module.types[var.ty].inner;
        if var.space == naga::AddressSpace::Immediate {
            let mut layouter = naga::proc::Layouter::default();
            layouter
                .update(module.to_ctx())
                .map_err(|e| format!("layout of {name}: {e}"))?;
            layout.immediate_bytes = layouter[var.ty].size;
            continue;
        }
        let Some(binding) = &var.binding else { continue };
        if binding.group != 0 {
            return Err(format!(
                "{name} is in @group({}); pipelines have one descriptor set, @group(0)",
                binding.group
            ));
        }
        let kind = match (var.space, inner) {
            (naga::AddressSpace::Uniform, _) => BindingKind::UniformBuffer,
            (naga::AddressSpace::Storage { access }, _) => BindingKind::StorageBuffer {
                writable: access.contains(naga::StorageAccess::STORE),
            },
            (naga::AddressSpace::Handle, naga::TypeInner::Sampler { .. }) => BindingKind::Sampler,
            (naga::AddressSpace::Handle, naga::TypeInner::Image { class, .. }) => match *class {
                naga::ImageClass::Sampled { .. } | naga::ImageClass::Depth { .. } => BindingKind::SampledImage,
                naga::ImageClass::Storage { format, access } => BindingKind::StorageImage {
                    format: vk_format(format).ok_or_else(|| format!("{name}: storage format {format:?}"))?,
                    readable: access.contains(naga::StorageAccess::LOAD),
                    writable: access.contains(naga::StorageAccess::STORE),
                },
                naga::ImageClass::External => return Err(format!("{name}: external textures are not supported")),
            },
            (space, inner) => return Err(format!("{name}: {space:?} {inner:?} is not a supported binding")),
        };
        if layout.bindings.iter().any(|b| b.index == binding.binding) {
            return Err(format!("@binding({}) is declared twice", binding.binding));
        }
        layout.bindings.push(Binding {
            name,
            index: binding.binding,
            kind,
        });
    }
    layout.bindings.sort_by_key(|b| b.index);
    Ok(layout)
}

impl ShaderSource {
    /// Parses and validates WGSL. Errors carry naga's annotated message.
    pub fn parse(name: &str, wgsl: &str) -> Result<Self, GpuError> {
        let module = naga::front::wgsl::parse_str(wgsl).map_err(|e| GpuError::Shader {
            name: name.into(),
            message: e.emit_to_string_with_path(wgsl, name),
        })?;
        Self::from_module(name, module, |e| e.emit_to_string_with_path(wgsl, name))
    }

    fn from_module(
        name: &str,
        module: naga::Module,
        describe: impl Fn(naga::WithSpan<naga::valid::ValidationError>) -> String,
    ) -> Result<Self, GpuError> {
        let err = |message: String| GpuError::Shader {
            name: name.into(),
            message,
        };
        let info = validator().validate(&module).map_err(|e| err(describe(e)))?;
        let layout = reflect(&module).map_err(err)?;
        Ok(ShaderSource {
            name: name.into(),
            module,
            info,
            layout,
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

    /// The bindings and immediate block every entry point of the module is laid out for.
    pub fn layout(&self) -> &ShaderLayout {
        &self.layout
    }

    /// Gives the storage texture type `alias` (a WGSL `alias` of a `texture_storage_*` type)
    /// the texel format `format`, in every binding declared with it. WGSL has no override
    /// for texel formats; this is the one explicit place a variant changes one.
    pub fn set_storage_format(self, alias: &str, format: vk::Format) -> Result<Self, GpuError> {
        let err = |message: String| GpuError::Shader {
            name: self.name.clone(),
            message,
        };
        let format = storage_format(format).ok_or_else(|| err(format!("{format:?} is not a storage format")))?;
        let found = self
            .module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(alias))
            .map(|(h, t)| (h, t.clone()));
        let Some((handle, mut ty)) = found else {
            return Err(err(format!("no type alias {alias}")));
        };
        match &mut ty.inner {
            naga::TypeInner::Image {
                class: naga::ImageClass::Storage { format: f, .. },
                ..
            } => *f = format,
            other => return Err(err(format!("{alias} is {other:?}, not a storage texture"))),
        }
        let mut module = self.module;
        if module.types.get(&ty).is_none() {
            module.types.replace(handle, ty);
        }
        let name = self.name;
        Self::from_module(&name, module, |e| format!("{e:?}"))
    }

    /// Resolves `constants` (bools as 0/1) and writes SPIR-V for the compute entry point `entry`.
    pub fn specialise(&self, entry: &str, constants: &[(&str, f64)]) -> Result<CompiledShader, GpuError> {
        let name = format!("{}:{entry}", self.name);
        let err = |message: String| GpuError::Shader {
            name: name.clone(),
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
        let workgroup_size = module
            .entry_points
            .iter()
            .find(|ep| ep.stage == naga::ShaderStage::Compute && ep.name == entry)
            .map(|ep| ep.workgroup_size)
            .ok_or_else(|| err("no such compute entry point".into()))?;
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
        let spirv = spv::write_vec(&module, &info, &options, Some(&pipeline))
            .map_err(|e| err(format!("SPIR-V output: {e}")))?;
        Ok(CompiledShader {
            name,
            entry: entry.into(),
            spirv,
            layout: self.layout.clone(),
            workgroup_size,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WGSL: &str = r#"
struct Block { a: vec4<f32>, b: u32 }
struct Push { index: u32, seed: u32 }
alias Target = texture_storage_2d<rgba16float, write>;
@group(0) @binding(3) var<uniform> params: Block;
@group(0) @binding(0) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(1) var<storage, read> weights: array<f32>;
@group(0) @binding(2) var image: texture_2d<f32>;
@group(0) @binding(4) var linear: sampler;
@group(0) @binding(5) var out: Target;
@group(0) @binding(6) var rw: texture_storage_2d<r32float, read_write>;
var<immediate> push: Push;
override WIDTH: u32 = 8u;

@compute @workgroup_size(WIDTH, 4, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    atomicAdd(&counts[gid.x], u32(weights[gid.y] + params.a.x) + push.index);
    let v = textureSampleLevel(image, linear, vec2<f32>(0.5), 0.0);
    textureStore(out, vec2<i32>(gid.xy), v);
    textureStore(rw, vec2<i32>(gid.xy), textureLoad(rw, vec2<i32>(gid.xy)));
}
"#;

    #[test]
    fn bindings_immediates_and_workgroup_size_come_from_the_module() {
        let source = ShaderSource::parse("test.wgsl", WGSL).unwrap();
        let kinds: Vec<_> = source
            .layout()
            .bindings
            .iter()
            .map(|b| (b.index, b.name.as_str(), b.kind))
            .collect();
        let storage = |format, readable| BindingKind::StorageImage {
            format,
            readable,
            writable: true,
        };
        assert_eq!(
            kinds,
            [
                (0, "counts", BindingKind::StorageBuffer { writable: true }),
                (1, "weights", BindingKind::StorageBuffer { writable: false }),
                (2, "image", BindingKind::SampledImage),
                (3, "params", BindingKind::UniformBuffer),
                (4, "linear", BindingKind::Sampler),
                (5, "out", storage(vk::Format::R16G16B16A16_SFLOAT, false)),
                (6, "rw", storage(vk::Format::R32_SFLOAT, true)),
            ]
        );
        assert_eq!(source.layout().immediate_bytes, 8);
        let compiled = source.specialise("main", &[]).unwrap();
        assert_eq!(compiled.workgroup_size, [8, 4, 1]);
        assert_eq!(
            source.specialise("main", &[("WIDTH", 16.0)]).unwrap().workgroup_size,
            [16, 4, 1]
        );
    }

    #[test]
    fn a_storage_alias_can_be_retyped_and_nothing_else() {
        let source = ShaderSource::parse("test.wgsl", WGSL).unwrap();
        let wide = source
            .set_storage_format("Target", vk::Format::R32G32B32A32_SFLOAT)
            .unwrap();
        let out = wide.layout().binding("out").unwrap();
        assert!(matches!(
            out.kind,
            BindingKind::StorageImage {
                format: vk::Format::R32G32B32A32_SFLOAT,
                ..
            }
        ));
        // The binding declared without the alias keeps its format.
        let rw = wide.layout().binding("rw").unwrap();
        assert!(matches!(
            rw.kind,
            BindingKind::StorageImage {
                format: vk::Format::R32_SFLOAT,
                ..
            }
        ));
        wide.specialise("main", &[]).unwrap();
        let again = ShaderSource::parse("test.wgsl", WGSL).unwrap();
        assert!(again
            .set_storage_format("Push", vk::Format::R32G32B32A32_SFLOAT)
            .is_err());
        let again = ShaderSource::parse("test.wgsl", WGSL).unwrap();
        assert!(again
            .set_storage_format("Missing", vk::Format::R32G32B32A32_SFLOAT)
            .is_err());
    }
}
