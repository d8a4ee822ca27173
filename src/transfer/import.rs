//! Transfer functions from other tools: ParaView colour maps (JSON `RGBPoints`, `Points`),
//! Inviwo `.itf` and 3D Slicer `presets.xml` (`scalarOpacity`, `colorTransfer`). Only colour
//! and opacity are imported; η and the medium keep their defaults (1 and white). Positions in
//! data units become the window ([`Imported::domain`]) and are rescaled to [0, 1].

use std::path::{Path, PathBuf};

use super::{ColorRamp, Curve, TransferError, TransferFunctions};

/// Imported transfer functions and the data range their positions spanned (`None` when the
/// file uses normalised positions already).
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    pub tf: TransferFunctions,
    pub domain: Option<[f32; 2]>,
}

fn parse_error(path: &Path, message: impl Into<String>) -> TransferError {
    TransferError::Import {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Loads caustica JSON or any importable format, chosen by extension and content. A preset of
/// a multi-preset file (Slicer presets.xml, a ParaView list) is picked with `FILE#NAME`;
/// without a name the first one is used.
pub fn load_any(spec: &Path) -> Result<Imported, TransferError> {
    let (path, name) = split_name(spec);
    let text = std::fs::read_to_string(&path).map_err(|source| TransferError::Io {
        path: path.clone(),
        source,
    })?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let (format, imported) = if ext == "itf" || text.contains("<InviwoWorkspace") {
        ("Inviwo transfer-function", inviwo(&text, &path)?)
    } else if ext == "xml" || text.trim_start().starts_with('<') {
        ("3D Slicer presets", slicer(&text, &path, name.as_deref())?)
    } else {
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| TransferError::Parse {
            path: path.clone(),
            message: e.to_string(),
        })?;
        let native = value.as_object().is_some_and(|o| o.contains_key("opacity"));
        if native {
            (
                "transfer-function JSON",
                Imported {
                    tf: TransferFunctions::from_json(&text, &path)?,
                    domain: None,
                },
            )
        } else {
            ("ParaView colour-map JSON", paraview(&value, &path, name.as_deref())?)
        }
    };
    imported.tf.validate().map_err(|e| e.in_file(&path, format))?;
    Ok(imported)
}

fn split_name(spec: &Path) -> (PathBuf, Option<String>) {
    if spec.exists() {
        return (spec.to_path_buf(), None);
    }
    let text = spec.to_string_lossy();
    match text.rsplit_once('#') {
        Some((file, name)) => (PathBuf::from(file), Some(name.to_string())),
        None => (spec.to_path_buf(), None),
    }
}

/// Builds [`Imported`] from opacity points `[x, a]` and colour points `[x, r, g, b]` in data
/// units (or normalised when `normalised`).
fn build(
    name: String,
    opacity: Vec<[f32; 2]>,
    color: Vec<[f32; 4]>,
    normalised: bool,
    path: &Path,
) -> Result<Imported, TransferError> {
    let xs = opacity.iter().map(|p| p[0]).chain(color.iter().map(|p| p[0]));
    let (lo, hi) = xs.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(parse_error(path, "no control points"));
    }
    // x ↦ (x − offset) · scale onto [0, 1]; identity for positions already normalised.
    let (domain, offset, scale) = if normalised && lo >= 0.0 && hi <= 1.0 {
        (None, 0.0, 1.0)
    } else if hi > lo {
        (Some([lo, hi]), lo, 1.0 / (hi - lo))
    } else {
        (None, lo, 0.0)
    };
    let map = |x: f32| ((x - offset) * scale).clamp(0.0, 1.0);
    let mut opacity: Vec<[f32; 2]> = opacity.iter().map(|p| [map(p[0]), p[1].clamp(0.0, 1.0)]).collect();
    let mut color: Vec<[f32; 4]> = color
        .iter()
        .map(|p| {
            [
                map(p[0]),
                p[1].clamp(0.0, 1.0),
                p[2].clamp(0.0, 1.0),
                p[3].clamp(0.0, 1.0),
            ]
        })
        .collect();
    opacity.sort_by(|a, b| a[0].total_cmp(&b[0]));
    color.sort_by(|a, b| a[0].total_cmp(&b[0]));
    let defaults = TransferFunctions::default();
    let tf = TransferFunctions {
        name: Some(name),
        opacity: if opacity.is_empty() {
            defaults.opacity
        } else {
            Curve { points: opacity }
        },
        color: if color.is_empty() {
            defaults.color
        } else {
            ColorRamp { points: color }
        },
        ..defaults
    };
    Ok(Imported { tf, domain })
}

