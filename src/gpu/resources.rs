//! RAII buffers, images and samplers created from labelled descriptors.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::error::{vk_err, GpuError};
use super::Context;

fn allocate(
    ctx: &Context,
    label: &str,
    requirements: vk::MemoryRequirements,
    location: MemoryLocation,
    linear: bool,
) -> Result<Allocation, GpuError> {
    let mut guard = ctx.allocator.lock().map_err(|_| GpuError::Allocation {
        what: label.into(),
        message: "allocator lock poisoned".into(),
    })?;
    let allocator = guard.as_mut().ok_or_else(|| GpuError::Allocation {
        what: label.into(),
        message: "allocator already destroyed".into(),
    })?;
    if ctx.injector.allocation_fails(label) {
        return Err(GpuError::OutOfDeviceMemory {
            what: label.to_string(),
            bytes: requirements.size,
        });
    }
    let allocation = allocator
        .allocate(&AllocationCreateDesc {
            name: label,
            requirements,
            location,
            linear,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        })
        .map_err(|e| match e {
            gpu_allocator::AllocationError::OutOfMemory => GpuError::OutOfDeviceMemory {
                what: label.to_string(),
                bytes: requirements.size,
            },
            e => GpuError::Allocation {
                what: label.to_string(),
                message: e.to_string(),
            },
        })?;
    ctx.allocator.meter.allocated(location, allocation.size());
    Ok(allocation)
}

/// Maps a failed create call, naming the resource when the driver is out of memory (some
/// drivers refuse an oversized buffer or image already at creation).
fn oom_of(label: &str, bytes: u64, call: &'static str, result: vk::Result) -> GpuError {
    match result {
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => GpuError::OutOfDeviceMemory {
            what: label.to_string(),
            bytes,
        },
        r => GpuError::vk(call, r),
    }
}

/// Bytes per texel of the formats this crate uses (for messages; 16 for any other).
fn texel_bytes(format: vk::Format) -> u64 {
    match format {
        vk::Format::R16_UNORM => 2,
        vk::Format::R32_SFLOAT => 4,
        vk::Format::R16G16B16A16_SFLOAT | vk::Format::R16G16B16A16_SNORM | vk::Format::R32G32_UINT => 8,
        _ => 16,
    }
}

fn free(ctx: &Context, allocation: Allocation, location: MemoryLocation) {
    ctx.allocator.meter.freed(location, allocation.size());
    if let Ok(mut guard) = ctx.allocator.lock() {
        if let Some(a) = guard.as_mut() {
            let _ = a.free(allocation);
        }
    }
}

/// A buffer with its memory. Host-visible buffers stay mapped.
pub struct Buffer {
    ctx: Arc<Context>,
    pub(crate) raw: vk::Buffer,
    allocation: Option<Allocation>,
    location: MemoryLocation,
    pub size: u64,
    pub usage: vk::BufferUsageFlags,
    pub label: String,
}

impl Buffer {
    /// A buffer the CPU writes and the GPU reads (uploads, uniforms).
    pub fn new_upload(
        ctx: &Arc<Context>,
        label: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
    ) -> Result<Self, GpuError> {
        Self::new(ctx, label, size, usage, MemoryLocation::CpuToGpu)
    }

    /// A storage buffer the CPU fills once with `bytes` for shaders to read (parameters,
    /// tables).
    pub fn new_storage_from(ctx: &Arc<Context>, label: &str, bytes: &[u8]) -> Result<Self, GpuError> {
        let mut b = Self::new_upload(ctx, label, bytes.len() as u64, vk::BufferUsageFlags::STORAGE_BUFFER)?;
        b.write(bytes)?;
        Ok(b)
    }

    /// A buffer only the GPU reads and writes (shader storage, fills, copies and indirect
    /// dispatch arguments). Larger than
    /// the device's storage buffer range is out of memory: the renderer then retries smaller.
    pub fn new_storage(ctx: &Arc<Context>, label: &str, size: u64) -> Result<Self, GpuError> {
        let range = ctx.limits().max_storage_buffer_range as u64;
        if size > range {
            return Err(GpuError::OutOfDeviceMemory {
                what: format!("{label} (larger than the device's storage buffer range of {range} bytes)"),
                bytes: size,
            });
        }
        Self::new(
            ctx,
            label,
            size,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::TRANSFER_SRC
                | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuOnly,
        )
    }

