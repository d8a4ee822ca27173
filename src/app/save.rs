//! Atomic file writes (temporary file + rename) for saved scenes, transfer functions and
//! screenshots, so an interrupted save never leaves a half-written file behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::render::RenderedImage;
use crate::scene::Scene;

/// A sibling temporary name in the same directory, so the rename stays on one file system.
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Saves `scene` as TOML with inline transfer functions: `caustica render` of the file
/// reproduces the view (paths in it are absolute, so the file can be moved).
pub fn save_scene(scene: &Scene, path: &Path) -> anyhow::Result<()> {
    let mut scene = scene.clone();
    absolutise(&mut scene);
    let text = toml::to_string_pretty(&scene)?;
    write_atomic(path, text.as_bytes())?;
    Ok(())
}

fn absolutise(scene: &mut Scene) {
    use crate::scene::{Environment, VolumeSource};
    let abs = |p: &mut PathBuf| {
        if let Ok(a) = std::path::absolute(&*p) {
            *p = a;
        }
    };
    for v in std::iter::once(&mut scene.volume).chain(scene.eta_volume.as_mut()) {
        match v {
            VolumeSource::File { path, .. } => abs(path),
            VolumeSource::Raw(desc) => abs(&mut desc.path),
            VolumeSource::Series { files, pattern, .. } => {
                files.iter_mut().for_each(abs);
                if let Some(p) = pattern {
                    abs(p);
                }
            }
            VolumeSource::Builtin { .. } => {}
        }
    }
    if let Environment::Image { path, .. } = &mut scene.environment {
        abs(path);
    }
}

/// Writes an image (PNG or EXR by extension) atomically.
pub fn save_image(image: &RenderedImage, path: &Path) -> anyhow::Result<()> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = temp_path(path).with_extension(format!("tmp.{ext}"));
    let result = image.save(&tmp).map_err(anyhow::Error::from).and_then(|()| {
        std::fs::rename(&tmp, path)?;
        Ok(())
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saved_scene_loads_back_equal() {
        let dir = std::env::temp_dir().join(format!("caustica-save-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("view.toml");
        let mut scene = crate::scene::builtin("ball-lens").unwrap().scene;
        scene.camera.yaw_deg = 33.0;
        scene.light.softness = 0.2;
        save_scene(&scene, &path).unwrap();
        let back = Scene::load(&path).unwrap();
        assert_eq!(back, scene);
        let leftovers = std::fs::read_dir(&dir).unwrap().count();
        assert_eq!(leftovers, 1, "no temporary file is left behind");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