fn numbers(value: &serde_json::Value, key: &str, path: &Path) -> Result<Vec<f32>, TransferError> {
    match value.get(key) {
        None => Ok(Vec::new()),
        Some(serde_json::Value::Array(items)) => items
            .iter()
            .map(|v| {
                v.as_f64()
                    .map(|f| f as f32)
                    .ok_or_else(|| parse_error(path, format!("{key} holds a non-number")))
            })
            .collect(),
        Some(_) => Err(parse_error(path, format!("{key} must be an array of numbers"))),
    }
}

/// ParaView: `[{"Name": .., "RGBPoints": [x, r, g, b, ...], "Points": [x, a, midpoint, sharpness, ...]}]`
/// (or one such object). Midpoint and sharpness are ignored: segments are linear.
fn paraview(value: &serde_json::Value, path: &Path, name: Option<&str>) -> Result<Imported, TransferError> {
    let maps: Vec<&serde_json::Value> = match value {
        serde_json::Value::Array(items) => items.iter().collect(),
        other => vec![other],
    };
    let map = match name {
        Some(n) => maps
            .iter()
            .find(|m| m.get("Name").and_then(|v| v.as_str()) == Some(n))
            .copied(),
        None => maps.first().copied(),
    }
    .ok_or_else(|| parse_error(path, format!("no ParaView colour map named '{}'", name.unwrap_or(""))))?;
    let rgb = numbers(map, "RGBPoints", path)?;
    let points = numbers(map, "Points", path)?;
    if rgb.is_empty() && points.is_empty() {
        return Err(parse_error(
            path,
            "neither RGBPoints nor Points: not a ParaView colour map",
        ));
    }
    if rgb.len() % 4 != 0 || points.len() % 4 != 0 {
        return Err(parse_error(path, "RGBPoints and Points must hold groups of 4 numbers"));
    }
    let color = rgb.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
    let opacity = points.chunks_exact(4).map(|c| [c[0], c[1]]).collect();
    let title = map
        .get("Name")
        .and_then(|v| v.as_str())
        .unwrap_or("paraview")
        .to_string();
    build(title, opacity, color, false, path)
}

fn xml<'a>(text: &'a str, path: &Path) -> Result<roxmltree::Document<'a>, TransferError> {
    roxmltree::Document::parse(text).map_err(|e| parse_error(path, format!("invalid XML: {e}")))
}

fn attr_f32(node: roxmltree::Node<'_, '_>, name: &str) -> Option<f32> {
    node.attribute(name)?.trim().parse().ok()
}