    /// A buffer the GPU writes and the CPU reads back.
    pub fn new_readback(ctx: &Arc<Context>, label: &str, size: u64) -> Result<Self, GpuError> {
        Self::new(
            ctx,
            label,
            size,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )
    }

    fn new(
        ctx: &Arc<Context>,
        label: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self, GpuError> {
        let mut buffer = Self::unbound(ctx, label, size, usage, location)?;
        buffer.bind(None)?;
        Ok(buffer)
    }

    /// The buffer, not yet bound to memory (`bind`).
    fn unbound(
        ctx: &Arc<Context>,
        label: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self, GpuError> {
        let info = vk::BufferCreateInfo::default()
            .size(size.max(4))
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // Filled in step by step: on an error `Drop` releases what was created (destroying a
        // null handle does nothing).
        let mut buffer = Buffer {
            ctx: ctx.clone(),
            raw: vk::Buffer::null(),
            allocation: None,
            location,
            size,
            usage,
            label: label.to_string(),
        };
        // SAFETY: valid create info; the buffer is destroyed in Drop.
        buffer.raw =
            unsafe { ctx.device.create_buffer(&info, None) }.map_err(|e| oom_of(label, size, "vkCreateBuffer", e))?;
        ctx.set_name(buffer.raw, label);
        Ok(buffer)
    }

    /// Allocates the buffer's memory and binds the buffer at its start. With `shared`, the
    /// requirements of another resource to be bound at the same place (an image over the
    /// same memory): the memory meets both; None where no memory type suits both.
    fn bind(&mut self, shared: Option<vk::MemoryRequirements>) -> Result<Option<&Allocation>, GpuError> {
        let d = &self.ctx.device;
        // SAFETY: plain query on the live buffer.
        let mut requirements = unsafe { d.get_buffer_memory_requirements(self.raw) };
        if let Some(other) = shared {
            requirements = vk::MemoryRequirements {
                size: requirements.size.max(other.size),
                alignment: requirements.alignment.max(other.alignment),
                memory_type_bits: requirements.memory_type_bits & other.memory_type_bits,
            };
            if requirements.memory_type_bits == 0 {
                return Ok(None);
            }
        }
        let allocation = self
            .allocation
            .insert(allocate(&self.ctx, &self.label, requirements, self.location, true)?);
        // SAFETY: the memory was allocated for this buffer's requirements and is bound to
        // nothing else but, with `shared`, the resource whose requirements it meets too; it
        // is freed after the buffer in Drop.
        unsafe { d.bind_buffer_memory(self.raw, allocation.memory(), allocation.offset()) }
            .map_err(vk_err("vkBindBufferMemory"))?;
        Ok(Some(allocation))
    }

    /// Bytes of memory the buffer holds (its allocation, at least `size`).
    pub fn bytes(&self) -> u64 {
        self.allocation.as_ref().map_or(0, Allocation::size)
    }

    /// Copies `bytes` to the start of a mapped buffer.
    pub fn write(&mut self, bytes: &[u8]) -> Result<(), GpuError> {
        self.write_at(0, bytes)
    }

    /// Copies `bytes` into a host-visible buffer at byte `offset`.
    pub fn write_at(&mut self, offset: u64, bytes: &[u8]) -> Result<(), GpuError> {
        let label = self.label.clone();
        let slice = self
            .allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .ok_or_else(|| GpuError::Allocation {
                what: label.clone(),
                message: "buffer is not host visible".into(),
            })?;
        let start = offset as usize;
        if start.checked_add(bytes.len()).is_none_or(|end| end > slice.len()) {
            return Err(GpuError::Allocation {
                what: label,
                message: format!("write of {} bytes at {offset} into {} bytes", bytes.len(), slice.len()),
            });
        }
        // Large copies (the volumes' staging, 139 MB on the CT head) are split over the
        // threads: one thread's copy does not use the memory's bandwidth (the CT head's
        // staging into a kept buffer in 21–28 ms on 2 cores instead of 31–36).
        use rayon::prelude::*;
        const CHUNK: usize = 4 << 20;
        slice[start..start + bytes.len()]
            .par_chunks_mut(CHUNK)
            .zip(bytes.par_chunks(CHUNK))
            .for_each(|(to, from)| to.copy_from_slice(from));
        Ok(())
    }

    /// The mapped contents of a host-visible buffer.
    pub fn read(&self) -> Result<&[u8], GpuError> {
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .map(|s| &s[..self.size as usize])
            .ok_or_else(|| GpuError::Allocation {
                what: self.label.clone(),
                message: "buffer is not host visible".into(),
            })
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // may still be in use by the hung submission: leak
        }
        // SAFETY: no pending submission uses the buffer: recorders borrow or hold it until
        // their submission completed (see the module contract).
        unsafe { self.ctx.device.destroy_buffer(self.raw, None) };
        if let Some(a) = self.allocation.take() {
            free(&self.ctx, a, self.location);
        }
    }
}

/// Describes an image: 2D when `depth == 1` and `dim3` is false; with `layers` a 2D array of
/// that many layers (its view a 2D array, as `texture_storage_2d_array` needs).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageDesc {
    pub label: String,
    pub format: vk::Format,
    pub extent: [u32; 3],
    pub dim3: bool,
    pub mip_levels: u32,
    pub layers: Option<u32>,
    pub usage: vk::ImageUsageFlags,
}

