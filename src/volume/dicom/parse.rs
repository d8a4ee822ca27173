//! One DICOM file into a dicom-rs object: Part-10 files with or without the 128-byte preamble,
//! bare data sets without a meta group (the transfer syntax is sniffed), and deflated data sets.
//!
//! dicom-rs allocates each value's declared length before reading it, so a few hostile bytes
//! could ask for gigabytes. Every element length is therefore checked against the bytes that
//! really follow ([`walk`]) before the library sees the data; the same walk finds where the
//! pixel data starts, so a header scan parses only the part before it.

use std::io::Read;
use std::path::Path;

use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry, VirtualVr};
use dicom_core::{Tag, VR};
use dicom_dictionary_std::StandardDataDictionary;
use dicom_object::{FileDicomObject, FileMetaTableBuilder, InMemDicomObject};
use dicom_transfer_syntax_registry::TransferSyntaxIndex;
use dicom_transfer_syntax_registry::TransferSyntaxRegistry;
use flate2::read::DeflateDecoder;

use super::header_error;
use crate::volume::read::io_error;
use crate::volume::VolumeError;

pub(crate) type Object = FileDicomObject<InMemDicomObject>;

/// Largest DICOM file read into memory.
pub(crate) const MAX_FILE_BYTES: u64 = 1 << 30;
/// Deepest nesting of sequences accepted.
const MAX_DEPTH: usize = 32;

pub(crate) const IMPLICIT_VR_LE: &str = "1.2.840.10008.1.2";
pub(crate) const EXPLICIT_VR_LE: &str = "1.2.840.10008.1.2.1";
const EXPLICIT_VR_BE: &str = "1.2.840.10008.1.2.2";
const DEFLATED: &str = "1.2.840.10008.1.2.1.99";

/// VRs with a 32-bit length; an unknown VR is read as UN.
const KNOWN_LONG: [&[u8; 2]; 13] = [
    b"OB", b"OD", b"OF", b"OL", b"OV", b"OW", b"SQ", b"SV", b"UC", b"UN", b"UR", b"UT", b"UV",
];

/// Pixel Data, Float Pixel Data and Double Float Pixel Data.
const PIXEL_TAGS: [(u16, u16); 3] = [(0x7FE0, 0x0010), (0x7FE0, 0x0008), (0x7FE0, 0x0009)];

/// A parsed file: the object, and whether it holds pixel data.
pub(crate) struct Parsed {
    pub object: Object,
    pub has_pixels: bool,
}

/// Reads and parses the DICOM file at `path`; with `headers_only` the pixel data is left out.
pub(crate) fn read_file(path: &Path, headers_only: bool) -> Result<Parsed, VolumeError> {
    let len = std::fs::metadata(path).map_err(io_error(path))?.len();
    if len > MAX_FILE_BYTES {
        return Err(header_error(path, format!("file of {len} bytes is larger than 1 GiB")));
    }
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    parse_bytes(&bytes, path, headers_only)
}

/// True when `bytes` start like a DICOM file: "DICM" at byte 128 or 0, or a bare data set
/// whose first element is a plausible group 0008 element.
pub(crate) fn looks_like_dicom(bytes: &[u8]) -> bool {
    bytes.get(128..132) == Some(b"DICM") || bytes.get(..4) == Some(b"DICM") || sniff_syntax(bytes).is_some()
}

