//! Built-in procedural scene volumes, generated in code and selected by name.

mod scenes;
mod shapes;
#[cfg(test)]
mod tests;

pub use self::scenes::{ball_lens, glass, luneburg, supernova, thin_structures, MIN_RESOLUTION};
pub use self::shapes::smoothstep;

use super::{checked_voxel_count, Volume, VolumeError};

/// Names accepted by [`generate`].
pub const SCENE_VOLUMES: &[&str] = &["ball-lens", "glass", "supernova", "luneburg", "thin-structures"];

/// Generates the named scene with `n` voxels along its longest axis (128 is a good default).
/// `n` below [`MIN_RESOLUTION`] is raised to it.
pub fn generate(name: &str, n: usize) -> Result<Volume, VolumeError> {
    let generator: fn(usize) -> Volume = match name {
        "ball-lens" => ball_lens,
        "glass" => glass,
        "supernova" => supernova,
        "luneburg" => luneburg,
        "thin-structures" => thin_structures,
        _ => return Err(VolumeError::UnknownScene(name.to_string())),
    };
    // Every scene fits in an n³ grid, so this bounds the allocation for all of them.
    let n = n.max(MIN_RESOLUTION);
    checked_voxel_count([n, n, n])?;
    Ok(generator(n))
}
