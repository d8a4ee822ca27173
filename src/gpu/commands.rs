//! One-shot command recording and submission with a fence.
//!
//! A [`Recorder<'r>`](Recorder) borrows every resource it records a use of for `'r`, and only
//! [`Recorder::submit_and_wait`] (which consumes it once the GPU is done) or dropping it
//! unsubmitted ends that borrow: safe code cannot drop, write or rebind what a pending command
//! uses. Staging buffers it is handed as an `Arc` are kept alive the same way.

use std::marker::PhantomData;
use std::sync::Arc;

use ash::vk;

use super::error::{vk_err, GpuError};
use super::{Buffer, ComputePipeline, Context, DescriptorSet, Image, Timestamps};

/// Records one command buffer; [`Recorder::submit_and_wait`] runs it to completion.
///
/// Every resource a command uses is borrowed for `'r`, so it outlives the recorder, and the
/// recorder is consumed only after the GPU has finished with it:
///
/// ```no_run
/// # use std::sync::Arc;
/// # use caustica::gpu::{Buffer, Context, Format, GpuError, Image, ImageDesc, Recorder};
/// # fn demo(ctx: &Arc<Context>) -> Result<(), GpuError> {
/// let image = Image::new(ctx, ImageDesc::storage_2d("target", Format::R32G32B32A32_SFLOAT, 8, 8))?;
/// let mut readback = Buffer::new_readback(ctx, "readback", 8 * 8 * 16)?;
/// let mut rec = Recorder::new(ctx, "clear and read")?;
/// rec.init_layout(&[&image]);
/// rec.copy_to_buffer(&image, &mut readback);
/// rec.submit_and_wait()?;
/// let _bytes = readback.read()?;
/// drop(image);
/// # Ok(()) }
/// ```
///
/// Dropping the image while the recorder still holds the copy does not compile, and neither
/// does reading the buffer the pending copy writes:
///
/// ```compile_fail,E0505
/// # use std::sync::Arc;
/// # use caustica::gpu::{Buffer, Context, Format, GpuError, Image, ImageDesc, Recorder};
/// # fn demo(ctx: &Arc<Context>) -> Result<(), GpuError> {
/// let image = Image::new(ctx, ImageDesc::storage_2d("target", Format::R32G32B32A32_SFLOAT, 8, 8))?;
/// let mut readback = Buffer::new_readback(ctx, "readback", 8 * 8 * 16)?;
/// let mut rec = Recorder::new(ctx, "clear and read")?;
/// rec.init_layout(&[&image]);
/// rec.copy_to_buffer(&image, &mut readback);
/// drop(image); // error[E0505]: cannot move out of `image` because it is borrowed
/// rec.submit_and_wait()?;
/// # Ok(()) }
/// ```
///
/// ```compile_fail,E0502
/// # use std::sync::Arc;
/// # use caustica::gpu::{Buffer, Context, Format, GpuError, Image, ImageDesc, Recorder};
/// # fn demo(ctx: &Arc<Context>) -> Result<(), GpuError> {
/// let image = Image::new(ctx, ImageDesc::storage_2d("target", Format::R32G32B32A32_SFLOAT, 8, 8))?;
/// let mut readback = Buffer::new_readback(ctx, "readback", 8 * 8 * 16)?;
/// let mut rec = Recorder::new(ctx, "clear and read")?;
/// rec.init_layout(&[&image]);
/// rec.copy_to_buffer(&image, &mut readback);
/// let _bytes = readback.read()?; // error[E0502]: the pending copy borrows it mutably
/// rec.submit_and_wait()?;
/// # Ok(()) }
/// ```
pub struct Recorder<'r> {
    ctx: Arc<Context>,
    cmd: vk::CommandBuffer,
    /// Buffers handed over as `Arc`s (staging): released with the recorder, after completion.
    held: Vec<Arc<Buffer>>,
    /// Dispatch commands recorded, direct and indirect (`dispatches`).
    dispatches: u32,
    /// The descriptor set bound last (null before any): a dispatch with the same set leaves
    /// it bound (`bind`).
    last_set: vk::DescriptorSet,
    /// The resources the recorded commands use are borrowed for `'r`.
    uses: PhantomData<&'r ()>,
}

