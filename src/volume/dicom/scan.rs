//! Finding DICOM images and grouping them into series: a folder (walked recursively), the
//! folder of one file (that file's series), or a DICOMDIR. Only the headers are read here;
//! the pixels of the chosen series are read by [`super::assemble`].

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use dicom_core::dictionary::UidDictionary;
use dicom_dictionary_std::{tags, StandardSopClassDictionary};
use rayon::prelude::*;

use super::frames::{image_info, text, ImageInfo};
use super::header_error;
use super::parse::{looks_like_dicom, read_file};
use crate::volume::read::io_error;
use crate::volume::VolumeError;

/// Deepest folder level searched below the one given.
const MAX_DEPTH: usize = 8;
/// Most files looked at in one folder tree.
const MAX_FILES: usize = 200_000;

/// One series found: what `caustica info DIR` lists.
#[derive(Clone, Debug, PartialEq)]
pub struct SeriesInfo {
    /// Position in the listing, from 1 (what `--series N` takes).
    pub number: usize,
    pub uid: String,
    pub description: String,
    pub modality: String,
    /// Series Number, as the scanner numbered it.
    pub series_number: Option<i64>,
    /// Columns × rows of its images.
    pub columns: usize,
    pub rows: usize,
    /// Frames in all its files (the slices of a volume).
    pub frames: usize,
    pub files: Vec<PathBuf>,
}

/// What a scan found.
pub(crate) struct Scan {
    pub series: Vec<SeriesInfo>,
    /// Files that do not start like DICOM.
    pub not_dicom: usize,
    /// DICOM-looking files that could not be read, with the reason.
    pub unreadable: Vec<(PathBuf, String)>,
    /// Objects without pixel data, with what they are.
    pub non_image: Vec<(PathBuf, String)>,
    /// The series of the file the user named, when a single file was given.
    pub preselected: Option<String>,
}

enum Entry {
    NotDicom,
    Unreadable(VolumeError),
    NonImage(String),
    /// A DICOMDIR (Media Storage Directory), whatever its file name.
    Directory,
    Image(Box<ImageInfo>),
}

const MEDIA_STORAGE_DIRECTORY: &str = "1.2.840.10008.1.3.10";

/// What kind of object a SOP class is, for "this DICOM object holds no image: …".
pub(crate) fn object_kind(sop_class: &str) -> String {
    let uid = sop_class.trim_end_matches('\0');
    let name = StandardSopClassDictionary
        .by_uid(uid)
        .map(|e| e.name.trim_end_matches(" Storage"));
    let category = if uid.starts_with("1.2.840.10008.5.1.4.1.1.88.") {
        Some("Structured Report")
    } else if uid.starts_with("1.2.840.10008.5.1.4.1.1.9.") {
        Some("waveform")
    } else if uid == "1.2.840.10008.5.1.4.1.1.481.3" {
        Some("RT structure set")
    } else if uid.starts_with("1.2.840.10008.5.1.4.1.1.481.") && name.is_some_and(|n| n.contains("Plan")) {
        Some("RT plan")
    } else {
        None
    };
    match (category, name) {
        (Some(c), Some(n)) => format!("{c} ({n})"),
        (None, Some(n)) => n.to_string(),
        (Some(c), None) => c.to_string(),
        (None, None) if uid.is_empty() => "an object without a SOP class".into(),
        (None, None) => format!("SOP class {uid}"),
    }
}

fn classify(path: &Path) -> Entry {
    let mut head = [0u8; 132];
    let got = std::fs::File::open(path).and_then(|mut f| {
        let mut n = 0;
        while n < head.len() {
            match f.read(&mut head[n..])? {
                0 => break,
                k => n += k,
            }
        }
        Ok(n)
    });
    match got {
        Ok(n) if looks_like_dicom(&head[..n]) => {}
        Ok(_) => return Entry::NotDicom,
        Err(e) => return Entry::Unreadable(io_error(path)(e)),
    }
    let parsed = match read_file(path, true) {
        Ok(p) => p,
        Err(e) => return Entry::Unreadable(e),
    };
    if !parsed.has_pixels {
        let sop = text(&parsed.object, tags::SOP_CLASS_UID)
            .unwrap_or_else(|| parsed.object.meta().media_storage_sop_class_uid().to_string());
        if sop.trim_end_matches('\0') == MEDIA_STORAGE_DIRECTORY {
            return Entry::Directory;
        }
        return Entry::NonImage(object_kind(&sop));
    }
    match image_info(&parsed.object, path.to_path_buf()) {
        Ok(info) => Entry::Image(Box::new(info)),
        Err(m) => Entry::Unreadable(header_error(path, m)),
    }
}

