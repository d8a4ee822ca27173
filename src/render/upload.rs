//! Scene data on the GPU: volume textures, pre-integrated tables, η table, environment map.

use std::cell::Cell;
use std::sync::Arc;

use half::f16;

use crate::gpu::{Buffer, Context, Format, GpuError, Image, ImageDesc, Recorder, Sampler, SamplerDesc};
use crate::transfer::{preintegrate, TransferFunctions, TABLE_SIZE};
use crate::volume::Volume;

use super::environment::EnvMap;

/// Entries of the η lookup table (the shaders interpolate linearly between them).
pub const ETA_TABLE_SIZE: usize = 1024;

type Levels = Vec<(u64, [u32; 3])>;

/// Everything sampled by the passes, uploaded once per render.
pub struct SceneTextures {
    pub volume: Image,
    pub eta_volume: Option<Image>,
    pub particle_table: Image,
    pub medium_table: Image,
    pub eta_table: Image,
    pub env: Image,
    pub env_levels: u32,
    pub linear_clamp: Sampler,
    pub volume_sampler: Sampler,
    pub env_sampler: Sampler,
}

/// The contents of freshly created [`SceneTextures`], staged for [`SceneTextures::record_upload`].
pub struct PendingUpload {
    staging: Arc<Buffer>,
    /// (index into [`SceneTextures::images`], (staging offset, extent) per mip level)
    uploads: Vec<(usize, Levels)>,
}

/// Collects byte blobs into one staging buffer with aligned offsets.
#[derive(Default)]
struct Staging {
    bytes: Vec<u8>,
}

impl Staging {
    fn push(&mut self, data: &[u8]) -> u64 {
        while self.bytes.len() % 16 != 0 {
            self.bytes.push(0);
        }
        let offset = self.bytes.len() as u64;
        self.bytes.extend_from_slice(data);
        offset
    }
}

/// 16-bit floats for the tables and the environment map, saturated at the largest finite
/// half (65504): a brighter pixel of an HDR environment image would otherwise become
/// infinite on the GPU.
fn halves(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values
        .flat_map(|v| f16::from_f32(v.min(f16::MAX.to_f32())).to_le_bytes())
        .collect()
}

fn volume_image(ctx: &Arc<Context>, label: &str, vol: &Volume) -> Result<Image, GpuError> {
    let extent = [vol.dims[0] as u32, vol.dims[1] as u32, vol.dims[2] as u32];
    Image::new(ctx, ImageDesc::sampled(label, Format::R16_UNORM, extent, true, 1))
}

impl SceneTextures {
    /// Creates the textures and stages their contents; [`SceneTextures::record_upload`]
    /// copies them in.
    pub fn upload(
        ctx: &Arc<Context>,
        volume: &Volume,
        window: [f32; 2],
        eta_volume: Option<(&Volume, [f32; 2])>,
        tf: &TransferFunctions,
        sample_distance: f32,
        env: Option<&EnvMap>,
    ) -> Result<(Self, PendingUpload), GpuError> {
        let mut staging = Staging::default();
        // (index into `images`, (staging offset, extent) per mip level)
        let mut uploads: Vec<(usize, Levels)> = Vec::new();
        let mut images: Vec<Image> = Vec::new();

        let vol_img = volume_image(ctx, "volume", volume)?;
        let bytes: Vec<u8> = bytemuck::cast_slice(&volume.normalized_u16(window)).to_vec();
        uploads.push((images.len(), vec![(staging.push(&bytes), vol_img.desc.extent)]));
        images.push(vol_img);

        let mut eta_index = None;
        if let Some((ev, w)) = eta_volume {
            let img = volume_image(ctx, "eta volume", ev)?;
            let bytes: Vec<u8> = bytemuck::cast_slice(&ev.normalized_u16(w)).to_vec();
            uploads.push((images.len(), vec![(staging.push(&bytes), img.desc.extent)]));
            eta_index = Some(images.len());
            images.push(img);
        }

        let tables = preintegrate(tf, sample_distance);
        let n = TABLE_SIZE as u32;
        for (label, data) in [("particle table", &tables.particle), ("medium table", &tables.medium)] {
            let img = Image::new(
                ctx,
                ImageDesc::sampled(label, Format::R16G16B16A16_SFLOAT, [n, n, 1], false, 1),
            )?;
            let offset = staging.push(&halves(data.iter().flatten().copied()));
            uploads.push((images.len(), vec![(offset, [n, n, 1])]));
            images.push(img);
        }

        let eta: Vec<f32> = (0..ETA_TABLE_SIZE)
            .map(|i| tf.eta.eval(i as f32 / (ETA_TABLE_SIZE - 1) as f32))
            .collect();
        let size = ETA_TABLE_SIZE as u32;
        let img = Image::new(
            ctx,
            ImageDesc::sampled("eta table", Format::R32_SFLOAT, [size, 1, 1], false, 1),
        )?;
        uploads.push((
            images.len(),
            vec![(staging.push(bytemuck::cast_slice(&eta)), [size, 1, 1])],
        ));
        images.push(img);

        let fallback;
        let env_levels: &[(u32, u32, Vec<[f32; 4]>)] = match env {
            Some(e) => &e.levels,
            None => {
                fallback = vec![(1u32, 1u32, vec![[0.0f32; 4]])];
                &fallback
            }
        };
        let (w0, h0) = (env_levels[0].0, env_levels[0].1);
        let img = Image::new(
            ctx,
            ImageDesc::sampled(
                "environment",
                Format::R16G16B16A16_SFLOAT,
                [w0, h0, 1],
                false,
                env_levels.len() as u32,
            ),
        )?;
        let levels = env_levels
            .iter()
            .map(|(w, h, px)| (staging.push(&halves(px.iter().flatten().copied())), [*w, *h, 1]))
            .collect();
        uploads.push((images.len(), levels));
        images.push(img);

        let mut buffer = Buffer::new_upload(
            ctx,
            "scene staging",
            staging.bytes.len() as u64,
            ash::vk::BufferUsageFlags::TRANSFER_SRC,
        )?;
        buffer.write(&staging.bytes)?;

        use ash::vk::SamplerAddressMode as A;
        let linear_clamp = Sampler::new(
            ctx,
            &SamplerDesc {
                label: "tables (linear, clamp to edge)".into(),
                linear: true,
                mipmaps: false,
                address: [A::CLAMP_TO_EDGE; 3],
            },
        )?;
        let volume_sampler = Sampler::new(
            ctx,
            &SamplerDesc {
                label: "volume (linear, zero outside)".into(),
                linear: true,
                mipmaps: false,
                address: [A::CLAMP_TO_BORDER; 3],
            },
        )?;
        let env_sampler = Sampler::new(
            ctx,
            &SamplerDesc {
                label: "environment (trilinear, wrap longitude)".into(),
                linear: true,
                mipmaps: true,
                address: [A::REPEAT, A::CLAMP_TO_EDGE, A::CLAMP_TO_EDGE],
            },
        )?;

        let mut it = images.into_iter();
        let volume = it.next().ok_or_else(missing)?;
        let eta_volume = if eta_index.is_some() { it.next() } else { None };
        let particle_table = it.next().ok_or_else(missing)?;
        let medium_table = it.next().ok_or_else(missing)?;
        let eta_table = it.next().ok_or_else(missing)?;
        let env = it.next().ok_or_else(missing)?;
        let textures = SceneTextures {
            volume,
            eta_volume,
            particle_table,
            medium_table,
            eta_table,
            env,
            env_levels: env_levels.len() as u32,
            linear_clamp,
            volume_sampler,
            env_sampler,
        };
        let pending = PendingUpload {
            staging: Arc::new(buffer),
            uploads,
        };
        Ok((textures, pending))
    }

