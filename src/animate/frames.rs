//! Frame files: names, which frames a run renders (`--shard`, `--range`), writing a frame
//! with the hash of what it shows embedded (a PNG text chunk or an EXR header attribute),
//! reading that hash back, the manifest, and `--check`.
//!
//! Every file is written to a temporary name and renamed, so an interrupted run never
//! leaves a partial frame under a frame's name, and shards writing the (identical) manifest
//! at the same time cannot corrupt it.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::file::{sha256_hex, Animation, ANIMATION_FILE, MANIFEST_FILE};
use super::tracks::FrameSpec;
use super::AnimateError;
use crate::scene::RenderedImage;

/// The key under which a frame file holds its hash.
pub const HASH_KEY: &str = "caustica-frame-hash";

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum FrameFormat {
    /// 8-bit sRGB PNG.
    Png,
    /// Linear 32-bit float RGBA OpenEXR.
    Exr,
}

impl FrameFormat {
    pub fn extension(self) -> &'static str {
        match self {
            FrameFormat::Png => "png",
            FrameFormat::Exr => "exr",
        }
    }
}

/// `frame_000012.png`: six digits, so names sort in frame order and ffmpeg's `%06d` reads them.
pub fn frame_name(k: u32, format: FrameFormat) -> String {
    format!("frame_{k:06}.{}", format.extension())
}

/// Which frames a run renders: a contiguous range and/or every `count`-th frame from `index`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Selection {
    /// First and last frame, inclusive.
    pub range: Option<(u32, u32)>,
    /// (index, count): frames k with k mod count = index.
    pub shard: Option<(u32, u32)>,
}

impl Selection {
    /// True when every frame is selected (the run that may encode an MP4).
    pub fn is_all(&self) -> bool {
        self.range.is_none() && !matches!(self.shard, Some((_, n)) if n > 1)
    }

    /// The selected frames of an animation of `total` frames; a range past the end is a
    /// usage error.
    pub fn frames(&self, total: u32) -> Result<Vec<u32>, AnimateError> {
        let (first, last) = self.range.unwrap_or((0, total.saturating_sub(1)));
        if last >= total {
            return Err(AnimateError::Usage(format!(
                "--range {first}..{last} goes past the last frame: the animation has {total} frames (0..{})",
                total - 1
            )));
        }
        let (index, count) = self.shard.unwrap_or((0, 1));
        Ok((first..=last).filter(|k| k % count == index).collect())
    }
}

/// `A..B`: frames A to B, both included (0-based).
pub fn parse_range(s: &str) -> Result<(u32, u32), String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("'{s}': expected FIRST..LAST, e.g. 0..99 (both included)"))?;
    let p = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("'{v}' in '{s}': {e}"));
    let (a, b) = (p(a)?, p(b.trim_start_matches('='))?);
    if a > b {
        return Err(format!("'{s}': the first frame {a} is after the last {b}"));
    }
    Ok((a, b))
}

/// `I/N`: shard I (0-based) of N.
pub fn parse_shard(s: &str) -> Result<(u32, u32), String> {
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| format!("'{s}': expected INDEX/COUNT, e.g. 0/4 (INDEX from 0 to COUNT-1)"))?;
    let p = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("'{v}' in '{s}': {e}"));
    let (i, n) = (p(i)?, p(n)?);
    if n == 0 {
        return Err(format!("'{s}': the shard count must be at least 1"));
    }
    if i >= n {
        return Err(format!(
            "'{s}': shard index {i} must be below the count {n} (indices start at 0)"
        ));
    }
    Ok((i, n))
}

/// Writes `bytes` to `path` via a sibling temporary file and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), AnimateError> {
    with_temp(path, |tmp| {
        let mut f = std::fs::File::create(tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })
}

/// Runs `write` on a temporary name next to `path` (same extension), then renames it.
fn with_temp(path: &Path, write: impl FnOnce(&Path) -> std::io::Result<()>) -> Result<(), AnimateError> {
    let name = path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    let ext = path.extension().map(|e| e.to_string_lossy()).unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{}.tmp.{ext}", std::process::id()));
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(AnimateError::Write {
            path: path.to_path_buf(),
            message: e.to_string(),
        });
    }
    Ok(())
}

/// The hash of what frame `spec` shows at `size` in `format`.
pub fn frame_hash(spec: &FrameSpec, size: [u32; 2], format: FrameFormat) -> String {
    #[derive(Serialize)]
    struct Key<'a> {
        spec: &'a FrameSpec,
        size: [u32; 2],
        format: FrameFormat,
    }
    let json = serde_json::to_vec(&Key { spec, size, format }).unwrap_or_default();
    sha256_hex(&json)
}

/// Writes a frame (PNG: 8-bit sRGB as `render` writes it; EXR: linear float RGBA) with
/// `hash` embedded.
pub fn write_frame(path: &Path, image: &RenderedImage, format: FrameFormat, hash: &str) -> Result<(), AnimateError> {
    with_temp(path, |tmp| match format {
        FrameFormat::Png => write_png(tmp, image, hash),
        FrameFormat::Exr => write_exr(tmp, image, hash),
    })
}

