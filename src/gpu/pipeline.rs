//! Compute pipelines with one descriptor set laid out as the shader declares it, and
//! descriptor sets to bind to them, written by binding name.

use std::marker::PhantomData;
use std::sync::Arc;

use ash::vk;

use super::error::{vk_err, GpuError};
use super::shader::{Binding, BindingKind, CompiledShader, ShaderLayout};
use super::{Buffer, Context, Image, Sampler};

/// A compute pipeline, its layout and its descriptor-set layout, made from a
/// [`CompiledShader`]: bindings, immediate size and workgroup size are the shader's own.
pub struct ComputePipeline {
    ctx: Arc<Context>,
    pub(crate) raw: vk::Pipeline,
    pub(crate) pipeline_layout: vk::PipelineLayout,
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pub(crate) layout: ShaderLayout,
    workgroup_size: [u32; 3],
    pub label: String,
}

/// A shader module that lives only while its pipeline is created.
struct ShaderModule<'c> {
    ctx: &'c Context,
    raw: vk::ShaderModule,
}

impl Drop for ShaderModule<'_> {
    fn drop(&mut self) {
        // SAFETY: pipeline creation has returned; nothing else uses the module.
        unsafe { self.ctx.device.destroy_shader_module(self.raw, None) };
    }
}

impl ComputePipeline {
    pub fn new(ctx: &Arc<Context>, label: &str, shader: &CompiledShader) -> Result<Self, GpuError> {
        let d = &ctx.device;
        let push_constant_bytes = shader.layout.immediate_bytes;
        // Filled in step by step: on an error `Drop` destroys what was created (destroying a
        // null handle does nothing).
        let mut pipeline = ComputePipeline {
            ctx: ctx.clone(),
            raw: vk::Pipeline::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            set_layout: vk::DescriptorSetLayout::null(),
            layout: shader.layout.clone(),
            workgroup_size: shader.workgroup_size,
            label: label.into(),
        };
        let layout_bindings: Vec<_> = shader
            .layout
            .bindings
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
        // SAFETY: the create info references locals; the layout is destroyed in Drop.
        pipeline.set_layout = unsafe { d.create_descriptor_set_layout(&set_info, None) }
            .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
        let ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: push_constant_bytes,
        }];
        let set_layouts = [pipeline.set_layout];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if push_constant_bytes > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        // SAFETY: as above; the set layout is live.
        pipeline.pipeline_layout =
            unsafe { d.create_pipeline_layout(&layout_info, None) }.map_err(vk_err("vkCreatePipelineLayout"))?;
        let module_info = vk::ShaderModuleCreateInfo::default().code(&shader.spirv);
        let module = ShaderModule {
            ctx,
            // SAFETY: `spirv` is a complete SPIR-V module written by naga; the module is
            // destroyed when `module` goes out of scope.
            raw: unsafe { d.create_shader_module(&module_info, None) }.map_err(vk_err("vkCreateShaderModule"))?,
        };
        let entry_c = std::ffi::CString::new(shader.entry.as_str()).map_err(|_| GpuError::Shader {
            name: label.into(),
            message: "entry point name contains NUL".into(),
        })?;
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module.raw)
            .name(&entry_c);
        let info = vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(pipeline.pipeline_layout);
        // SAFETY: module, layout and entry name are live for the call.
        pipeline.raw = unsafe { d.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) }
            .map_err(|(_, e)| GpuError::vk("vkCreateComputePipelines", e))?[0];
        ctx.set_name(pipeline.raw, label);
        ctx.set_name(pipeline.pipeline_layout, &format!("{label} layout"));
        ctx.set_name(pipeline.set_layout, &format!("{label} set layout"));
        Ok(pipeline)
    }

    /// The bindings and immediate block the shader declares.
    pub fn layout(&self) -> &ShaderLayout {
        &self.layout
    }

    /// `@workgroup_size` of the shader.
    pub fn workgroup_size(&self) -> [u32; 3] {
        self.workgroup_size
    }

    /// Workgroups that cover `extent` invocations (rounded up per axis).
    pub fn groups_for(&self, extent: [u32; 3]) -> [u32; 3] {
        std::array::from_fn(|i| extent[i].div_ceil(self.workgroup_size[i].max(1)))
    }
}

