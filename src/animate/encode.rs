//! MP4 from the PNG frames through the `ffmpeg` on the PATH (H.264, yuv420p, which every
//! player and slide program reads; odd sizes are padded by one pixel, as yuv420p needs even
//! ones). The movie is written to a temporary name and renamed, like the frames.

use std::path::Path;
use std::process::Command;

use super::file::ANIMATION_FILE;
use super::frames::is_mp4;
use super::AnimateError;

/// Encodes `frames` PNG frames of `dir` (`frame_000000.png`, ...) at `fps` into `output`.
pub fn encode_mp4(dir: &Path, frames: usize, fps: f64, output: &Path) -> Result<(), AnimateError> {
    debug_assert!(is_mp4(output));
    let name = output.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    let tmp = output.with_file_name(format!(".{name}.{}.tmp.mp4", std::process::id()));
    let result = Command::new("ffmpeg")
        .args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y", "-framerate"])
        .arg(fps.to_string())
        .arg("-i")
        .arg(dir.join("frame_%06d.png"))
        .args(["-frames:v", &frames.to_string()])
        .args(["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2"])
        .args(["-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "18"])
        .args(["-movflags", "+faststart"])
        .arg(&tmp)
        .output();
    let failed = |message: String| {
        let _ = std::fs::remove_file(&tmp);
        Err(AnimateError::Ffmpeg {
            output: output.to_path_buf(),
            dir: dir.to_path_buf(),
            message,
        })
    };
    match result {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(AnimateError::NoFfmpeg {
            output: output.to_path_buf(),
            dir: dir.to_path_buf(),
            animation: dir.join(ANIMATION_FILE),
            frames,
        }),
        Err(e) => failed(format!("cannot run ffmpeg: {e}")),
        Ok(out) if !out.status.success() => {
            let stderr = String::from_utf8_lossy(&out.stderr);
            failed(format!("{} ({})", stderr.trim(), out.status))
        }
        Ok(_) => std::fs::rename(&tmp, output).or_else(|e| failed(format!("cannot rename {}: {e}", tmp.display()))),
    }
}
