//! The animation file (TOML): frame count, rate and size, the base scene, and the tracks.
//! Loading normalises it: the scene and the transfer-function keys inline, every path
//! absolute. The normalised text is what `animate` writes next to the frames, and its
//! SHA-256 is the animation's hash.
//!
//! ```toml
//! frames = 120
//! fps = 30.0
//! size = [512, 512]
//! loop = true                     # time k / frames: the last frame leads back to the first
//! scene_file = "head.toml"        # or an inline [scene] table
//!
//! [tracks.camera]
//! yaw_deg = [[0.0, 0.0], [1.0, 360.0]]       # keys [at, value], at in [0, 1]
//!
//! [[tracks.transfer]]
//! at = 0.0
//! file = "bone.json"              # or an inline [tracks.transfer.functions] table
//! ```

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::paths::resolve_scene;
use super::tracks::{FrameSpec, Tracks, TransferKey};
use super::AnimateError;
use crate::scene::Scene;
use crate::transfer::TransferFunctions;

/// The normalised animation written next to the frames.
pub const ANIMATION_FILE: &str = "animation.toml";
/// The list of frames and their hashes written next to the frames.
pub const MANIFEST_FILE: &str = "manifest.json";

/// Largest frame side, as for `render`'s output on any device caustica supports.
const MAX_SIZE: u32 = 16384;

fn default_fps() -> f64 {
    30.0
}

/// A transfer-function key as written by hand: inline functions or a file (transfer
/// functions in any importable format, or a scene file whose functions and window are taken).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TransferKeyFile {
    at: f64,
    #[serde(default)]
    window: Option<[f32; 2]>,
    #[serde(default)]
    file: Option<PathBuf>,
    #[serde(default)]
    functions: Option<TransferFunctions>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AnimationFile {
    frames: u32,
    #[serde(default = "default_fps")]
    fps: f64,
    size: [u32; 2],
    #[serde(default, rename = "loop")]
    looped: bool,
    #[serde(default)]
    scene_file: Option<PathBuf>,
    #[serde(default)]
    tracks: Tracks<TransferKeyFile>,
    #[serde(default)]
    scene: Option<Scene>,
}

/// A normalised animation: what every frame shows follows from it alone.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Animation {
    pub frames: u32,
    pub fps: f64,
    /// Frame width and height in pixels.
    pub size: [u32; 2],
    /// Time of frame k is k / frames instead of k / (frames − 1): the sequence loops.
    #[serde(rename = "loop")]
    pub looped: bool,
    pub tracks: Tracks<TransferKey>,
    pub scene: Scene,
}

/// True for a `.toml` file with a top-level `frames` key: an animation, not a scene.
pub fn is_animation_file(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "toml")
        && std::fs::read_to_string(path)
            .ok()
            .and_then(|text| text.parse::<toml::Table>().ok())
            .is_some_and(|t| t.contains_key("frames"))
}

/// Transfer functions and window of a key file: a scene file or any transfer-function file.
pub fn load_key_file(path: &Path) -> Result<(TransferFunctions, Option<[f32; 2]>), AnimateError> {
    if path.extension().is_some_and(|e| e == "toml") {
        let scene = Scene::load(path)?;
        Ok((scene.transfer_functions()?, scene.window))
    } else {
        let imported = crate::transfer::load_any(path)?;
        Ok((imported.tf, imported.domain))
    }
}