/// Parses a whole file held in memory (see [`read_file`]).
pub(crate) fn parse_bytes(bytes: &[u8], path: &Path, headers_only: bool) -> Result<Parsed, VolumeError> {
    let meta_at = if bytes.get(128..132) == Some(b"DICM") {
        Some(132)
    } else if bytes.get(..4) == Some(b"DICM") {
        Some(4)
    } else {
        None
    };
    let (meta, data_at, syntax) = match meta_at {
        Some(at) => {
            let meta = read_meta(bytes, at).map_err(|m| header_error(path, format!("file meta group: {m}")))?;
            let syntax = meta.syntax.clone();
            if syntax.is_empty() {
                return Err(header_error(path, "the file meta group has no Transfer Syntax UID"));
            }
            (meta.elements, meta.end, syntax)
        }
        None => {
            let syntax = sniff_syntax(bytes).ok_or_else(|| {
                header_error(
                    path,
                    "no 'DICM' marker (at byte 128 or 0) and no recognisable data set: not a DICOM file",
                )
            })?;
            (MetaElements::default(), 0, syntax.to_string())
        }
    };
    let ts = TransferSyntaxRegistry
        .get(&syntax)
        .ok_or_else(|| header_error(path, format!("unknown transfer syntax '{syntax}'")))?;
    let inflated;
    let (data, data_syntax) = if syntax == DEFLATED {
        inflated = inflate(&bytes[data_at..]).map_err(|m| header_error(path, m))?;
        (&inflated[..], EXPLICIT_VR_LE)
    } else {
        if ts.is_unsupported() {
            return Err(header_error(
                path,
                format!("transfer syntax {} ({syntax}) cannot be read", ts.name()),
            ));
        }
        (&bytes[data_at..], syntax.as_str())
    };
    let explicit = data_syntax != IMPLICIT_VR_LE;
    let big = data_syntax == EXPLICIT_VR_BE;
    let pixels_at = walk(data, explicit, big).map_err(|m| header_error(path, m))?;
    let end = if headers_only {
        pixels_at.unwrap_or(data.len())
    } else {
        data.len()
    };
    let dataset_ts = TransferSyntaxRegistry
        .get(data_syntax)
        .ok_or_else(|| header_error(path, format!("unknown transfer syntax '{data_syntax}'")))?;
    let dataset = InMemDicomObject::read_dataset_with_ts(&data[..end], dataset_ts)
        .map_err(|e| header_error(path, format!("cannot parse the data set: {e}")))?;
    let sop_class = meta
        .sop_class
        .or_else(|| text_of(&dataset, Tag(0x0008, 0x0016)))
        .unwrap_or_default();
    let sop_instance = meta
        .sop_instance
        .or_else(|| text_of(&dataset, Tag(0x0008, 0x0018)))
        .unwrap_or_default();
    let file_meta = FileMetaTableBuilder::new()
        .transfer_syntax(syntax.as_str())
        .media_storage_sop_class_uid(sop_class)
        .media_storage_sop_instance_uid(sop_instance)
        .implementation_class_uid("2.25.0")
        .build()
        .map_err(|e| header_error(path, format!("file meta group: {e}")))?;
    Ok(Parsed {
        object: dataset.with_exact_meta(file_meta),
        has_pixels: pixels_at.is_some(),
    })
}

fn text_of(obj: &InMemDicomObject, tag: Tag) -> Option<String> {
    let text = obj.get(tag)?.to_str().ok()?;
    Some(text.trim_end_matches(['\0', ' ']).to_string())
}

#[derive(Default)]
struct MetaElements {
    sop_class: Option<String>,
    sop_instance: Option<String>,
}

struct Meta {
    elements: MetaElements,
    syntax: String,
    /// Offset of the first data-set byte.
    end: usize,
}

/// The file meta group (always explicit VR little endian) from byte `at` on.
fn read_meta(bytes: &[u8], at: usize) -> Result<Meta, String> {
    let mut cur = Cursor::new(bytes, at, bytes.len(), true, false);
    let mut meta = Meta {
        elements: MetaElements::default(),
        syntax: String::new(),
        end: at,
    };
    while cur.at < bytes.len() {
        let start = cur.at;
        let Some(h) = cur.header() else {
            return Err("ends inside an element header".into());
        };
        if h.group != 0x0002 {
            cur.at = start;
            break;
        }
        let len = h.len.ok_or("an element of undefined length")?;
        let value = cur.take(len).ok_or("an element runs past the end of the file")?;
        let text = || {
            String::from_utf8_lossy(value)
                .trim_end_matches(['\0', ' '])
                .trim()
                .to_string()
        };
        match h.element {
            0x0002 => meta.elements.sop_class = Some(text()),
            0x0003 => meta.elements.sop_instance = Some(text()),
            0x0010 => meta.syntax = text(),
            _ => {}
        }
    }
    meta.end = cur.at;
    Ok(meta)
}

