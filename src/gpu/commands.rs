//! One-shot command recording, submission with a fence, and GPU timestamps.

use std::sync::Arc;

use ash::vk;

use super::error::{vk_err, GpuError};
use super::{Buffer, ComputePipeline, Context, DescriptorSet, Image};

/// A timestamp query pool; read after the submission that wrote it was waited for.
pub struct Timestamps {
    ctx: Arc<Context>,
    pool: vk::QueryPool,
    count: u32,
}

impl Timestamps {
    pub fn new(ctx: &Arc<Context>, count: u32) -> Result<Self, GpuError> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(count);
        // SAFETY: valid create info; destroyed in Drop.
        let pool = unsafe { ctx.device.create_query_pool(&info, None) }.map_err(vk_err("vkCreateQueryPool"))?;
        ctx.set_name(pool, "timestamps");
        Ok(Timestamps {
            ctx: ctx.clone(),
            pool,
            count,
        })
    }

    /// Elapsed milliseconds between consecutive timestamps (`count - 1` values).
    pub fn read_ms(&self) -> Result<Vec<f64>, GpuError> {
        let mut ticks = vec![0u64; self.count as usize];
        // SAFETY: the pool was written by a submission that has completed.
        unsafe {
            self.ctx.device.get_query_pool_results(
                self.pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(vk_err("vkGetQueryPoolResults"))?;
        let bits = {
            // SAFETY: plain query on a valid physical device.
            let families = unsafe {
                self.ctx
                    .instance
                    .get_physical_device_queue_family_properties(self.ctx.physical)
            };
            families
                .get(self.ctx.queue_family as usize)
                .map(|f| f.timestamp_valid_bits)
                .unwrap_or(64)
        };
        let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        let period = self.ctx.timestamp_period_ns();
        Ok(ticks
            .windows(2)
            .map(|w| ((w[1].wrapping_sub(w[0])) & mask) as f64 * period / 1.0e6)
            .collect())
    }
}

impl Drop for Timestamps {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return;
        }
        // SAFETY: no pending submission uses the pool.
        unsafe { self.ctx.device.destroy_query_pool(self.pool, None) };
    }
}

/// Records one command buffer; [`Recorder::submit_and_wait`] runs it to completion.
pub struct Recorder {
    ctx: Arc<Context>,
    cmd: vk::CommandBuffer,
    submitted: bool,
}