/// Scans `path`: a folder, a DICOMDIR, or one file (whose folder is scanned for its series).
pub(crate) fn scan(path: &Path) -> Result<Scan, VolumeError> {
    let mut preselected = None;
    let files = if path.is_dir() {
        let dicomdir = path.join("DICOMDIR");
        if dicomdir.is_file() {
            dicomdir_files(&dicomdir)?
        } else {
            let mut files = Vec::new();
            walk(path, 0, &mut files)?;
            files
        }
    } else {
        match classify(path) {
            Entry::Directory => return scan_files(dicomdir_files(path)?, None),
            Entry::Image(info) => preselected = Some(info.series_uid.clone()),
            Entry::NonImage(kind) => {
                return Err(header_error(path, format!("this DICOM object holds no image: {kind}")))
            }
            Entry::Unreadable(e) => return Err(e),
            Entry::NotDicom => {
                return Err(header_error(
                    path,
                    "no 'DICM' marker (at byte 128 or 0) and no recognisable data set: not a DICOM file",
                ))
            }
        }
        let dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let mut files = Vec::new();
        walk(dir, MAX_DEPTH, &mut files)?;
        files
    };
    scan_files(files, preselected)
}

/// Reads the headers of `files` and groups the images by series.
fn scan_files(files: Vec<PathBuf>, preselected: Option<String>) -> Result<Scan, VolumeError> {
    let entries: Vec<(PathBuf, Entry)> = files
        .into_par_iter()
        .map(|p| {
            let e = classify(&p);
            (p, e)
        })
        .collect();
    let mut scan = Scan {
        series: Vec::new(),
        not_dicom: 0,
        unreadable: Vec::new(),
        non_image: Vec::new(),
        preselected,
    };
    let mut groups: BTreeMap<String, Vec<ImageInfo>> = BTreeMap::new();
    for (path, entry) in entries {
        match entry {
            Entry::NotDicom | Entry::Directory => scan.not_dicom += 1,
            Entry::Unreadable(e) => scan.unreadable.push((path, e.to_string())),
            Entry::NonImage(kind) => scan.non_image.push((path, kind)),
            Entry::Image(info) => groups.entry(info.series_uid.clone()).or_default().push(*info),
        }
    }
    let mut series: Vec<SeriesInfo> = groups
        .into_iter()
        .map(|(uid, images)| {
            let first = &images[0];
            SeriesInfo {
                number: 0,
                description: first.series_description.clone(),
                modality: first.modality.clone(),
                series_number: first.series_number,
                columns: first.format.columns,
                rows: first.format.rows,
                frames: images.iter().map(|i| i.frames.len()).sum(),
                files: images.iter().map(|i| i.path.clone()).collect(),
                uid,
            }
        })
        .collect();
    // Series numbers as the scanner gave them, then UIDs.
    series.sort_by_key(|s| (s.series_number.unwrap_or(i64::MAX), s.uid.clone()));
    for (k, s) in series.iter_mut().enumerate() {
        s.number = k + 1;
    }
    scan.series = series;
    Ok(scan)
}

fn is_dicomdir(path: &Path) -> bool {
    path.file_name().is_some_and(|n| n.eq_ignore_ascii_case("DICOMDIR"))
}

/// Regular files under `dir`, at most [`MAX_DEPTH`] levels down (`depth` = levels already
/// taken; [`MAX_DEPTH`] lists `dir` alone), hidden ones left out, sorted.
fn walk(dir: &Path, depth: usize, out: &mut Vec<PathBuf>) -> Result<(), VolumeError> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(io_error(dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| !p.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.')))
        .collect();
    entries.sort();
    for p in entries {
        if out.len() >= MAX_FILES {
            return Err(header_error(
                dir,
                format!("more than {MAX_FILES} files in the folder tree"),
            ));
        }
        if p.is_file() && !is_dicomdir(&p) {
            out.push(p);
        } else if p.is_dir() && depth < MAX_DEPTH {
            walk(&p, depth + 1, out)?;
        }
    }
    Ok(())
}

/// The image files a DICOMDIR refers to (Referenced File ID, relative to its folder). Their
/// series come from the files themselves, so the order of the directory records does not
/// matter.
fn dicomdir_files(path: &Path) -> Result<Vec<PathBuf>, VolumeError> {
    let parsed = read_file(path, false)?;
    let root = path.parent().unwrap_or(Path::new("."));
    let records = parsed
        .object
        .get(tags::DIRECTORY_RECORD_SEQUENCE)
        .and_then(|e| e.items())
        .ok_or_else(|| header_error(path, "DICOMDIR without a Directory Record Sequence"))?;
    let mut files = Vec::new();
    for record in records {
        let Some(id) = record.get(tags::REFERENCED_FILE_ID).and_then(|e| e.to_multi_str().ok()) else {
            continue;
        };
        let mut file = root.to_path_buf();
        for part in id.iter() {
            let part = part.trim();
            if part.is_empty() || part == ".." || part.contains('/') {
                return Err(header_error(
                    path,
                    format!("Referenced File ID '{}' is not a relative path", id.join("\\")),
                ));
            }
            file.push(part);
        }
        if !file.is_file() {
            // Media written on other systems often differ in case.
            let lower = root.join(id.iter().map(|p| p.trim().to_ascii_lowercase()).collect::<PathBuf>());
            if lower.is_file() {
                file = lower;
            }
        }
        files.push(file);
    }
    if files.is_empty() {
        return Err(header_error(path, "the DICOMDIR refers to no files"));
    }
    Ok(files)
}