fn write_png(path: &Path, image: &RenderedImage, hash: &str) -> std::io::Result<()> {
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut encoder = png::Encoder::new(file, image.width, image.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.add_text_chunk(HASH_KEY.into(), hash.into())?;
    encoder.add_text_chunk("Software".into(), format!("caustica {}", env!("CARGO_PKG_VERSION")))?;
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&image.to_srgb8())?;
    writer.finish()?;
    Ok(())
}

fn write_exr(path: &Path, image: &RenderedImage, hash: &str) -> std::io::Result<()> {
    use exr::meta::attribute::{AttributeValue, Text};
    use exr::prelude::*;
    let w = image.width as usize;
    let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
        let p = image.pixels[y * w + x];
        (p[0], p[1], p[2], p[3])
    });
    let mut attributes = LayerAttributes::default();
    attributes
        .other
        .insert(Text::from(HASH_KEY), AttributeValue::Text(Text::from(hash)));
    attributes.software_name = Some(Text::from(format!("caustica {}", env!("CARGO_PKG_VERSION")).as_str()));
    let layer = Layer::new(
        (w, image.height as usize),
        attributes,
        crate::scene::image::EXR_ENCODING,
        channels,
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| std::io::Error::other(e.to_string()))
}

/// The hash embedded in a frame file; `None` when the file is missing, unreadable or holds
/// none. With `decode`, the whole image is decoded too, so a damaged file reads as `None`.
pub fn read_frame_hash(path: &Path, format: FrameFormat, decode: bool) -> Option<String> {
    match format {
        FrameFormat::Png => {
            let file = std::io::BufReader::new(std::fs::File::open(path).ok()?);
            let mut reader = png::Decoder::new(file).read_info().ok()?;
            let hash = reader
                .info()
                .uncompressed_latin1_text
                .iter()
                .find(|c| c.keyword == HASH_KEY)
                .map(|c| c.text.clone())?;
            if decode {
                let mut buf = vec![0; reader.output_buffer_size()?];
                reader.next_frame(&mut buf).ok()?;
            }
            Some(hash)
        }
        FrameFormat::Exr => {
            use exr::meta::attribute::AttributeValue;
            let meta = exr::meta::MetaData::read_from_file(path, false).ok()?;
            let hash = meta
                .headers
                .first()?
                .own_attributes
                .other
                .iter()
                .find_map(|(k, v)| match v {
                    AttributeValue::Text(t) if *k == *HASH_KEY => Some(t.to_string()),
                    _ => None,
                })?;
            if decode {
                // Decoding every block is the check; the pixels are not kept.
                exr::prelude::read_first_rgba_layer_from_file(
                    path,
                    |_, _| (),
                    |_: &mut (), _, _: (f32, f32, f32, f32)| {},
                )
                .ok()?;
            }
            Some(hash)
        }
    }
}

/// One frame in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ManifestFrame {
    pub index: u32,
    pub file: String,
    /// Hash of what the frame shows (its scene, size and format); the frame file holds it too.
    pub hash: String,
}

/// `manifest.json`: the frames of the animation in this folder and its hash. Every run
/// writes the same bytes for the same animation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub caustica: String,
    pub animation: String,
    /// SHA-256 of `animation.toml`.
    pub animation_hash: String,
    pub fps: f64,
    pub size: [u32; 2],
    pub format: FrameFormat,
    pub frames: Vec<ManifestFrame>,
}

impl Manifest {
    pub fn new(animation: &Animation, specs: &[FrameSpec], format: FrameFormat) -> Result<Manifest, AnimateError> {
        Ok(Manifest {
            caustica: env!("CARGO_PKG_VERSION").into(),
            animation: ANIMATION_FILE.into(),
            animation_hash: animation.hash()?,
            fps: animation.fps,
            size: animation.size,
            format,
            frames: specs
                .iter()
                .map(|s| ManifestFrame {
                    index: s.index,
                    file: frame_name(s.index, format),
                    hash: frame_hash(s, animation.size, format),
                })
                .collect(),
        })
    }

    pub fn load(dir: &Path) -> Result<Manifest, AnimateError> {
        let path = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).map_err(|source| AnimateError::Io {
            path: path.clone(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| AnimateError::Parse {
            path,
            message: e.to_string(),
        })
    }

    pub fn save(&self, dir: &Path) -> Result<(), AnimateError> {
        let json = serde_json::to_string_pretty(self).map_err(|e| AnimateError::Invalid(e.to_string()))?;
        write_atomic(&dir.join(MANIFEST_FILE), format!("{json}\n").as_bytes())
    }
}

/// What `--check` found in a frame folder.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CheckReport {
    pub total: usize,
    pub present: Vec<u32>,
    pub missing: Vec<u32>,
    /// Present, but showing something else (another version of the animation) or damaged.
    pub stale: Vec<u32>,
    /// The animation file next to the frames no longer has the manifest's hash.
    pub animation_changed: bool,
}

impl CheckReport {
    pub fn complete(&self) -> bool {
        self.missing.is_empty() && self.stale.is_empty() && !self.animation_changed
    }
}