    /// The images in the order [`PendingUpload`] indexes them (the order of creation).
    fn images(&self) -> Vec<&Image> {
        let mut images = vec![&self.volume];
        images.extend(self.eta_volume.as_ref());
        images.extend([&self.particle_table, &self.medium_table, &self.eta_table, &self.env]);
        images
    }

    /// Records the copy of the staged contents into the textures. The recorder keeps the
    /// staging memory until the copy has executed, then it goes.
    pub fn record_upload<'r>(&'r self, rec: &mut Recorder<'r>, pending: PendingUpload) {
        let images = self.images();
        rec.init_layout(&images);
        for (index, levels) in &pending.uploads {
            if let Some(image) = images.get(*index) {
                rec.upload(&pending.staging, image, levels);
            }
        }
        rec.transfer_to_compute();
    }
}

/// What the scene textures were made from. The volumes are compared by identity and kept
/// alive here, so a freed volume's address cannot be mistaken for a new one.
pub struct TexturesKey {
    volume: Arc<Volume>,
    eta_volume: Option<Arc<Volume>>,
    window: [f32; 2],
    tf: TransferFunctions,
    sample_distance: f32,
    environment: crate::scene::Environment,
}

impl TexturesKey {
    pub fn new(prepared: &super::PreparedScene, uses_eta_volume: bool) -> Self {
        TexturesKey {
            volume: prepared.volume.clone(),
            eta_volume: prepared.eta_volume.clone().filter(|_| uses_eta_volume),
            window: prepared.window(),
            tf: prepared.tf.clone(),
            sample_distance: prepared.scene.quality.sample_distance,
            environment: prepared.scene.environment.clone(),
        }
    }

    fn same(&self, other: &TexturesKey) -> bool {
        let eta_same = match (&self.eta_volume, &other.eta_volume) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        };
        Arc::ptr_eq(&self.volume, &other.volume)
            && eta_same
            && self.window == other.window
            && self.tf == other.tf
            && self.sample_distance == other.sample_distance
            && self.environment == other.environment
    }
}

/// Scene textures kept by the renderer between renders.
pub struct CachedTextures {
    key: TexturesKey,
    pub textures: SceneTextures,
    /// The upload commands have executed; until then (a render cancelled or failed before
    /// its first submission) the textures hold nothing and must not be reused. A `Cell`, so
    /// it can be set while the render's descriptor sets borrow the textures.
    uploaded: Cell<bool>,
}

impl CachedTextures {
    pub fn new(key: TexturesKey, textures: SceneTextures) -> Self {
        CachedTextures {
            key,
            textures,
            uploaded: Cell::new(false),
        }
    }

    pub fn matches(&self, key: &TexturesKey) -> bool {
        self.uploaded.get() && self.key.same(key)
    }

    /// Called after a submission that contained the upload has completed.
    pub fn uploaded(&self) {
        self.uploaded.set(true);
    }
}

fn missing() -> GpuError {
    GpuError::Allocation {
        what: "scene textures".into(),
        message: "internal: texture list out of order".into(),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn halves_saturate_instead_of_overflowing() {
        let bytes = super::halves([1.0f32, 1e6, 65504.0].into_iter());
        let back: Vec<f32> = bytes
            .chunks(2)
            .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
            .collect();
        assert_eq!(back, [1.0, 65504.0, 65504.0]);
    }
}
