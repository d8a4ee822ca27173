//! Compute pipelines with one descriptor set, and descriptor sets to bind to them.

use std::sync::Arc;

use ash::vk;

use super::error::{vk_err, GpuError};
use super::{Buffer, Context, Image, Sampler};

/// What a binding slot holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    Uniform,
    /// A storage buffer (read-only or read-write, as the shader declares it).
    StorageBuffer,
    SampledImage,
    Sampler,
    StorageImage,
}

impl BindingKind {
    fn descriptor_type(self) -> vk::DescriptorType {
        match self {
            BindingKind::Uniform => vk::DescriptorType::UNIFORM_BUFFER,
            BindingKind::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            BindingKind::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
            BindingKind::Sampler => vk::DescriptorType::SAMPLER,
            BindingKind::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
        }
    }
}

/// One slot of the pipeline's descriptor set.
#[derive(Clone, Copy, Debug)]
pub struct Binding {
    pub index: u32,
    pub kind: BindingKind,
}

/// A compute pipeline, its layout and its descriptor-set layout.
pub struct ComputePipeline {
    ctx: Arc<Context>,
    pub(crate) raw: vk::Pipeline,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pub(crate) push_constant_bytes: u32,
    pub(crate) bindings: Vec<Binding>,
    pub label: String,
}

impl ComputePipeline {
    pub fn new(
        ctx: &Arc<Context>,
        label: &str,
        spirv: &[u32],
        entry: &str,
        bindings: &[Binding],
        push_constant_bytes: u32,
    ) -> Result<Self, GpuError> {
        let d = &ctx.device;
        let layout_bindings: Vec<_> = bindings
            .iter()
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.index)
                    .descriptor_type(b.kind.descriptor_type())
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings);
        // SAFETY: create infos reference locals; every object is destroyed in Drop or below.
        let set_layout = unsafe { d.create_descriptor_set_layout(&set_info, None) }
            .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
        let ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: push_constant_bytes,
        }];
        let set_layouts = [set_layout];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if push_constant_bytes > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        let layout = match unsafe { d.create_pipeline_layout(&layout_info, None) } {
            Ok(l) => l,
            Err(e) => {
                unsafe { d.destroy_descriptor_set_layout(set_layout, None) };
                return Err(GpuError::vk("vkCreatePipelineLayout", e));
            }
        };
        let module_info = vk::ShaderModuleCreateInfo::default().code(spirv);
        let module = match unsafe { d.create_shader_module(&module_info, None) } {
            Ok(m) => m,
            Err(e) => {
                unsafe {
                    d.destroy_pipeline_layout(layout, None);
                    d.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(GpuError::vk("vkCreateShaderModule", e));
            }
        };
        let entry_c = std::ffi::CString::new(entry).map_err(|_| GpuError::Shader {
            name: label.into(),
            message: "entry point name contains NUL".into(),
        })?;
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(&entry_c);
        let info = vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout);
        let result = unsafe { d.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) };
        unsafe { d.destroy_shader_module(module, None) };
        let raw = match result {
            Ok(p) => p[0],
            Err((_, e)) => {
                unsafe {
                    d.destroy_pipeline_layout(layout, None);
                    d.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(GpuError::vk("vkCreateComputePipelines", e));
            }
        };
        ctx.set_name(raw, label);
        ctx.set_name(layout, &format!("{label} layout"));
        ctx.set_name(set_layout, &format!("{label} set layout"));
        Ok(ComputePipeline {
            ctx: ctx.clone(),
            raw,
            layout,
            set_layout,
            push_constant_bytes,
            bindings: bindings.to_vec(),
            label: label.into(),
        })
    }
}

