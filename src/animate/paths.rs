//! A scene's file paths resolved against a base folder and made absolute, and its transfer
//! functions made inline: an animation file then holds everything its frames depend on
//! (except the data files themselves) and renders the same from any working directory.

use std::path::{Path, PathBuf};

use crate::scene::{Environment, Scene, SceneError, TransferSource, VolumeSource};

fn resolve(p: &mut PathBuf, base: &Path) {
    let joined = base.join(&*p);
    *p = std::path::absolute(&joined).unwrap_or(joined);
}

/// Resolves every relative path of `scene` against `base` (an empty path: the working
/// directory), makes it absolute, and reads a transfer-function file into the scene (any
/// importable format; a data-unit domain becomes the window unless the scene has one).
pub fn resolve_scene(scene: &mut Scene, base: &Path) -> Result<(), SceneError> {
    for v in std::iter::once(&mut scene.volume).chain(scene.eta_volume.as_mut()) {
        match v {
            VolumeSource::File { path, .. } => resolve(path, base),
            VolumeSource::Raw(desc) => resolve(&mut desc.path, base),
            VolumeSource::Series { files, pattern, .. } => {
                files.iter_mut().for_each(|f| resolve(f, base));
                if let Some(p) = pattern {
                    resolve(p, base);
                }
            }
            VolumeSource::Builtin { .. } => {}
        }
    }
    if let Environment::Image { path, .. } = &mut scene.environment {
        resolve(path, base);
    }
    if let TransferSource::File(p) = &scene.transfer {
        let mut p = p.clone();
        resolve(&mut p, base);
        let imported = crate::transfer::load_any(&p)?;
        scene.window = scene.window.or(imported.domain);
        scene.transfer = TransferSource::Inline(imported.tf);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_become_absolute_under_the_base() {
        let mut scene = crate::scene::builtin("ball-lens").unwrap().scene;
        scene.volume = VolumeSource::Series {
            files: vec!["t0.nrrd".into(), "/abs/t1.nrrd".into()],
            pattern: None,
            frame: 0,
        };
        scene.environment = Environment::Image {
            path: "sky.exr".into(),
            intensity: 1.0,
        };
        resolve_scene(&mut scene, Path::new("/data/anim")).unwrap();
        let VolumeSource::Series { files, .. } = &scene.volume else {
            panic!("still a series")
        };
        assert_eq!(
            files,
            &[PathBuf::from("/data/anim/t0.nrrd"), PathBuf::from("/abs/t1.nrrd")]
        );
        assert!(
            matches!(&scene.environment, Environment::Image { path, .. } if path == Path::new("/data/anim/sky.exr"))
        );
        let mut rel = crate::scene::builtin("ball-lens").unwrap().scene;
        rel.volume = VolumeSource::File {
            path: "v.nrrd".into(),
            series: None,
        };
        resolve_scene(&mut rel, Path::new("")).unwrap();
        let VolumeSource::File { path, .. } = &rel.volume else {
            panic!("still a file")
        };
        assert!(path.is_absolute() && path.ends_with("v.nrrd"), "{path:?}");
    }
}