impl Drop for ComputePipeline {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // possibly still in use by a hung submission: leak
        }
        // SAFETY: no submission using the pipeline is pending: recorders borrow it until
        // their submission completed; the descriptor sets made from its set layout borrow it
        // too. Null handles (a creation that failed half-way) are ignored by Vulkan.
        unsafe {
            let d = &self.ctx.device;
            d.destroy_pipeline(self.raw, None);
            d.destroy_pipeline_layout(self.pipeline_layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// A descriptor set (with its own small pool) laid out for one pipeline.
///
/// It borrows the pipeline and everything written into it for `'a`; [`DescriptorSet::write`]
/// takes `&mut self`, so a set cannot be rewritten while a recorder holds it.
///
/// ```no_run
/// # use std::sync::Arc;
/// # use caustica::gpu::{ComputePipeline, Context, DescriptorSet, GpuError, Image, Recorder, Resource};
/// # fn demo(ctx: &Arc<Context>, pipeline: &ComputePipeline, image: Image) -> Result<(), GpuError> {
/// let mut set = DescriptorSet::new(ctx, pipeline, "set")?;
/// set.write(&[("image_out", Resource::Image(&image))])?;
/// let mut rec = Recorder::new(ctx, "dispatch")?;
/// rec.dispatch(pipeline, &set, &[], [1, 1, 1])?;
/// rec.submit_and_wait()?;
/// drop(set);
/// drop(image);
/// # Ok(()) }
/// ```
///
/// Dropping an image the set refers to before the set is gone does not compile:
///
/// ```compile_fail,E0505
/// # use std::sync::Arc;
/// # use caustica::gpu::{ComputePipeline, Context, DescriptorSet, GpuError, Image, Recorder, Resource};
/// # fn demo(ctx: &Arc<Context>, pipeline: &ComputePipeline, image: Image) -> Result<(), GpuError> {
/// let mut set = DescriptorSet::new(ctx, pipeline, "set")?;
/// set.write(&[("image_out", Resource::Image(&image))])?;
/// drop(image); // error[E0505]: cannot move out of `image` because it is borrowed
/// let mut rec = Recorder::new(ctx, "dispatch")?;
/// rec.dispatch(pipeline, &set, &[], [1, 1, 1])?;
/// rec.submit_and_wait()
/// # }
/// ```
pub struct DescriptorSet<'a> {
    ctx: Arc<Context>,
    pipeline: &'a ComputePipeline,
    pool: vk::DescriptorPool,
    pub(crate) raw: vk::DescriptorSet,
    /// Which of the pipeline's bindings have been written.
    written: Vec<bool>,
    resources: PhantomData<&'a ()>,
}

/// A resource to write into a binding slot.
pub enum Resource<'a> {
    /// A uniform or storage buffer, bound whole.
    Buffer(&'a Buffer),
    /// A sampled or storage image (its full view).
    Image(&'a Image),
    Sampler(&'a Sampler),
}

impl<'a> DescriptorSet<'a> {
    pub fn new(ctx: &Arc<Context>, pipeline: &'a ComputePipeline, label: &str) -> Result<Self, GpuError> {
        let d = &ctx.device;
        let sizes: Vec<_> = pipeline
            .layout
            .bindings
            .iter()
            .map(|b| vk::DescriptorPoolSize {
                ty: b.kind.descriptor_type(),
                descriptor_count: 1,
            })
            .collect();
        let info = vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes);
        let mut set = DescriptorSet {
            ctx: ctx.clone(),
            pipeline,
            // SAFETY: valid create info; the pool (and with it the set) is destroyed in Drop.
            pool: unsafe { d.create_descriptor_pool(&info, None) }.map_err(vk_err("vkCreateDescriptorPool"))?,
            raw: vk::DescriptorSet::null(),
            written: vec![false; pipeline.layout.bindings.len()],
            resources: PhantomData,
        };
        let layouts = [pipeline.set_layout];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(set.pool)
            .set_layouts(&layouts);
        // SAFETY: the pool has room for one set of this layout, which the borrowed pipeline
        // keeps alive.
        set.raw = unsafe { d.allocate_descriptor_sets(&alloc) }.map_err(vk_err("vkAllocateDescriptorSets"))?[0];
        ctx.set_name(set.pool, &format!("{label} pool"));
        ctx.set_name(set.raw, label);
        Ok(set)
    }

    /// Writes one resource per binding, named as in the shader; errors on an unknown name, a
    /// resource of the wrong kind, or an image or buffer made without the usage (or, for a
    /// storage image, the format) the binding needs.
    pub fn write(&mut self, writes: &[(&str, Resource<'a>)]) -> Result<(), GpuError> {
        let mut buffer_infos = Vec::new();
        let mut image_infos = Vec::new();
        let mut positions = Vec::new();
        for (name, res) in writes {
            let err = |message: String| GpuError::Shader {
                name: self.pipeline.label.clone(),
                message: format!("binding {name}: {message}"),
            };
            let position = self
                .pipeline
                .layout
                .bindings
                .iter()
                .position(|b| b.name == *name)
                .ok_or_else(|| err("not declared by the shader".into()))?;
            let Binding { index, kind, .. } = self.pipeline.layout.bindings[position];
            let ty = kind.descriptor_type();
            let needs = |ok: bool, what: String| if ok { Ok(()) } else { Err(err(what)) };
            match (kind, res) {
                (BindingKind::UniformBuffer | BindingKind::StorageBuffer { .. }, Resource::Buffer(b)) => {
                    let usage = if kind == BindingKind::UniformBuffer {
                        vk::BufferUsageFlags::UNIFORM_BUFFER
                    } else {
                        vk::BufferUsageFlags::STORAGE_BUFFER
                    };
                    needs(b.usage.contains(usage), format!("{} lacks {usage:?} usage", b.label))?;
                    let info = vk::DescriptorBufferInfo {
                        buffer: b.raw,
                        offset: 0,
                        range: vk::WHOLE_SIZE,
                    };
                    buffer_infos.push((index, ty, info));
                }
                (BindingKind::SampledImage | BindingKind::StorageImage { .. }, Resource::Image(i)) => {
                    if let BindingKind::StorageImage { format, .. } = kind {
                        needs(
                            i.desc.usage.contains(vk::ImageUsageFlags::STORAGE),
                            format!("{} is not a storage image", i.desc.label),
                        )?;
                        needs(
                            i.desc.format == format,
                            format!(
                                "{} is {:?}, the shader declares {format:?}",
                                i.desc.label, i.desc.format
                            ),
                        )?;
                    } else {
                        needs(
                            i.desc.usage.contains(vk::ImageUsageFlags::SAMPLED),
                            format!("{} is not a sampled image", i.desc.label),
                        )?;
                    }
                    let info = vk::DescriptorImageInfo {
                        sampler: vk::Sampler::null(),
                        image_view: i.view,
                        image_layout: vk::ImageLayout::GENERAL,
                    };
                    image_infos.push((index, ty, info));
                }
                (BindingKind::Sampler, Resource::Sampler(s)) => image_infos.push((
                    index,
                    ty,
                    vk::DescriptorImageInfo {
                        sampler: s.raw,
                        image_view: vk::ImageView::null(),
                        image_layout: vk::ImageLayout::UNDEFINED,
                    },
                )),
                _ => return Err(err(format!("expects {kind:?}"))),
            }
            positions.push(position);
        }
        let mut vk_writes = Vec::new();
        for (index, ty, info) in &buffer_infos {
            vk_writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(self.raw)
                    .dst_binding(*index)
                    .descriptor_type(*ty)
                    .buffer_info(std::slice::from_ref(info)),
            );
        }
        for (index, ty, info) in &image_infos {
            vk_writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(self.raw)
                    .dst_binding(*index)
                    .descriptor_type(*ty)
                    .image_info(std::slice::from_ref(info)),
            );
        }
        // SAFETY: the written handles are borrowed for 'a, as long as the set lives; `&mut self`
        // means no recorder holds the set, so no pending command uses it; descriptor types
        // match the layout (checked above).
        unsafe { self.ctx.device.update_descriptor_sets(&vk_writes, &[]) };
        for p in positions {
            self.written[p] = true;
        }
        Ok(())
    }

    /// Checks that the set was made for `pipeline`, or for one laid out alike, and that every
    /// binding has been written (a dispatch must not read an empty descriptor).
    pub(crate) fn check_complete(&self, pipeline: &ComputePipeline) -> Result<(), GpuError> {
        let err = |message: String| GpuError::Shader {
            name: pipeline.label.clone(),
            message,
        };
        // A set serves any pipeline whose bindings and immediates are those it was made for
        // (the same shader file's entry points): Vulkan counts their layouts as compatible.
        if self.pipeline.set_layout != pipeline.set_layout && self.pipeline.layout != pipeline.layout {
            return Err(err(format!("descriptor set made for {}", self.pipeline.label)));
        }
        let missing: Vec<&str> = pipeline
            .layout
            .bindings
            .iter()
            .zip(&self.written)
            .filter(|(_, w)| !**w)
            .map(|(b, _)| b.name.as_str())
            .collect();
        if missing.is_empty() {
            Ok(())
        } else {
            Err(err(format!("bindings {} not written", missing.join(", "))))
        }
    }
}

impl Drop for DescriptorSet<'_> {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return;
        }
        // SAFETY: no pending submission uses the set: recorders borrow it until their
        // submission completed.
        unsafe { self.ctx.device.destroy_descriptor_pool(self.pool, None) };
    }
}