impl Drop for ComputePipeline {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // possibly still in use by a hung submission: leak
        }
        // SAFETY: no submission using the pipeline is pending (module contract).
        unsafe {
            let d = &self.ctx.device;
            d.destroy_pipeline(self.raw, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// A descriptor set (with its own small pool) laid out for one pipeline.
pub struct DescriptorSet {
    ctx: Arc<Context>,
    pool: vk::DescriptorPool,
    pub(crate) raw: vk::DescriptorSet,
    bindings: Vec<Binding>,
}

/// A resource to write into a binding slot.
pub enum Resource<'a> {
    Buffer(&'a Buffer),
    Image(&'a Image),
    Sampler(&'a Sampler),
}

impl DescriptorSet {
    pub fn new(ctx: &Arc<Context>, pipeline: &ComputePipeline, label: &str) -> Result<Self, GpuError> {
        let d = &ctx.device;
        let sizes: Vec<_> = pipeline
            .bindings
            .iter()
            .map(|b| vk::DescriptorPoolSize {
                ty: b.kind.descriptor_type(),
                descriptor_count: 1,
            })
            .collect();
        let info = vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes);
        // SAFETY: valid create info; the pool (and with it the set) is destroyed in Drop.
        let pool = unsafe { d.create_descriptor_pool(&info, None) }.map_err(vk_err("vkCreateDescriptorPool"))?;
        let layouts = [pipeline.set_layout];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        let raw = match unsafe { d.allocate_descriptor_sets(&alloc) } {
            Ok(s) => s[0],
            Err(e) => {
                unsafe { d.destroy_descriptor_pool(pool, None) };
                return Err(GpuError::vk("vkAllocateDescriptorSets", e));
            }
        };
        ctx.set_name(pool, &format!("{label} pool"));
        ctx.set_name(raw, label);
        Ok(DescriptorSet {
            ctx: ctx.clone(),
            pool,
            raw,
            bindings: pipeline.bindings.clone(),
        })
    }

    /// Writes one resource per binding slot; panics never, errors on a kind mismatch.
    pub fn write(&self, writes: &[(u32, Resource<'_>)]) -> Result<(), GpuError> {
        let mut buffer_infos = Vec::new();
        let mut image_infos = Vec::new();
        for (index, res) in writes {
            let kind = self
                .bindings
                .iter()
                .find(|b| b.index == *index)
                .map(|b| b.kind)
                .ok_or_else(|| GpuError::Shader {
                    name: "descriptor set".into(),
                    message: format!("no binding {index} in the layout"),
                })?;
            match (kind, res) {
                (BindingKind::Uniform | BindingKind::StorageBuffer, Resource::Buffer(b)) => buffer_infos.push((
                    *index,
                    kind,
                    vk::DescriptorBufferInfo {
                        buffer: b.raw,
                        offset: 0,
                        range: vk::WHOLE_SIZE,
                    },
                )),
                (BindingKind::SampledImage | BindingKind::StorageImage, Resource::Image(i)) => image_infos.push((
                    *index,
                    kind,
                    vk::DescriptorImageInfo {
                        sampler: vk::Sampler::null(),
                        image_view: i.view,
                        image_layout: vk::ImageLayout::GENERAL,
                    },
                )),
                (BindingKind::Sampler, Resource::Sampler(s)) => image_infos.push((
                    *index,
                    kind,
                    vk::DescriptorImageInfo {
                        sampler: s.raw,
                        image_view: vk::ImageView::null(),
                        image_layout: vk::ImageLayout::UNDEFINED,
                    },
                )),
                _ => {
                    return Err(GpuError::Shader {
                        name: "descriptor set".into(),
                        message: format!("binding {index} expects {kind:?}"),
                    })
                }
            }
        }
        let mut vk_writes = Vec::new();
        for (index, kind, info) in &buffer_infos {
            vk_writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(self.raw)
                    .dst_binding(*index)
                    .descriptor_type(kind.descriptor_type())
                    .buffer_info(std::slice::from_ref(info)),
            );
        }
        for (index, kind, info) in &image_infos {
            vk_writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(self.raw)
                    .dst_binding(*index)
                    .descriptor_type(kind.descriptor_type())
                    .image_info(std::slice::from_ref(info)),
            );
        }
        // SAFETY: all referenced handles are alive; the set is not in use by pending work.
        unsafe { self.ctx.device.update_descriptor_sets(&vk_writes, &[]) };
        Ok(())
    }
}

impl Drop for DescriptorSet {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return;
        }
        // SAFETY: no pending submission uses the set.
        unsafe { self.ctx.device.destroy_descriptor_pool(self.pool, None) };
    }
}