/// Inviwo `.itf`: `<Point><pos content=".."/><rgba x y z w/></Point>`; w is the opacity.
fn inviwo(text: &str, path: &Path) -> Result<Imported, TransferError> {
    let doc = xml(text, path)?;
    let mut opacity = Vec::new();
    let mut color = Vec::new();
    for point in doc
        .descendants()
        .filter(|n| n.tag_name().name().eq_ignore_ascii_case("point"))
    {
        let child = |name: &str| {
            point
                .children()
                .find(|c| c.tag_name().name().eq_ignore_ascii_case(name))
        };
        let pos = child("pos").and_then(|p| attr_f32(p, "content").or_else(|| attr_f32(p, "x")));
        let rgba = child("rgba").and_then(|c| {
            Some([
                attr_f32(c, "x")?,
                attr_f32(c, "y")?,
                attr_f32(c, "z")?,
                attr_f32(c, "w")?,
            ])
        });
        let (Some(x), Some([r, g, b, a])) = (pos, rgba) else {
            return Err(parse_error(path, "an Inviwo Point needs pos and rgba (x, y, z, w)"));
        };
        opacity.push([x, a]);
        color.push([x, r, g, b]);
    }
    if opacity.is_empty() {
        return Err(parse_error(path, "no Inviwo transfer-function points"));
    }
    // type 1 means positions in data units; otherwise they are relative to the data range.
    let absolute = doc
        .descendants()
        .find(|n| n.has_tag_name("type"))
        .and_then(|n| n.attribute("content"))
        .is_some_and(|c| c.trim() == "1");
    build("inviwo".into(), opacity, color, !absolute, path)
}