impl ImageDesc {
    /// A 2D image written by compute shaders and read by later dispatches or copied out.
    pub fn storage_2d(label: &str, format: vk::Format, width: u32, height: u32) -> Self {
        ImageDesc {
            label: label.into(),
            format,
            extent: [width, height, 1],
            dim3: false,
            mip_levels: 1,
            layers: None,
            usage: vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC,
        }
    }

    /// A 2D array of `layers` layers that compute shaders write and read back in later
    /// dispatches (state kept from plane to plane).
    pub fn storage_2d_array(label: &str, format: vk::Format, width: u32, height: u32, layers: u32) -> Self {
        ImageDesc {
            layers: Some(layers),
            usage: vk::ImageUsageFlags::STORAGE,
            ..Self::storage_2d(label, format, width, height)
        }
    }

    /// A sampled image filled once by a transfer (volumes, tables, environment maps).
    pub fn sampled(label: &str, format: vk::Format, extent: [u32; 3], dim3: bool, mip_levels: u32) -> Self {
        ImageDesc {
            label: label.into(),
            format,
            extent,
            dim3,
            mip_levels,
            layers: None,
            usage: vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
        }
    }
}

/// A device-local image and its full view, in `GENERAL` layout once recorded as initialised.
pub struct Image {
    ctx: Arc<Context>,
    pub(crate) raw: vk::Image,
    pub(crate) view: vk::ImageView,
    allocation: Option<Allocation>,
    pub desc: ImageDesc,
}