/// The transfer syntax of a data set without a meta group, from its first element: explicit
/// VR when bytes 4–5 are a VR, byte order from the group number (groups 0002–0028 are small).
fn sniff_syntax(bytes: &[u8]) -> Option<&'static str> {
    let head = bytes.get(..8)?;
    let le = u16::from_le_bytes([head[0], head[1]]);
    let be = u16::from_be_bytes([head[0], head[1]]);
    let vr_like = head[4].is_ascii_uppercase() && head[5].is_ascii_uppercase();
    let plausible = |g: u16| (0x0002..=0x0028).contains(&g) && g % 2 == 0;
    match (plausible(le), plausible(be), vr_like) {
        (true, _, true) => Some(EXPLICIT_VR_LE),
        (true, _, false) => Some(IMPLICIT_VR_LE),
        (false, true, true) => Some(EXPLICIT_VR_BE),
        _ => None,
    }
}

/// Inflates a deflated data set, at most [`MAX_FILE_BYTES`].
fn inflate(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    DeflateDecoder::new(bytes)
        .take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut out)
        .map_err(|e| format!("deflated data set: {e}"))?;
    if out.len() as u64 > MAX_FILE_BYTES {
        return Err("deflated data set inflates to more than 1 GiB".into());
    }
    Ok(out)
}

struct Header {
    group: u16,
    element: u16,
    vr: [u8; 2],
    /// `None`: undefined length.
    len: Option<u32>,
}

struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    /// End of the enclosing item or value.
    end: usize,
    explicit: bool,
    big: bool,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8], at: usize, end: usize, explicit: bool, big: bool) -> Cursor<'a> {
        Cursor {
            bytes,
            at,
            end,
            explicit,
            big,
        }
    }

    fn word<const N: usize>(&mut self) -> Option<[u8; N]> {
        let end = self.at.checked_add(N).filter(|e| *e <= self.end)?;
        let out: [u8; N] = self.bytes.get(self.at..end)?.try_into().ok()?;
        self.at = end;
        Some(out)
    }

    fn u16(&mut self) -> Option<u16> {
        let b = self.word::<2>()?;
        Some(if self.big {
            u16::from_be_bytes(b)
        } else {
            u16::from_le_bytes(b)
        })
    }

    fn u32(&mut self) -> Option<u32> {
        let b = self.word::<4>()?;
        Some(if self.big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }

    fn header(&mut self) -> Option<Header> {
        let group = self.u16()?;
        let element = self.u16()?;
        let defined = |len: u32| (len != u32::MAX).then_some(len);
        // Items and delimiters never carry a VR; in implicit VR the dictionary tells which
        // elements are sequences (so their items are checked too).
        if group == 0xFFFE || !self.explicit {
            let len = self.u32()?;
            let sequence = group != 0xFFFE
                && StandardDataDictionary
                    .by_tag(Tag(group, element))
                    .is_some_and(|e| e.vr() == VirtualVr::Exact(VR::SQ));
            return Some(Header {
                group,
                element,
                vr: if sequence { *b"SQ" } else { *b"UN" },
                len: defined(len),
            });
        }
        let vr = self.word::<2>()?;
        // As dicom-rs reads it: these VRs have a 16-bit length; every other VR, unknown ones
        // included (read as UN), has 2 reserved bytes and a 32-bit length.
        let long = !matches!(
            &vr,
            b"AE"
                | b"AS"
                | b"AT"
                | b"CS"
                | b"DA"
                | b"DS"
                | b"DT"
                | b"FL"
                | b"FD"
                | b"IS"
                | b"LO"
                | b"LT"
                | b"PN"
                | b"SH"
                | b"SL"
                | b"SS"
                | b"ST"
                | b"TM"
                | b"UI"
                | b"UL"
                | b"US"
        );
        let vr = if long && !KNOWN_LONG.contains(&&vr) { *b"UN" } else { vr };
        let len = if long {
            self.word::<2>()?;
            self.u32()?
        } else {
            u32::from(self.u16()?)
        };
        Some(Header {
            group,
            element,
            vr,
            len: defined(len),
        })
    }

    fn take(&mut self, len: u32) -> Option<&'a [u8]> {
        let end = self.at.checked_add(len as usize).filter(|e| *e <= self.end)?;
        let out = self.bytes.get(self.at..end)?;
        self.at = end;
        Some(out)
    }
}