impl Recorder {
    pub fn new(ctx: &Arc<Context>, label: &str) -> Result<Self, GpuError> {
        let pool = ctx.command_pool.lock().map_err(|_| GpuError::Allocation {
            what: "command pool".into(),
            message: "lock poisoned".into(),
        })?;
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(*pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is locked while allocating; the buffer is freed in Drop.
        let cmd = unsafe { ctx.device.allocate_command_buffers(&info) }.map_err(vk_err("vkAllocateCommandBuffers"))?[0];
        drop(pool);
        ctx.set_name(cmd, label);
        let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        let rec = Recorder {
            ctx: ctx.clone(),
            cmd,
            submitted: false,
        };
        // SAFETY: fresh command buffer in the initial state.
        unsafe { ctx.device.begin_command_buffer(cmd, &begin) }.map_err(vk_err("vkBeginCommandBuffer"))?;
        Ok(rec)
    }

    fn d(&self) -> &ash::Device {
        &self.ctx.device
    }

    /// Moves images from `UNDEFINED` (contents discarded) to `GENERAL`.
    pub fn init_layout(&mut self, images: &[&Image]) {
        let barriers: Vec<_> = images
            .iter()
            .map(|i| {
                vk::ImageMemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::empty())
                    .dst_access_mask(
                        vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                    )
                    .old_layout(vk::ImageLayout::UNDEFINED)
                    .new_layout(vk::ImageLayout::GENERAL)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .image(i.raw)
                    .subresource_range(Image::full_range(i.desc.mip_levels))
            })
            .collect();
        // SAFETY: recording state; images alive until the submission completes.
        unsafe {
            self.d().cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::TOP_OF_PIPE,
                vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &barriers,
            )
        };
    }

    /// Copies tightly packed mip levels from `src` into an image in `GENERAL` layout.
    /// `levels` lists (byte offset in `src`, extent) per mip level, starting at level 0.
    pub fn upload(&mut self, src: &Buffer, dst: &Image, levels: &[(u64, [u32; 3])]) {
        let regions: Vec<_> = levels
            .iter()
            .enumerate()
            .map(|(level, (offset, e))| vk::BufferImageCopy {
                buffer_offset: *offset,
                buffer_row_length: 0,
                buffer_image_height: 0,
                image_subresource: vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: level as u32,
                    base_array_layer: 0,
                    layer_count: 1,
                },
                image_offset: vk::Offset3D::default(),
                image_extent: vk::Extent3D {
                    width: e[0],
                    height: e[1],
                    depth: e[2],
                },
            })
            .collect();
        // SAFETY: recording state; buffer and image alive until completion.
        unsafe {
            self.d()
                .cmd_copy_buffer_to_image(self.cmd, src.raw, dst.raw, vk::ImageLayout::GENERAL, &regions)
        };
    }

    /// Makes transfer writes visible to compute shaders.
    pub fn transfer_to_compute(&mut self) {
        self.memory_barrier(
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_READ,
        );
    }

    /// Makes all compute writes visible to the next dispatch (reads and writes).
    pub fn compute_to_compute(&mut self) {
        self.memory_barrier(
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_WRITE,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
        );
    }

    /// Makes compute writes visible to a following copy.
    pub fn compute_to_transfer(&mut self) {
        self.memory_barrier(
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_WRITE,
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_READ,
        );
    }

    fn memory_barrier(
        &mut self,
        src_stage: vk::PipelineStageFlags,
        src: vk::AccessFlags,
        dst_stage: vk::PipelineStageFlags,
        dst: vk::AccessFlags,
    ) {
        let barrier = [vk::MemoryBarrier::default().src_access_mask(src).dst_access_mask(dst)];
        // SAFETY: recording state.
        unsafe {
            self.d().cmd_pipeline_barrier(
                self.cmd,
                src_stage,
                dst_stage,
                vk::DependencyFlags::empty(),
                &barrier,
                &[],
                &[],
            )
        };
    }

    /// Binds `pipeline` and `set`, pushes `push` and dispatches `groups` workgroups.
    pub fn dispatch(&mut self, pipeline: &ComputePipeline, set: &DescriptorSet, push: &[u8], groups: [u32; 3]) {
        let d = &self.ctx.device;
        // SAFETY: recording state; pipeline, layout and set alive until completion; push size
        // matches the layout's range (checked by the caller through `push_constant_bytes`).
        unsafe {
            d.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, pipeline.raw);
            d.cmd_bind_descriptor_sets(
                self.cmd,
                vk::PipelineBindPoint::COMPUTE,
                pipeline.layout,
                0,
                &[set.raw],
                &[],
            );
            if pipeline.push_constant_bytes > 0 {
                let n = (pipeline.push_constant_bytes as usize).min(push.len());
                d.cmd_push_constants(self.cmd, pipeline.layout, vk::ShaderStageFlags::COMPUTE, 0, &push[..n]);
            }
            d.cmd_dispatch(self.cmd, groups[0], groups[1], groups[2]);
        }
    }

    /// Fills a buffer with a repeated 32-bit word and makes the fill visible to compute shaders.
    pub fn fill(&mut self, dst: &Buffer, word: u32) {
        // SAFETY: recording state; the buffer is alive until completion and was created with
        // TRANSFER_DST (`Buffer::new_device`).
        unsafe { self.d().cmd_fill_buffer(self.cmd, dst.raw, 0, vk::WHOLE_SIZE, word) };
        self.memory_barrier(
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
        );
    }

    /// Copies the first `bytes` of `src` into `dst` and makes them visible to the host.
    pub fn copy_buffer(&mut self, src: &Buffer, dst: &Buffer, bytes: u64) {
        let region = vk::BufferCopy {
            src_offset: 0,
            dst_offset: 0,
            size: bytes,
        };
        // SAFETY: recording state; both buffers alive until completion; `bytes` fits both
        // (the caller sizes them).
        unsafe { self.d().cmd_copy_buffer(self.cmd, src.raw, dst.raw, &[region]) };
        self.memory_barrier(
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::HOST,
            vk::AccessFlags::HOST_READ,
        );
    }

    /// Copies mip 0 of a 2D image into a buffer, tightly packed.
    pub fn copy_to_buffer(&mut self, src: &Image, dst: &Buffer) {
        let region = vk::BufferImageCopy {
            buffer_offset: 0,
            buffer_row_length: 0,
            buffer_image_height: 0,
            image_subresource: vk::ImageSubresourceLayers {
                aspect_mask: vk::ImageAspectFlags::COLOR,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            },
            image_offset: vk::Offset3D::default(),
            image_extent: vk::Extent3D {
                width: src.desc.extent[0],
                height: src.desc.extent[1],
                depth: 1,
            },
        };
        // SAFETY: recording state; both resources alive until completion.
        unsafe {
            self.d()
                .cmd_copy_image_to_buffer(self.cmd, src.raw, vk::ImageLayout::GENERAL, dst.raw, &[region])
        };
        self.memory_barrier(
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::HOST,
            vk::AccessFlags::HOST_READ,
        );
    }

    pub fn reset_timestamps(&mut self, ts: &Timestamps) {
        // SAFETY: recording state; pool alive until completion.
        unsafe { self.d().cmd_reset_query_pool(self.cmd, ts.pool, 0, ts.count) };
    }

    pub fn timestamp(&mut self, ts: &Timestamps, index: u32) {
        // SAFETY: recording state; index < count is the caller's contract, clamped here.
        unsafe {
            self.d().cmd_write_timestamp(
                self.cmd,
                vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                ts.pool,
                index.min(ts.count.saturating_sub(1)),
            )
        };
    }

    /// Ends recording, submits, and blocks until the GPU is done or the context's fence
    /// timeout has passed ([`GpuError::Timeout`]; the device then counts as lost).
    pub fn submit_and_wait(mut self) -> Result<(), GpuError> {
        let ctx = self.ctx.clone();
        let d = &ctx.device;
        if ctx.is_lost() {
            return Err(GpuError::DeviceLost { call: "vkQueueSubmit" });
        }
        // SAFETY: the buffer is in the recording state; the fence is waited for and destroyed
        // before returning, so everything referenced by the commands outlives their execution.
        // On a timeout the fence and command buffer are leaked with the rest (see `Context`).
        unsafe {
            d.end_command_buffer(self.cmd).map_err(vk_err("vkEndCommandBuffer"))?;
            let (inject_lost, inject_hang) = ctx.injector.next_submission();
            if inject_lost {
                ctx.mark_lost(false);
                return Err(GpuError::DeviceLost { call: "vkQueueSubmit" });
            }
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .map_err(vk_err("vkCreateFence"))?;
            let cmds = [self.cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            if let Err(e) = d.queue_submit(ctx.queue, &submit, fence) {
                d.destroy_fence(fence, None);
                if e == vk::Result::ERROR_DEVICE_LOST {
                    ctx.mark_lost(false);
                }
                return Err(GpuError::vk("vkQueueSubmit", e));
            }
            self.submitted = true;
            let timeout_ns = if inject_hang {
                0
            } else {
                ctx.fence_timeout.as_nanos().min(u64::MAX as u128) as u64
            };
            match d.wait_for_fences(&[fence], true, timeout_ns) {
                Ok(()) => {
                    d.destroy_fence(fence, None);
                    Ok(())
                }
                Err(vk::Result::TIMEOUT) => {
                    ctx.mark_lost(true);
                    Err(GpuError::Timeout {
                        seconds: ctx.fence_timeout.as_secs(),
                    })
                }
                Err(e) => {
                    // Device lost: waiting is over (the spec makes fences signal), so the
                    // fence can go.
                    ctx.mark_lost(false);
                    d.destroy_fence(fence, None);
                    Err(GpuError::vk("vkWaitForFences", e))
                }
            }
        }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // possibly still executing: leak
        }
        if let Ok(pool) = self.ctx.command_pool.lock() {
            // SAFETY: the buffer is not pending: submit_and_wait waited, or it was never submitted.
            unsafe { self.ctx.device.free_command_buffers(*pool, &[self.cmd]) };
        }
        let _ = self.submitted;
    }
}
