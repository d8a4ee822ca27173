//! Built-in procedural scene volumes, generated in code and selected by name.

mod scenes;
mod shapes;
#[cfg(test)]
mod tests;

pub use self::scenes::{ball_lens, glass, luneburg, supernova, thin_structures, Part, MIN_RESOLUTION};
pub use self::shapes::smoothstep;

use super::{checked_voxel_count, Volume, VolumeError};

/// Names accepted by [`generate`].
pub const SCENE_VOLUMES: &[&str] = &["ball-lens", "glass", "supernova", "luneburg", "thin-structures"];

/// Generates the named scene with `n` voxels along its longest axis (128 is a good default).
/// `n` below [`MIN_RESOLUTION`] is raised to it.
pub fn generate(name: &str, n: usize) -> Result<Volume, VolumeError> {
    generate_part(name, n, Part::Whole)
}

/// Generates `part` of the named scene. Its values keep the whole scene's meaning (transfer
/// function inputs in [0, 1]), so its value range is [0, 1] whatever it holds.
pub fn generate_part(name: &str, n: usize, part: Part) -> Result<Volume, VolumeError> {
    let generator: fn(usize, Part) -> Volume = match name {
        "ball-lens" => scenes::ball_lens_part,
        "glass" => scenes::glass_part,
        "supernova" => scenes::supernova_part,
        "luneburg" => scenes::luneburg_part,
        "thin-structures" => scenes::thin_structures_part,
        _ => return Err(VolumeError::UnknownScene(name.to_string())),
    };
    // Every scene fits in an n³ grid, so this bounds the allocation for all of them.
    let n = n.max(MIN_RESOLUTION);
    checked_voxel_count([n, n, n])?;
    let mut volume = generator(n, part);
    if part != Part::Whole {
        volume.value_range = [0.0, 1.0];
    }
    Ok(volume)
}