impl Image {
    pub fn new(ctx: &Arc<Context>, desc: ImageDesc) -> Result<Self, GpuError> {
        let limits = ctx.limits();
        let limit = if desc.dim3 {
            limits.max_image_dimension3_d
        } else {
            limits.max_image_dimension2_d
        };
        let largest = desc.extent.iter().copied().max().unwrap_or(1);
        let layers = desc.layers.unwrap_or(1);
        if layers > limits.max_image_array_layers {
            return Err(GpuError::Limit {
                what: format!("{} layers", desc.label),
                requested: layers as u64,
                limit: limits.max_image_array_layers as u64,
            });
        }
        if largest > limit {
            return Err(GpuError::Limit {
                what: format!("{} size", desc.label),
                requested: largest as u64,
                limit: limit as u64,
            });
        }
        let needed = if desc.usage.contains(vk::ImageUsageFlags::STORAGE) {
            vk::FormatFeatureFlags::STORAGE_IMAGE
        } else {
            vk::FormatFeatureFlags::SAMPLED_IMAGE
        };
        if !ctx.format_features(desc.format).contains(needed) {
            return Err(GpuError::Format(desc.format, "the requested image usage"));
        }
        let info = vk::ImageCreateInfo::default()
            .image_type(if desc.dim3 {
                vk::ImageType::TYPE_3D
            } else {
                vk::ImageType::TYPE_2D
            })
            .format(desc.format)
            .extent(vk::Extent3D {
                width: desc.extent[0],
                height: desc.extent[1],
                depth: desc.extent[2],
            })
            .mip_levels(desc.mip_levels)
            .array_layers(layers)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(desc.usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let d = &ctx.device;
        let bytes = desc.extent.iter().map(|e| *e as u64).product::<u64>() * layers as u64 * texel_bytes(desc.format);
        // Filled in step by step: on an error `Drop` releases what was created (destroying a
        // null handle does nothing).
        let mut image = Image {
            ctx: ctx.clone(),
            raw: vk::Image::null(),
            view: vk::ImageView::null(),
            allocation: None,
            desc,
        };
        let desc = &image.desc;
        // SAFETY: valid create info; the image is destroyed in Drop.
        image.raw =
            unsafe { d.create_image(&info, None) }.map_err(|e| oom_of(&desc.label, bytes, "vkCreateImage", e))?;
        // SAFETY: plain query on the live image.
        let requirements = unsafe { d.get_image_memory_requirements(image.raw) };
        let allocation = allocate(ctx, &desc.label, requirements, MemoryLocation::GpuOnly, false)?;
        let allocation = image.allocation.insert(allocation);
        // SAFETY: the memory was allocated for this image's requirements and is not bound to
        // anything else; it is freed after the image in Drop.
        unsafe { d.bind_image_memory(image.raw, allocation.memory(), allocation.offset()) }
            .map_err(vk_err("vkBindImageMemory"))?;
        image.create_view()?;
        Ok(image)
    }

    /// Creates the view of the whole image (3D, 2D array where `desc.layers` is set, else 2D)
    /// once the image is bound to memory, and names both.
    fn create_view(&mut self) -> Result<(), GpuError> {
        let desc = &self.desc;
        let view_info = vk::ImageViewCreateInfo::default()
            .image(self.raw)
            .view_type(if desc.dim3 {
                vk::ImageViewType::TYPE_3D
            } else if desc.layers.is_some() {
                vk::ImageViewType::TYPE_2D_ARRAY
            } else {
                vk::ImageViewType::TYPE_2D
            })
            .format(desc.format)
            .subresource_range(Self::full_range(desc.mip_levels));
        // SAFETY: the image is live and bound to memory; the view is destroyed in Drop.
        self.view =
            unsafe { self.ctx.device.create_image_view(&view_info, None) }.map_err(vk_err("vkCreateImageView"))?;
        self.ctx.set_name(self.raw, &desc.label);
        self.ctx.set_name(self.view, &format!("{} view", desc.label));
        Ok(())
    }

    pub(crate) fn full_range(mip_levels: u32) -> vk::ImageSubresourceRange {
        vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: 0,
            level_count: mip_levels,
            base_array_layer: 0,
            layer_count: vk::REMAINING_ARRAY_LAYERS,
        }
    }

    /// Bytes of device memory the image holds (its allocation: every mip level, the
    /// driver's layout and alignment included).
    pub fn bytes(&self) -> u64 {
        self.allocation.as_ref().map_or(0, Allocation::size)
    }

    pub fn width(&self) -> u32 {
        self.desc.extent[0]
    }

    pub fn height(&self) -> u32 {
        self.desc.extent[1]
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // may still be in use by the hung submission: leak
        }
        // SAFETY: no pending submission uses the image: recorders and descriptor sets borrow
        // it until their submission completed (see the module contract). Null handles (a
        // creation that failed half-way) are ignored by Vulkan.
        unsafe {
            self.ctx.device.destroy_image_view(self.view, None);
            self.ctx.device.destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            free(&self.ctx, a, MemoryLocation::GpuOnly);
        }
    }
}