/// Compares the frames in `dir` with its manifest: each frame must exist, decode, and hold
/// the manifest's hash.
pub fn check(dir: &Path) -> Result<CheckReport, AnimateError> {
    let manifest = Manifest::load(dir)?;
    let animation_changed = std::fs::read(dir.join(&manifest.animation))
        .map(|bytes| sha256_hex(&bytes) != manifest.animation_hash)
        .unwrap_or(true);
    let mut report = CheckReport {
        total: manifest.frames.len(),
        animation_changed,
        ..Default::default()
    };
    for f in &manifest.frames {
        let path = dir.join(&f.file);
        if !path.exists() {
            report.missing.push(f.index);
        } else if read_frame_hash(&path, manifest.format, true).as_deref() == Some(f.hash.as_str()) {
            report.present.push(f.index);
        } else {
            report.stale.push(f.index);
        }
    }
    Ok(report)
}

/// `0..3, 7, 9..10`: frame numbers as inclusive runs.
pub fn runs(frames: &[u32]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            frames[i].to_string()
        } else {
            format!("{}..{}", frames[i], frames[j])
        });
        i = j + 1;
    }
    out.join(", ")
}

/// Frames already in `dir` with the expected hash (resume skips them).
pub fn present(dir: &Path, expected: &[(u32, String)], format: FrameFormat) -> Vec<u32> {
    expected
        .iter()
        .filter(|(k, hash)| read_frame_hash(&dir.join(frame_name(*k, format)), format, false).as_deref() == Some(hash))
        .map(|(k, _)| *k)
        .collect()
}

/// The folder of the frames: `DIR` itself, or `NAME_frames` next to `NAME.mp4`.
pub fn frames_dir(output: &Path) -> PathBuf {
    if is_mp4(output) {
        let stem = output.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default();
        output.with_file_name(format!("{stem}_frames"))
    } else {
        output.to_path_buf()
    }
}

pub fn is_mp4(output: &Path) -> bool {
    output.extension().is_some_and(|e| e.eq_ignore_ascii_case("mp4"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_and_ranges_partition_the_frames() {
        let all: Vec<u32> = (0..10).collect();
        assert_eq!(Selection::default().frames(10).unwrap(), all);
        let mut union: Vec<u32> = (0..3)
            .flat_map(|i| {
                Selection {
                    shard: Some((i, 3)),
                    range: None,
                }
                .frames(10)
                .unwrap()
            })
            .collect();
        union.sort();
        assert_eq!(union, all, "shards cover every frame exactly once");
        let s = Selection {
            range: Some((2, 7)),
            shard: Some((1, 2)),
        };
        assert_eq!(s.frames(10).unwrap(), vec![3, 5, 7]);
        let past = Selection {
            range: Some((5, 10)),
            shard: None,
        };
        assert!(matches!(past.frames(10), Err(AnimateError::Usage(m)) if m.contains("10 frames")));
        assert!(Selection {
            shard: Some((0, 1)),
            range: None
        }
        .is_all());
    }

    #[test]
    fn bad_shards_and_ranges_are_refused() {
        assert_eq!(parse_shard("2/4"), Ok((2, 4)));
        assert_eq!(parse_range("3..7"), Ok((3, 7)));
        assert_eq!(parse_range("3..=7"), Ok((3, 7)));
        for bad in ["4/4", "1/0", "x/2", "3", "-1/2"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
        for bad in ["7..3", "3", "a..4", "1..-2"] {
            assert!(parse_range(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn runs_join_consecutive_frames() {
        assert_eq!(runs(&[0, 1, 2, 3, 7, 9, 10]), "0..3, 7, 9..10");
        assert_eq!(runs(&[]), "");
    }

    /// A frame written with a hash reads it back, in both formats; a damaged file and a
    /// file written by something else read as no hash.
    #[test]
    fn frames_carry_their_hash() {
        let dir = std::env::temp_dir().join(format!("caustica-frames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let image = RenderedImage {
            width: 3,
            height: 2,
            pixels: (0..6).map(|i| [i as f32 / 5.0, 0.5, 2.0, 1.0]).collect(),
        };
        for format in [FrameFormat::Png, FrameFormat::Exr] {
            let path = dir.join(frame_name(4, format));
            write_frame(&path, &image, format, "abc123").unwrap();
            assert_eq!(read_frame_hash(&path, format, true).as_deref(), Some("abc123"));
            let bytes = std::fs::read(&path).unwrap();
            std::fs::write(&path, &bytes[..bytes.len() - 20]).unwrap();
            assert_eq!(read_frame_hash(&path, format, true), None, "{format:?} truncated");
            image.save(&path).unwrap();
            assert_eq!(read_frame_hash(&path, format, false), None, "{format:?} without hash");
        }
        // The PNG frame holds exactly what `render` writes.
        let path = dir.join("f.png");
        write_frame(&path, &image, FrameFormat::Png, "h").unwrap();
        let decoded = image::open(&path).unwrap().to_rgba8().into_raw();
        assert_eq!(decoded, image.to_srgb8());
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            3,
            "no temporary file is left behind"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