impl<'r> Recorder<'r> {
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
            held: Vec::new(),
            dispatches: 0,
            last_set: vk::DescriptorSet::null(),
            uses: PhantomData,
        };
        // SAFETY: fresh command buffer in the initial state.
        unsafe { ctx.device.begin_command_buffer(cmd, &begin) }.map_err(vk_err("vkBeginCommandBuffer"))?;
        Ok(rec)
    }

    fn d(&self) -> &ash::Device {
        &self.ctx.device
    }

    /// Dispatch commands recorded so far, direct and indirect (an indirect one whose
    /// arguments say no workgroups counts too: a CPU driver still reads them).
    pub fn dispatches(&self) -> u32 {
        self.dispatches
    }

    /// Moves images from `UNDEFINED` (contents discarded) to `GENERAL`.
    pub fn init_layout(&mut self, images: &[&'r Image]) {
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
        // SAFETY: recording state; the images are borrowed for 'r, so they outlive the
        // submission.
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
    /// The recorder keeps `src` until the submission completes, so a staging buffer may be
    /// dropped by the caller at once.
    pub fn upload(&mut self, src: &Arc<Buffer>, dst: &'r Image, levels: &[(u64, [u32; 3])]) {
        if !self.held.iter().any(|h| Arc::ptr_eq(h, src)) {
            self.held.push(src.clone());
        }
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
        // SAFETY: recording state; `src` is held and `dst` borrowed until completion; the
        // regions lie within both (the caller's contract on `levels`, checked by validation).
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
        // SAFETY: recording state; a global memory barrier references no resource.
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

    /// Binds `pipeline` and `set` and pushes `push`, after the checks the types cannot make:
    /// `push` has the pipeline's immediate size, and `set` was made for this pipeline with
    /// every binding written.
    fn bind(&mut self, pipeline: &'r ComputePipeline, set: &'r DescriptorSet<'r>, push: &[u8]) -> Result<(), GpuError> {
        if push.len() != pipeline.layout.immediate_bytes as usize {
            return Err(GpuError::Shader {
                name: pipeline.label.clone(),
                message: format!(
                    "{} bytes of immediates given, the shader declares {}",
                    push.len(),
                    pipeline.layout.immediate_bytes
                ),
            });
        }
        set.check_complete(pipeline)?;
        let d = &self.ctx.device;
        // SAFETY: recording state; the pipeline and the set (with everything written into it)
        // are borrowed for 'r, so they outlive the submission; the set was allocated with this
        // pipeline's set layout and every binding is written (checked above); `push` has the
        // size of the layout's push-constant range (checked above).
        unsafe {
            d.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, pipeline.raw);
            // A set stays bound across pipelines whose layouts are defined alike, which
            // `check_complete` asks of any pipeline the set is used with: binding it again
            // would only make a CPU driver hand every resource to the shader anew.
            if set.raw != self.last_set {
                d.cmd_bind_descriptor_sets(
                    self.cmd,
                    vk::PipelineBindPoint::COMPUTE,
                    pipeline.pipeline_layout,
                    0,
                    &[set.raw],
                    &[],
                );
            }
            if !push.is_empty() {
                d.cmd_push_constants(
                    self.cmd,
                    pipeline.pipeline_layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    push,
                );
            }
        }
        self.last_set = set.raw;
        Ok(())
    }

    /// Binds `pipeline` and `set`, pushes `push` and dispatches `groups` workgroups.
    ///
    /// Fails when `push` is not the size of the pipeline's immediate block, or `set` was made
    /// for another pipeline or leaves a binding unwritten.
    pub fn dispatch(
        &mut self,
        pipeline: &'r ComputePipeline,
        set: &'r DescriptorSet<'r>,
        push: &[u8],
        groups: [u32; 3],
    ) -> Result<(), GpuError> {
        self.bind(pipeline, set, push)?;
        // SAFETY: recording state with a compute pipeline and its set bound above.
        unsafe { self.d().cmd_dispatch(self.cmd, groups[0], groups[1], groups[2]) };
        self.dispatches += 1;
        Ok(())
    }

    /// Like [`Recorder::dispatch`], with the workgroup counts read by the device from `args`
    /// at byte `offset` (three u32: x, y, z), written by an earlier dispatch; see
    /// [`Recorder::compute_to_indirect`]. Fails when the offset is not a multiple of 4 or the
    /// three words do not fit.
    pub fn dispatch_indirect(
        &mut self,
        pipeline: &'r ComputePipeline,
        set: &'r DescriptorSet<'r>,
        push: &[u8],
        args: &'r Buffer,
        offset: u64,
    ) -> Result<(), GpuError> {
        if offset % 4 != 0 || offset + 12 > args.size {
            return Err(GpuError::Shader {
                name: pipeline.label.clone(),
                message: format!("indirect arguments at byte {offset} of a {}-byte buffer", args.size),
            });
        }
        self.bind(pipeline, set, push)?;
        // SAFETY: recording state with a compute pipeline and its set bound above; `args` is
        // borrowed for 'r, holds the three words at `offset` (checked above) and was created
        // with INDIRECT_BUFFER usage (`Buffer::new_storage`).
        unsafe { self.d().cmd_dispatch_indirect(self.cmd, args.raw, offset) };
        self.dispatches += 1;
        Ok(())
    }

    /// Makes compute writes visible to the next dispatch, its indirect arguments included.
    pub fn compute_to_indirect(&mut self) {
        self.memory_barrier(
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_WRITE,
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::DRAW_INDIRECT,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::INDIRECT_COMMAND_READ,
        );
    }

    /// Fills `size` bytes of `dst` from byte `offset` with a repeated 32-bit word, after the
    /// compute work recorded before it has finished with them, and makes the fill visible to
    /// compute shaders. Fails when the range is not whole words inside the buffer.
    pub fn fill_range(&mut self, dst: &'r Buffer, offset: u64, size: u64, word: u32) -> Result<(), GpuError> {
        if offset % 4 != 0 || size % 4 != 0 || offset + size > dst.size {
            return Err(GpuError::Shader {
                name: "fill".into(),
                message: format!("{size} bytes at byte {offset} of a {}-byte buffer", dst.size),
            });
        }
        self.memory_barrier(
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
        );
        // SAFETY: recording state; the buffer is borrowed for 'r, so it outlives the
        // submission, was created with TRANSFER_DST (`Buffer::new_storage`), and the range is
        // whole words inside it (checked above).
        unsafe { self.d().cmd_fill_buffer(self.cmd, dst.raw, offset, size, word) };
        self.memory_barrier(
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
        );
        Ok(())
    }

    /// Fills a buffer with a repeated 32-bit word and makes the fill visible to compute shaders.
    pub fn fill(&mut self, dst: &'r Buffer, word: u32) {
        // SAFETY: recording state; the buffer is borrowed for 'r, so it outlives the
        // submission, and was created with TRANSFER_DST (`Buffer::new_storage`).
        unsafe { self.d().cmd_fill_buffer(self.cmd, dst.raw, 0, vk::WHOLE_SIZE, word) };
        self.memory_barrier(
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
        );
    }

    /// Copies the first `bytes` of `src` into `dst` and makes them visible to the host. The
    /// destination is borrowed mutably: the host cannot read it before the copy has executed.
    pub fn copy_buffer(&mut self, src: &'r Buffer, dst: &'r mut Buffer, bytes: u64) {
        let region = vk::BufferCopy {
            src_offset: 0,
            dst_offset: 0,
            size: bytes.min(src.size).min(dst.size),
        };
        // SAFETY: recording state; both buffers are borrowed for 'r and the region lies within
        // both (clamped above).
        unsafe { self.d().cmd_copy_buffer(self.cmd, src.raw, dst.raw, &[region]) };
        self.memory_barrier(
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::HOST,
            vk::AccessFlags::HOST_READ,
        );
    }

    /// Copies mip 0 of a 2D image into a buffer, tightly packed. The buffer is borrowed
    /// mutably: the host cannot read it before the copy has executed.
    pub fn copy_to_buffer(&mut self, src: &'r Image, dst: &'r mut Buffer) {
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
        // SAFETY: recording state; both resources are borrowed for 'r, so they outlive the
        // submission.
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

    pub fn reset_timestamps(&mut self, ts: &'r Timestamps) {
        // SAFETY: recording state; the pool is borrowed for 'r, so it outlives the submission.
        unsafe { self.d().cmd_reset_query_pool(self.cmd, ts.pool, 0, ts.count) };
    }

    pub fn timestamp(&mut self, ts: &'r Timestamps, index: u32) {
        // SAFETY: recording state; the pool is borrowed for 'r; the index is clamped to the
        // pool's size.
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
    /// timeout has passed ([`GpuError::Timeout`]; the device then counts as lost). Consuming
    /// the recorder ends its borrows only once the commands have executed (or, after a hang,
    /// once everything they use is leaked; see the module contract).
    pub fn submit_and_wait(self) -> Result<(), GpuError> {
        let ctx = self.ctx.clone();
        let d = &ctx.device;
        if ctx.is_lost() {
            return Err(GpuError::DeviceLost { call: "vkQueueSubmit" });
        }
        // SAFETY: the buffer is in the recording state; the fence is waited for and destroyed
        // before returning, so everything the commands borrow (for 'r, which outlasts `self`)
        // or the recorder holds outlives their execution. On a timeout the fence and command
        // buffer are leaked with the rest (see `Context`).
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

impl Drop for Recorder<'_> {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // possibly still executing: leak (held buffers leak in their own Drop)
        }
        if let Ok(pool) = self.ctx.command_pool.lock() {
            // SAFETY: the buffer is not pending: submit_and_wait waited, or it was never submitted.
            unsafe { self.ctx.device.free_command_buffers(*pool, &[self.cmd]) };
        }
    }
}