/// Where the texels of a linear image lie in its memory (bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinearLayout {
    /// From one row of a layer to the next.
    pub row_pitch: u64,
    /// From one layer to the next.
    pub array_pitch: u64,
}

/// A storage buffer and a linear 2D-array image over the same memory: shaders write the
/// buffer (atomics, which images without returned values cannot replace) and read its words
/// back as texels of the image, laid out as [`LinearLayout`] says. A CPU driver gathers
/// texel fetches for all the invocations of a batch at once, where it loads a storage
/// buffer invocation by invocation.
pub struct AliasedBuffer {
    /// Dropped before the buffer whose memory it views.
    pub image: Image,
    pub buffer: Buffer,
    pub layout: LinearLayout,
}

/// The create info of a linear 2D array image that shaders read as a storage image.
fn linear_info(format: vk::Format, width: u32, height: u32, layers: u32) -> vk::ImageCreateInfo<'static> {
    vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(format)
        .extent(vk::Extent3D {
            width,
            height,
            depth: 1,
        })
        .mip_levels(1)
        .array_layers(layers)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::LINEAR)
        .usage(vk::ImageUsageFlags::STORAGE)
        .sharing_mode(vk::SharingMode::EXCLUSIVE)
        .initial_layout(vk::ImageLayout::UNDEFINED)
}

/// The layout of a live linear image: its first layer's pitches, with layer 0 at offset 0.
fn linear_layout_of(ctx: &Context, image: vk::Image, layers: u32) -> Option<LinearLayout> {
    let sub = |layer| vk::ImageSubresource {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        mip_level: 0,
        array_layer: layer,
    };
    // SAFETY: plain queries on a live linear image with these subresources.
    let first = unsafe { ctx.device.get_image_subresource_layout(image, sub(0)) };
    let pitch = if layers > 1 {
        // SAFETY: as above.
        unsafe { ctx.device.get_image_subresource_layout(image, sub(1)) }.offset
    } else {
        first.array_pitch.max(first.size)
    };
    (first.offset == 0 && first.row_pitch > 0 && pitch >= first.row_pitch).then_some(LinearLayout {
        row_pitch: first.row_pitch,
        array_pitch: pitch,
    })
}

impl AliasedBuffer {
    /// Whether the device can read a linear 2D array storage image of `format` this large.
    pub fn supported(ctx: &Context, format: vk::Format, width: u32, height: u32, layers: u32) -> bool {
        // SAFETY: plain queries on a valid physical device.
        let features =
            unsafe { ctx.instance.get_physical_device_format_properties(ctx.physical, format) }.linear_tiling_features;
        // SAFETY: as above.
        let properties = unsafe {
            ctx.instance.get_physical_device_image_format_properties(
                ctx.physical,
                format,
                vk::ImageType::TYPE_2D,
                vk::ImageTiling::LINEAR,
                vk::ImageUsageFlags::STORAGE,
                vk::ImageCreateFlags::empty(),
            )
        };
        features.contains(vk::FormatFeatureFlags::STORAGE_IMAGE)
            && properties.is_ok_and(|p| {
                width <= p.max_extent.width && height <= p.max_extent.height && layers <= p.max_array_layers
            })
    }

    /// The layout such an image of `format` would have, or None where the device cannot
    /// read one (then the buffer is read as a buffer).
    pub fn layout(ctx: &Context, format: vk::Format, width: u32, height: u32, layers: u32) -> Option<LinearLayout> {
        if !Self::supported(ctx, format, width, height, layers) {
            return None;
        }
        // SAFETY: valid create info; the image is destroyed below and never bound.
        let image = unsafe {
            ctx.device
                .create_image(&linear_info(format, width, height, layers), None)
        }
        .ok()?;
        let layout = linear_layout_of(ctx, image, layers);
        // SAFETY: created above, never used.
        unsafe { ctx.device.destroy_image(image, None) };
        layout
    }