/// Checks that every element of a data set fits in the bytes that follow it (sequences,
/// items and encapsulated fragments included), and returns the offset of the top-level pixel
/// data element, if any.
pub(crate) fn walk(bytes: &[u8], explicit: bool, big: bool) -> Result<Option<usize>, String> {
    let mut cur = Cursor::new(bytes, 0, bytes.len(), explicit, big);
    walk_items(&mut cur, 0, true)
}

/// Walks elements until the cursor's end or an item/sequence delimiter. At the top level,
/// returns where the pixel data starts.
fn walk_items(cur: &mut Cursor, depth: usize, top: bool) -> Result<Option<usize>, String> {
    if depth > MAX_DEPTH {
        return Err(format!("sequences nested more than {MAX_DEPTH} deep"));
    }
    let mut pixels_at = None;
    while cur.at < cur.end {
        let start = cur.at;
        let h = cur
            .header()
            .ok_or_else(|| format!("data set ends inside an element header at byte {start}"))?;
        if h.group == 0xFFFE && matches!(h.element, 0xE00D | 0xE0DD) {
            if top {
                return Err(format!("stray delimiter at byte {start}"));
            }
            return Ok(None);
        }
        let tag = (h.group, h.element);
        if top && pixels_at.is_none() && PIXEL_TAGS.contains(&tag) {
            pixels_at = Some(start);
        }
        match h.len {
            Some(len) => {
                let value_at = cur.at;
                cur.take(len).ok_or_else(|| {
                    format!(
                        "element ({:04X},{:04X}) at byte {start} claims {len} bytes but only {} follow",
                        h.group,
                        h.element,
                        cur.end.saturating_sub(value_at)
                    )
                })?;
                // A defined-length sequence: its items must fit inside it.
                if &h.vr == b"SQ" || (h.group == 0xFFFE && h.element == 0xE000 && !top) {
                    let mut inner = Cursor::new(cur.bytes, value_at, cur.at, cur.explicit, cur.big);
                    if &h.vr == b"SQ" {
                        walk_sequence(&mut inner, depth + 1)?;
                    } else {
                        walk_items(&mut inner, depth + 1, false)?;
                    }
                }
            }
            None if PIXEL_TAGS.contains(&tag) => walk_fragments(cur)?,
            None => {
                // Undefined length: a sequence; VR UN of undefined length holds implicit VR
                // little endian items.
                let explicit = cur.explicit && &h.vr != b"UN";
                let big = cur.big && &h.vr != b"UN";
                let mut inner = Cursor::new(cur.bytes, cur.at, cur.end, explicit, big);
                walk_sequence(&mut inner, depth + 1)?;
                cur.at = inner.at;
            }
        }
    }
    Ok(pixels_at)
}

/// Items of a sequence until its end or its delimiter.
fn walk_sequence(cur: &mut Cursor, depth: usize) -> Result<(), String> {
    while cur.at < cur.end {
        let start = cur.at;
        let h = cur.header().ok_or("sequence ends inside an item header")?;
        match (h.group, h.element, h.len) {
            (0xFFFE, 0xE0DD, _) => return Ok(()),
            (0xFFFE, 0xE000, Some(len)) => {
                let value_at = cur.at;
                cur.take(len)
                    .ok_or_else(|| format!("item at byte {start} claims {len} bytes past its end"))?;
                let mut inner = Cursor::new(cur.bytes, value_at, cur.at, cur.explicit, cur.big);
                walk_items(&mut inner, depth, false)?;
            }
            (0xFFFE, 0xE000, None) => walk_items(cur, depth, false).map(|_| ())?,
            _ => {
                return Err(format!(
                    "expected an item in a sequence at byte {start}, found ({:04X},{:04X})",
                    h.group, h.element
                ))
            }
        }
    }
    Ok(())
}

/// The fragments of encapsulated pixel data, up to the sequence delimiter.
fn walk_fragments(cur: &mut Cursor) -> Result<(), String> {
    loop {
        let start = cur.at;
        let h = cur.header().ok_or("pixel data ends inside a fragment header")?;
        match (h.group, h.element, h.len) {
            (0xFFFE, 0xE0DD, _) => return Ok(()),
            (0xFFFE, 0xE000, Some(len)) => {
                cur.take(len)
                    .ok_or_else(|| format!("pixel data fragment at byte {start} runs past the end of the file"))?;
            }
            _ => return Err(format!("malformed encapsulated pixel data at byte {start}")),
        }
    }
}
