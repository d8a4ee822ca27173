//! Built-in scenes: procedural volumes (see `volume::procedural`) with their transfer
//! functions (`transfer_functions/*.json`), camera and light.

use std::path::Path;

use super::{Camera, Environment, Light, Quality, Scene, SceneError, Shading, TransferSource, VolumeSource};
use crate::transfer::TransferFunctions;

/// A named built-in scene.
pub struct BuiltinScene {
    pub name: &'static str,
    pub description: &'static str,
    pub scene: Scene,
}

/// (name, volume generator, transfer functions, description)
const TABLE: &[(&str, &str, &str, &str)] = &[
    (
        "ball-lens",
        "ball-lens",
        include_str!("../../transfer_functions/ball-lens.json"),
        "glass ball (n = 1.5) above a diffuse ground: a caustic spot in its shadow",
    ),
    (
        "glass-beer",
        "glass",
        include_str!("../../transfer_functions/glass-beer.json"),
        "glass of a clear amber drink: coloured caustics, no particle opacity (paper Fig. 8c)",
    ),
    (
        "glass-juice",
        "glass",
        include_str!("../../transfer_functions/glass-juice.json"),
        "glass of juice: an absorbing liquid casts a dark shadow (paper Fig. 8d)",
    ),
    (
        "glass-wine",
        "glass",
        include_str!("../../transfer_functions/glass-wine.json"),
        "red wine in green-tinted glass (paper Fig. 8e)",
    ),
    (
        "supernova",
        "supernova",
        include_str!("../../transfer_functions/supernova.json"),
        "layered sphere with a transparent purple refractive shell over a ground plane (paper Fig. 6)",
    ),
    (
        "luneburg",
        "luneburg",
        include_str!("../../transfer_functions/luneburg.json"),
        "Luneburg lens, η = sqrt(2 − r²/R²): parallel light focuses on its far surface",
    ),
    (
        "thin-structures",
        "thin-structures",
        include_str!("../../transfer_functions/thin-structures.json"),
        "faint thin legs, visible through refraction and caustics on a checkered floor (paper Fig. 11 idea)",
    ),
    (
        "milk-glass",
        "ball-lens",
        include_str!("../../transfer_functions/milk-glass.json"),
        "milk-glass ball (albedo 0.97, g 0.6) above a diffuse ground: the light it scatters glows in its shadow (multiple scattering, spread mode)",
    ),
];

/// Names of the built-in scenes, in `caustica scenes` order.
pub const BUILTIN_SCENES: [&str; 8] = [
    "ball-lens",
    "glass-beer",
    "glass-juice",
    "glass-wine",
    "supernova",
    "luneburg",
    "thin-structures",
    "milk-glass",
];

fn camera(yaw_deg: f32, pitch_deg: f32, distance: f32) -> Camera {
    Camera {
        yaw_deg,
        pitch_deg,
        distance,
        ..Camera::default()
    }
}

fn light(polar_deg: f32, azimuth_deg: f32, softness: f32) -> Light {
    Light {
        polar_deg,
        azimuth_deg,
        softness,
        ..Light::default()
    }
}

/// The built-in scene `name` at the default resolution (128 voxels along the longest axis).
pub fn builtin(name: &str) -> Result<BuiltinScene, SceneError> {
    let Some((name, generator, tf_json, description)) = TABLE.iter().find(|row| row.0 == name) else {
        return Err(SceneError::Invalid(format!(
            "unknown built-in scene '{name}'; available: {}",
            BUILTIN_SCENES.join(", ")
        )));
    };
    let tf = TransferFunctions::from_json(tf_json, Path::new(&format!("transfer_functions/{name}.json")))?;
    let (camera, light) = match *name {
        "ball-lens" | "milk-glass" => (camera(20.0, 35.0, 2.6), light(55.0, -45.0, 0.02)),
        "supernova" => (camera(0.0, 22.0, 2.7), light(40.0, 0.0, 0.05)),
        "luneburg" => (camera(25.0, 28.0, 2.6), light(38.0, 0.0, 0.02)),
        "thin-structures" => (camera(30.0, 35.0, 2.5), light(40.0, 20.0, 0.03)),
        _ => (camera(25.0, 18.0, 2.6), light(35.0, -25.0, 0.04)),
    };
    Ok(BuiltinScene {
        name,
        description,
        scene: Scene {
            volume: VolumeSource::builtin(generator, 128),
            eta_volume: None,
            window: Some([0.0, 1.0]),
            transfer: TransferSource::Inline(tf),
            camera,
            light,
            shading: Shading::default(),
            clip: None,
            environment: Environment::default(),
            quality: Quality::default(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_scene_is_valid_and_round_trips_through_toml() {
        for name in BUILTIN_SCENES {
            let s = builtin(name).unwrap().scene;
            s.validate().unwrap();
            let text = s.to_toml();
            let back: Scene = toml::from_str(&text).unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
            assert_eq!(back, s, "{name}");
        }
        assert!(builtin("nope").is_err());
    }
}
