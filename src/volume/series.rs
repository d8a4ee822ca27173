//! Time series: a sequence of volume files, one per time step, from a list or a file-name
//! pattern with one `*` (`frames/t*.nrrd`). Frames load one at a time, so a viewer can step
//! through a series without holding it all in memory.

use std::path::{Path, PathBuf};

use super::{open, Loaded, VolumeError};

#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub frames: Vec<PathBuf>,
}

impl Series {
    pub fn from_list(frames: Vec<PathBuf>) -> Result<Series, VolumeError> {
        if frames.is_empty() {
            return Err(VolumeError::Series("the frame list is empty".into()));
        }
        Ok(Series { frames })
    }

    /// Files matching `pattern`, whose file name has exactly one `*`, sorted by the number in
    /// the part `*` matched (so `t2` comes before `t10`), then by name.
    pub fn from_pattern(pattern: &Path) -> Result<Series, VolumeError> {
        let name = pattern.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let Some((prefix, suffix)) = name.split_once('*') else {
            return Err(VolumeError::Series(format!(
                "pattern '{}' has no '*' in its file name",
                pattern.display()
            )));
        };
        if suffix.contains('*') {
            return Err(VolumeError::Series(format!(
                "pattern '{}' has more than one '*'",
                pattern.display()
            )));
        }
        let dir = match pattern.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let entries = std::fs::read_dir(&dir).map_err(|source| VolumeError::Io {
            path: dir.clone(),
            source,
        })?;
        let mut matches: Vec<(Option<u64>, String)> = entries
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| n.len() >= prefix.len() + suffix.len() && n.starts_with(prefix) && n.ends_with(suffix))
            .map(|n| {
                let middle = &n[prefix.len()..n.len() - suffix.len()];
                let digits: String = middle.chars().filter(char::is_ascii_digit).collect();
                (digits.parse().ok(), n)
            })
            .collect();
        matches.sort();
        if matches.is_empty() {
            return Err(VolumeError::Series(format!("no files match '{}'", pattern.display())));
        }
        Ok(Series {
            frames: matches.into_iter().map(|(_, n)| dir.join(n)).collect(),
        })
    }

    /// A pattern if `spec` contains `*`, otherwise a single file.
    pub fn from_spec(spec: &Path) -> Result<Series, VolumeError> {
        if spec.to_string_lossy().contains('*') {
            Series::from_pattern(spec)
        } else {
            Series::from_list(vec![spec.to_path_buf()])
        }
    }

    pub fn len(&self) -> usize {
        self.frames.len()
    }

    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The frame shown at time `t` (in frames, rounded to the nearest); an error past the end.
    pub fn frame_at(&self, t: f32) -> Result<usize, VolumeError> {
        let last = self.frames.len().saturating_sub(1);
        if !(t.is_finite() && t >= 0.0 && t.round() as usize <= last) {
            return Err(VolumeError::Series(format!(
                "time {t} is outside the series' frames 0..={last}"
            )));
        }
        Ok(t.round() as usize)
    }

    /// Loads frame `k`.
    pub fn open_frame(&self, k: usize) -> Result<Loaded, VolumeError> {
        let path = self.frames.get(k).ok_or_else(|| {
            VolumeError::Series(format!(
                "frame {k} does not exist (the series has {} frames)",
                self.frames.len()
            ))
        })?;
        open(path)
    }
}

#[cfg(test)]
mod tests {
    use super::super::nrrd::write_nrrd;
    use super::super::test_support::ScratchDir;
    use super::super::Volume;
    use super::*;

    #[test]
    fn pattern_orders_frames_numerically_and_loads_each() {
        let dir = ScratchDir::new("series");
        for k in [0usize, 1, 2, 10] {
            let vol = Volume::new([2, 1, 1], [1.0; 3], vec![k as f32, 0.0]).unwrap();
            write_nrrd(&dir.path(&format!("t{k}.nrrd")), &vol, false).unwrap();
        }
        dir.write("other.nrrd", b"not part of the series");
        let series = Series::from_pattern(&dir.path("t*.nrrd")).expect("pattern");
        assert_eq!(series.len(), 4);
        assert!(series.frames[3].ends_with("t10.nrrd"), "{:?}", series.frames);
        assert_eq!(series.frame_at(2.6).unwrap(), 3);
        assert_eq!(series.open_frame(3).unwrap().volume.data[0], 10.0);
        assert!(series.frame_at(3.6).unwrap_err().to_string().contains("0..=3"));
        assert!(series.open_frame(9).is_err());
        assert!(Series::from_pattern(&dir.path("x*.nrrd"))
            .unwrap_err()
            .to_string()
            .contains("no files match"));
        assert!(Series::from_pattern(&dir.path("t.nrrd")).is_err());
    }
}