impl Animation {
    /// Reads an animation file; relative paths are relative to its folder.
    pub fn load(path: &Path) -> Result<Animation, AnimateError> {
        let text = std::fs::read_to_string(path).map_err(|source| AnimateError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let file: AnimationFile = toml::from_str(&text).map_err(|e| AnimateError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let base = path.parent().unwrap_or(Path::new(""));
        let scene = match (file.scene_file, file.scene) {
            (Some(p), None) => {
                let mut s = Scene::load(&base.join(p))?;
                resolve_scene(&mut s, Path::new(""))?;
                s
            }
            (None, Some(mut s)) => {
                resolve_scene(&mut s, base)?;
                s
            }
            _ => {
                return Err(AnimateError::Parse {
                    path: path.to_path_buf(),
                    message: "give either scene_file = \"...\" or a [scene] table".into(),
                })
            }
        };
        let t = file.tracks;
        let mut transfer = Vec::new();
        for (i, k) in t.transfer.into_iter().enumerate() {
            let (functions, window) = match (k.file, k.functions) {
                (Some(p), None) => load_key_file(&base.join(p))?,
                (None, Some(f)) => (f, None),
                _ => {
                    return Err(AnimateError::Parse {
                        path: path.to_path_buf(),
                        message: format!("transfer key {i}: give either file = \"...\" or a functions table"),
                    })
                }
            };
            transfer.push(TransferKey {
                at: k.at,
                window: k.window.or(window),
                functions,
            });
        }
        let animation = Animation {
            frames: file.frames,
            fps: file.fps,
            size: file.size,
            looped: file.looped,
            tracks: Tracks {
                camera: t.camera,
                light: t.light,
                clip: t.clip,
                time: t.time,
                transfer,
            },
            scene,
        };
        animation.validate()?;
        Ok(animation)
    }

    /// The animation time of frame `k`, in [0, 1].
    pub fn time_of(&self, k: u32) -> f64 {
        let n = if self.looped {
            self.frames
        } else {
            self.frames.saturating_sub(1)
        };
        if n == 0 {
            0.0
        } else {
            k as f64 / n as f64
        }
    }

    /// Checks the settings and the tracks, and that every frame's scene is valid.
    pub fn validate(&self) -> Result<(), AnimateError> {
        let bad = |m: String| Err(AnimateError::Invalid(m));
        if self.frames == 0 {
            return bad("frames must be at least 1".into());
        }
        if !(self.fps.is_finite() && self.fps > 0.0) {
            return bad(format!("fps {} must be a finite number > 0", self.fps));
        }
        if self.size.iter().any(|s| !(1..=MAX_SIZE).contains(s)) {
            return bad(format!(
                "size {}x{} must be between 1x1 and {MAX_SIZE}x{MAX_SIZE}",
                self.size[0], self.size[1]
            ));
        }
        self.scene.validate()?;
        self.tracks.validate(&self.scene)?;
        self.frame_specs().map(|_| ())
    }

    /// What every frame shows, in order.
    pub fn frame_specs(&self) -> Result<Vec<FrameSpec>, AnimateError> {
        let series_len = if self.tracks.time.is_empty() {
            0
        } else {
            self.scene.volume.series()?.map_or(0, |s| s.len())
        };
        (0..self.frames)
            .map(|k| {
                let (scene, blend) = self
                    .tracks
                    .apply(&self.scene, self.time_of(k), series_len)
                    .map_err(|e| AnimateError::Invalid(format!("frame {k}: {e}")))?;
                Ok(FrameSpec { index: k, scene, blend })
            })
            .collect()
    }

    /// The normalised file text: the header comment and the animation as TOML.
    pub fn to_toml(&self) -> Result<String, AnimateError> {
        let body = toml::to_string(self).map_err(|e| AnimateError::Invalid(e.to_string()))?;
        Ok(format!(
            "# caustica animation: render it with `caustica animate THIS_FILE -o DIR` (see README, `animate`)\n{body}"
        ))
    }

    /// SHA-256 (hex) of [`Animation::to_toml`]: `sha256sum DIR/animation.toml` prints it too.
    pub fn hash(&self) -> Result<String, AnimateError> {
        Ok(sha256_hex(self.to_toml()?.as_bytes()))
    }

    /// Writes the normalised animation to `path` (via a temporary file and a rename).
    pub fn save(&self, path: &Path) -> Result<(), AnimateError> {
        super::frames::write_atomic(path, self.to_toml()?.as_bytes())
    }
}

pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Dir(PathBuf);

    impl Dir {
        fn new(tag: &str) -> Dir {
            let d = std::env::temp_dir().join(format!("caustica-anim-{tag}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&d);
            std::fs::create_dir_all(&d).unwrap();
            Dir(d)
        }
    }

    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// A hand-written file with a scene file and a key file loads, normalises to inline
    /// content, and the normalised text loads back to the same animation (and hash).
    #[test]
    fn hand_written_file_normalises_and_round_trips() {
        let dir = Dir::new("roundtrip");
        let tf_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("transfer_functions");
        std::fs::write(
            dir.0.join("s.toml"),
            format!(
                "transfer = {:?}\n[volume]\nkind = \"builtin\"\nname = \"ball-lens\"\nresolution = 16\n",
                tf_dir.join("ball-lens.json")
            ),
        )
        .unwrap();
        std::fs::copy(tf_dir.join("ct-bone.json"), dir.0.join("bone.json")).unwrap();
        let path = dir.0.join("a.toml");
        std::fs::write(
            &path,
            "frames = 5\nsize = [8, 6]\nscene_file = \"s.toml\"\n\
             [tracks.camera]\nyaw_deg = [[0.0, 10.0], [1.0, 50.0]]\n\
             [[tracks.transfer]]\nat = 0.0\nfile = \"bone.json\"\n\
             [[tracks.transfer]]\nat = 1.0\nfile = \"s.toml\"\n",
        )
        .unwrap();
        assert!(is_animation_file(&path));
        assert!(!is_animation_file(&dir.0.join("s.toml")));
        let a = Animation::load(&path).unwrap();
        assert_eq!((a.frames, a.fps, a.size), (5, 30.0, [8, 6]));
        assert_eq!(
            a.tracks.transfer[0].functions,
            TransferFunctions::load(&tf_dir.join("ct-bone.json")).unwrap()
        );
        let specs = a.frame_specs().unwrap();
        assert_eq!(specs[2].scene.camera.yaw_deg, 30.0);
        let copy = dir.0.join("elsewhere").join(ANIMATION_FILE);
        std::fs::create_dir_all(copy.parent().unwrap()).unwrap();
        a.save(&copy).unwrap();
        let back = Animation::load(&copy).unwrap();
        assert_eq!(back, a);
        assert_eq!(back.hash().unwrap(), a.hash().unwrap());
        assert_eq!(a.hash().unwrap(), sha256_hex(&std::fs::read(&copy).unwrap()));
    }

    #[test]
    fn errors_name_the_file_and_the_problem() {
        let dir = Dir::new("errors");
        let path = dir.0.join("a.toml");
        let write = |text: &str| std::fs::write(&path, text).unwrap();
        let scene = "[scene]\ntransfer = { opacity = [[0.0, 0.0]] }\n[scene.volume]\nkind = \"builtin\"\nname = \"ball-lens\"\nresolution = 8\n";
        write(&format!("frames = 3\nsize = [4, 4]\nfsp = 3\n{scene}"));
        let e = Animation::load(&path).unwrap_err().to_string();
        assert!(e.contains("a.toml") && e.contains("fsp"), "{e}");
        write(&format!(
            "frames = 3\nsize = [4, 4]\n[tracks.light]\npolar_deg = [[0.0, 10.0], [1.0, 95.0]]\n{scene}"
        ));
        let e = Animation::load(&path).unwrap_err().to_string();
        assert!(e.contains("frame 2") && e.contains("polar_deg"), "{e}");
        write("frames = 3\nsize = [4, 4]\n");
        let e = Animation::load(&path).unwrap_err().to_string();
        assert!(e.contains("scene_file"), "{e}");
        write(&format!("frames = 0\nsize = [4, 4]\n{scene}"));
        assert!(Animation::load(&path).unwrap_err().to_string().contains("at least 1"));
    }

    #[test]
    fn a_loop_never_reaches_its_last_key() {
        let mut a = Animation {
            frames: 4,
            fps: 30.0,
            size: [4, 4],
            looped: false,
            tracks: Tracks::default(),
            scene: crate::scene::builtin("ball-lens").unwrap().scene,
        };
        assert_eq!((a.time_of(0), a.time_of(3)), (0.0, 1.0));
        a.looped = true;
        assert_eq!((a.time_of(2), a.time_of(3)), (0.5, 0.75));
        a.frames = 1;
        a.looped = false;
        assert_eq!(a.time_of(0), 0.0);
    }
}
