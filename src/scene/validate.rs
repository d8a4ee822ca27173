//! Range checks for every number of a scene a user can type.

use super::{
    Environment, Scene, SceneError, TransferSource, MAX_BEAMS_PER_TEXEL, MAX_CONCENTRATION, MAX_LIGHT_POLAR_DEG,
    MAX_LIGHT_RADIANCE, MAX_SOFTNESS, MAX_SPECULAR, MIN_BEAMS_PER_TEXEL,
};

impl Scene {
    /// Range checks for everything a user can type.
    pub fn validate(&self) -> Result<(), SceneError> {
        let bad = |m: String| Err(SceneError::Invalid(m));
        if let TransferSource::Inline(tf) = &self.transfer {
            tf.validate()?;
        }
        let q = &self.quality;
        if !(q.sample_distance.is_finite() && (0.01..=16.0).contains(&q.sample_distance)) {
            return bad(format!(
                "quality.sample_distance {} must be in [0.01, 16]",
                q.sample_distance
            ));
        }
        if !(q.max_intensity_ratio.is_finite() && q.max_intensity_ratio >= 1.0) {
            return bad("quality.max_intensity_ratio must be ≥ 1".into());
        }
        if let Some(c) = q.max_concentration {
            if !(c.is_finite() && (1.0..=MAX_CONCENTRATION).contains(&c)) {
                return bad(format!("quality.max_concentration must be in [1, {MAX_CONCENTRATION}]"));
            }
        }
        if !(q.beams_per_texel.is_finite() && (MIN_BEAMS_PER_TEXEL..=MAX_BEAMS_PER_TEXEL).contains(&q.beams_per_texel))
        {
            return bad(format!(
                "quality.beams_per_texel {} must be in [{MIN_BEAMS_PER_TEXEL}, {MAX_BEAMS_PER_TEXEL}]",
                q.beams_per_texel
            ));
        }
        if q.volume_level > super::MAX_VOLUME_LEVEL {
            return bad(format!(
                "quality.volume_level {} must be 0 (the volume as loaded) or 1 (half resolution)",
                q.volume_level
            ));
        }
        q.lbm.check().map_err(SceneError::Invalid)?;
        if q.multiple_scattering == super::MultipleScattering::Spread
            && q.light_transport != super::LightTransport::Beams
        {
            return bad(format!(
                "quality.multiple_scattering = \"spread\" needs light_transport = \"beams\" (not \"{}\")",
                q.light_transport.name()
            ));
        }
        if !(0.0..=1.0).contains(&q.termination_opacity) {
            return bad("quality.termination_opacity must be in [0, 1]".into());
        }
        let l = &self.light;
        if !(0.0..=MAX_LIGHT_POLAR_DEG).contains(&l.polar_deg) {
            return bad(format!(
                "light.polar_deg {} must be in [0, {MAX_LIGHT_POLAR_DEG}]: the light must be in the viewer's hemisphere",
                l.polar_deg
            ));
        }
        if !(0.0..=MAX_SOFTNESS).contains(&l.softness) {
            return bad(format!("light.softness {} must be in [0, {MAX_SOFTNESS}]", l.softness));
        }
        if l.color.iter().chain([&l.intensity]).any(|c| !c.is_finite() || *c < 0.0) {
            return bad("light colour and intensity must be finite and ≥ 0".into());
        }
        if l.color.iter().any(|c| c * l.intensity > MAX_LIGHT_RADIANCE) {
            return bad(format!(
                "light colour × intensity must be at most {MAX_LIGHT_RADIANCE} (16-bit light buffers)"
            ));
        }
        let s = &self.shading;
        if !(s.specular.is_finite() && (0.0..=MAX_SPECULAR).contains(&s.specular)) {
            return bad(format!(
                "shading.specular {} must be in [0, {MAX_SPECULAR}]",
                s.specular
            ));
        }
        if !(0.0..=1.0).contains(&s.roughness) {
            return bad(format!("shading.roughness {} must be in [0, 1]", s.roughness));
        }
        if !l.azimuth_deg.is_finite() {
            return bad("light.azimuth_deg must be finite".into());
        }
        let c = &self.camera;
        let camera_ok = c.distance.is_finite()
            && c.distance > 0.0
            && (1.0..=170.0).contains(&c.fov_deg)
            && c.zoom.is_finite()
            && c.zoom > 0.0
            && [c.yaw_deg, c.pitch_deg, c.roll_deg]
                .iter()
                .chain(&c.target)
                .all(|v| v.is_finite());
        if !camera_ok {
            return bad(
                "camera: distance and zoom must be finite and > 0, fov_deg in [1, 170], angles and target finite"
                    .into(),
            );
        }
        let env_ok = match &self.environment {
            Environment::Studio { intensity } | Environment::Image { intensity, .. } => {
                intensity.is_finite() && (0.0..=MAX_LIGHT_RADIANCE).contains(intensity)
            }
            Environment::Color { color } => color
                .iter()
                .all(|v| v.is_finite() && (0.0..=MAX_LIGHT_RADIANCE).contains(v)),
        };
        if !env_ok {
            return bad(format!(
                "environment intensity and colour must be finite and in [0, {MAX_LIGHT_RADIANCE}]"
            ));
        }
        if let Some(w) = self.window {
            if !(w[0].is_finite() && w[1].is_finite() && w[1] > w[0]) {
                return bad(format!("window {w:?} must be two finite values, low < high"));
            }
        }
        if let Some(clip) = &self.clip {
            if clip.normal.iter().all(|v| *v == 0.0) || clip.normal.iter().any(|v| !v.is_finite()) {
                return bad("clip.normal must be a finite non-zero vector".into());
            }
            if !clip.offset.is_finite() {
                return bad("clip.offset must be finite".into());
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{builtin, ClipPlane};

    /// Every number a user can type is range-checked: NaN, ±Inf and out-of-range values of
    /// each field are rejected with a message naming the field.
    #[test]
    fn non_finite_and_out_of_range_values_are_rejected() {
        let base = builtin("ball-lens").unwrap().scene;
        base.validate().unwrap();
        type Edit = fn(&mut Scene, f32);
        let fields: [(&str, Edit); 17] = [
            ("sample_distance", |s, v| s.quality.sample_distance = v),
            ("max_intensity_ratio", |s, v| s.quality.max_intensity_ratio = v),
            ("max_concentration", |s, v| s.quality.max_concentration = Some(v)),
            ("beams_per_texel", |s, v| s.quality.beams_per_texel = v),
            ("termination_opacity", |s, v| s.quality.termination_opacity = v),
            ("light.polar_deg", |s, v| s.light.polar_deg = v),
            ("light.azimuth_deg", |s, v| s.light.azimuth_deg = v),
            ("light.softness", |s, v| s.light.softness = v),
            ("light colour", |s, v| s.light.intensity = v),
            ("shading.specular", |s, v| s.shading.specular = v),
            ("shading.roughness", |s, v| s.shading.roughness = v),
            ("camera", |s, v| s.camera.distance = v),
            ("camera", |s, v| s.camera.zoom = v),
            ("camera", |s, v| s.camera.yaw_deg = v),
            ("camera", |s, v| s.camera.target[1] = v),
            ("environment", |s, v| {
                s.environment = Environment::Studio { intensity: v }
            }),
            ("clip.offset", |s, v| {
                s.clip = Some(ClipPlane {
                    normal: [1.0, 0.0, 0.0],
                    offset: v,
                })
            }),
        ];
        for (name, edit) in fields {
            for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let mut s = base.clone();
                edit(&mut s, v);
                let err = s.validate().expect_err(name).to_string();
                assert!(err.contains(name), "{name} = {v}: '{err}'");
            }
        }
        let mut s = base.clone();
        s.light.intensity = 2.0 * MAX_LIGHT_RADIANCE;
        assert!(s.validate().is_err(), "a light beyond the 16-bit light buffers");
        let mut s = base.clone();
        s.shading.roughness = 1.5;
        assert!(s.validate().is_err());
        let mut s = base.clone();
        s.quality.multiple_scattering = super::super::MultipleScattering::Lbm;
        assert!(s.validate().is_ok(), "lbm");
        let mut s = base;
        s.quality.multiple_scattering = super::super::MultipleScattering::Spread;
        assert!(s.validate().is_ok(), "spread with the forward beams");
        s.quality.light_transport = super::super::LightTransport::Backward;
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("spread") && err.contains("beams"), "{err}");
    }
}