/// 3D Slicer `presets.xml`: `<VolumeProperty name=".." scalarOpacity="n x a ..." colorTransfer="n x r g b ..."/>`.
fn slicer(text: &str, path: &Path, name: Option<&str>) -> Result<Imported, TransferError> {
    let doc = xml(text, path)?;
    let mut props = doc.descendants().filter(|n| n.has_tag_name("VolumeProperty"));
    let prop = match name {
        Some(n) => props.find(|p| p.attribute("name") == Some(n)),
        None => props.next(),
    }
    .ok_or_else(|| {
        parse_error(
            path,
            format!(
                "no Slicer VolumeProperty{}",
                name.map(|n| format!(" named '{n}'")).unwrap_or_default()
            ),
        )
    })?;
    let list = |attr: &str, group: usize| -> Result<Vec<f32>, TransferError> {
        let text = prop.attribute(attr).unwrap_or("");
        let values: Vec<f32> = text
            .split_whitespace()
            .map(|t| {
                t.parse()
                    .map_err(|_| parse_error(path, format!("{attr}: '{t}' is not a number")))
            })
            .collect::<Result<_, _>>()?;
        let Some((&count, rest)) = values.split_first() else {
            return Ok(Vec::new());
        };
        if count as usize != rest.len() || rest.len() % group != 0 {
            return Err(parse_error(
                path,
                format!("{attr} announces {count} numbers but holds {}", rest.len()),
            ));
        }
        Ok(rest.to_vec())
    };
    let opacity = list("scalarOpacity", 2)?
        .chunks_exact(2)
        .map(|c| [c[0], c[1]])
        .collect();
    let color = list("colorTransfer", 4)?
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    build(
        prop.attribute("name").unwrap_or("slicer").to_string(),
        opacity,
        color,
        false,
        path,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory for one test's files (left in the temp dir; they are tiny).
    fn scratch(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("caustica-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create scratch dir");
        dir
    }

    #[test]
    fn paraview_points_become_a_window_and_normalised_curves() {
        let dir = scratch("tf-paraview");
        let json = r#"[{"Name": "A", "RGBPoints": [-1000, 0, 0, 0, 1000, 1, 0.5, 0], "Points": [-1000, 0, 0.5, 0, 0, 0.2, 0.5, 0, 1000, 1, 0.5, 0]},
                       {"Name": "B", "RGBPoints": [0, 1, 1, 1, 1, 0, 0, 0]}]"#;
        let p = dir.join("maps.json");
        std::fs::write(&p, json).unwrap();
        let a = load_any(&p).expect("first map");
        assert_eq!(a.domain, Some([-1000.0, 1000.0]));
        assert_eq!(a.tf.opacity.points, vec![[0.0, 0.0], [0.5, 0.2], [1.0, 1.0]]);
        assert_eq!(a.tf.color.eval(1.0), [1.0, 0.5, 0.0]);
        assert!(a.tf.eta_is_constant() && a.tf.medium_is_white());
        let b = load_any(&dir.join("maps.json#B")).expect("named map");
        assert_eq!(b.tf.name.as_deref(), Some("B"));
        assert_eq!(
            b.tf.opacity,
            TransferFunctions::default().opacity,
            "no Points: default opacity"
        );
        let err = load_any(&dir.join("maps.json#C")).unwrap_err().to_string();
        assert!(err.contains("no ParaView colour map named 'C'"), "{err}");
    }

    #[test]
    fn inviwo_itf_relative_positions() {
        let dir = scratch("tf-inviwo");
        let itf = r#"<?xml version="1.0" ?>
<InviwoWorkspace version="2">
    <maskMin content="0" /><maskMax content="1" /><type content="0" />
    <Points>
        <Point><pos content="0.25" /><rgba x="1" y="0" z="0" w="0" /></Point>
        <Point><pos content="0.75" /><rgba x="0" y="0" z="1" w="0.8" /></Point>
    </Points>
</InviwoWorkspace>"#;
        let p = dir.join("tf.itf");
        std::fs::write(&p, itf).unwrap();
        let i = load_any(&p).expect("itf");
        assert_eq!(i.domain, None);
        assert_eq!(i.tf.opacity.eval(0.5), 0.4);
        assert_eq!(i.tf.color.eval(0.25), [1.0, 0.0, 0.0]);
    }

    #[test]
    fn slicer_presets_by_name() {
        let dir = scratch("tf-slicer");
        let xml = r#"<?xml version="1.0" encoding="UTF-8"?>
<collection>
  <VolumeProperty name="CT-Bone" scalarOpacity="8 -3024 0 -16 0 641 0.72 3071 0.71" colorTransfer="16 -3024 0 0 0 -16 0.73 0.25 0.30 641 0.90 0.82 0.56 3071 1 1 1" />
  <VolumeProperty name="MR-Default" scalarOpacity="4 0 0 100 1" colorTransfer="8 0 0 0 0 100 1 1 1" />
</collection>"#;
        let p = dir.join("presets.xml");
        std::fs::write(&p, xml).unwrap();
        let bone = load_any(&p).expect("first preset");
        assert_eq!(bone.tf.name.as_deref(), Some("CT-Bone"));
        assert_eq!(bone.domain, Some([-3024.0, 3071.0]));
        let x641 = (641.0 + 3024.0) / 6095.0;
        assert!((bone.tf.opacity.eval(x641) - 0.72).abs() < 1e-5);
        let mr = load_any(&dir.join("presets.xml#MR-Default")).expect("named preset");
        assert_eq!(mr.domain, Some([0.0, 100.0]));
        assert_eq!(mr.tf.opacity.eval(0.5), 0.5);
    }

    #[test]
    fn malformed_imports_fail_clearly() {
        let dir = scratch("tf-bad");
        let cases = [
            ("a.json", r#"[{"Name": "x", "RGBPoints": [0, 1, 1]}]"#, "groups of 4"),
            ("b.json", r#"{"foo": 1}"#, "not a ParaView colour map"),
            ("c.json", "{", "not valid JSON"),
            (
                "d.itf",
                "<InviwoWorkspace><Points><Point><pos content=\"0\"/></Point></Points></InviwoWorkspace>",
                "needs pos and rgba",
            ),
            (
                "e.xml",
                "<collection><VolumeProperty name=\"x\" scalarOpacity=\"6 0 0 1\"/></collection>",
                "announces 6",
            ),
            ("f.xml", "<collection>", "invalid XML"),
            ("g.json", r#"[{"RGBPoints": [0, 2, 0, 0, "x", 0, 0, 0]}]"#, "non-number"),
        ];
        for (name, text, expected) in cases {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            let err = load_any(&p).unwrap_err().to_string();
            assert!(err.contains(expected), "{name}: '{err}' should mention '{expected}'");
        }
    }
}