    /// A storage buffer of `layers` layers of `width`×`height` texels of `format` and the
    /// image that views it, with the layout [`AliasedBuffer::layout`] gave.
    pub fn new(
        ctx: &Arc<Context>,
        label: &str,
        format: vk::Format,
        width: u32,
        height: u32,
        layers: u32,
    ) -> Result<Self, GpuError> {
        let unsupported = || GpuError::Format(format, "a linear image over a storage buffer");
        if !Self::supported(ctx, format, width, height, layers) {
            return Err(unsupported());
        }
        let d = &ctx.device;
        let mut image = Image {
            ctx: ctx.clone(),
            raw: vk::Image::null(),
            view: vk::ImageView::null(),
            allocation: None,
            desc: ImageDesc {
                label: format!("{label} image"),
                format,
                extent: [width, height, 1],
                dim3: false,
                mip_levels: 1,
                layers: Some(layers),
                usage: vk::ImageUsageFlags::STORAGE,
            },
        };
        let info = linear_info(format, width, height, layers);
        // SAFETY: valid create info; the image is destroyed in Drop.
        image.raw = unsafe { d.create_image(&info, None) }.map_err(vk_err("vkCreateImage"))?;
        let layout = linear_layout_of(ctx, image.raw, layers).ok_or_else(unsupported)?;
        // SAFETY: plain query on the live image.
        let image_req = unsafe { d.get_image_memory_requirements(image.raw) };
        let size = (layout.array_pitch * layers as u64).max(image_req.size);
        let range = ctx.limits().max_storage_buffer_range as u64;
        if size > range {
            return Err(GpuError::OutOfDeviceMemory {
                what: format!("{label} (larger than the device's storage buffer range of {range} bytes)"),
                bytes: size,
            });
        }
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::TRANSFER_DST
            | vk::BufferUsageFlags::TRANSFER_SRC;
        let mut buffer = Buffer::unbound(ctx, label, size, usage, MemoryLocation::GpuOnly)?;
        let allocation = buffer.bind(Some(image_req))?.ok_or_else(unsupported)?;
        // SAFETY: the memory meets the image's requirements too and the image is bound at its
        // start, as the buffer is; the buffer (which frees it) outlives the image (dropped
        // first, as the struct orders them).
        unsafe { d.bind_image_memory(image.raw, allocation.memory(), allocation.offset()) }
            .map_err(vk_err("vkBindImageMemory"))?;
        image.create_view()?;
        Ok(AliasedBuffer { image, buffer, layout })
    }
}

/// Sampler settings that matter to the renderer.
#[derive(Clone, Debug)]
pub struct SamplerDesc {
    pub label: String,
    pub linear: bool,
    pub mipmaps: bool,
    /// Address mode per axis (u, v, w).
    pub address: [vk::SamplerAddressMode; 3],
}

pub struct Sampler {
    ctx: Arc<Context>,
    pub(crate) raw: vk::Sampler,
}

impl Sampler {
    pub fn new(ctx: &Arc<Context>, desc: &SamplerDesc) -> Result<Self, GpuError> {
        let filter = if desc.linear {
            vk::Filter::LINEAR
        } else {
            vk::Filter::NEAREST
        };
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(filter)
            .min_filter(filter)
            .mipmap_mode(if desc.mipmaps {
                vk::SamplerMipmapMode::LINEAR
            } else {
                vk::SamplerMipmapMode::NEAREST
            })
            .address_mode_u(desc.address[0])
            .address_mode_v(desc.address[1])
            .address_mode_w(desc.address[2])
            .border_color(vk::BorderColor::FLOAT_TRANSPARENT_BLACK)
            .min_lod(0.0)
            .max_lod(if desc.mipmaps { vk::LOD_CLAMP_NONE } else { 0.0 });
        // SAFETY: valid create info; destroyed in Drop.
        let raw = unsafe { ctx.device.create_sampler(&info, None) }.map_err(vk_err("vkCreateSampler"))?;
        ctx.set_name(raw, &desc.label);
        Ok(Sampler { ctx: ctx.clone(), raw })
    }
}

impl Drop for Sampler {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return;
        }
        // SAFETY: no pending submission uses the sampler: descriptor sets borrow it until
        // their submission completed.
        unsafe { self.ctx.device.destroy_sampler(self.raw, None) };
    }
}
