//! `Features`: what a scene needs the renderer to model. Each feature is an `override` constant
//! in the shaders; a disabled feature is constant-folded away and its buffers are not allocated.

use crate::scene::{Gradient, LightTransport, MultipleScattering, Precision, Projection, Scene};
use crate::transfer::TransferFunctions;

/// What one image needs. Derived from the scene ([`Features::for_scene`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Features {
    /// η varies: bend light and view rays (light-direction, view position/direction buffers).
    pub refraction: bool,
    /// The medium colour is not white: medium buffer per view ray, medium attenuation of light.
    pub medium: bool,
    /// Soft light: three-sample incremental convolution.
    pub light_filter: bool,
    /// Intensity law (caustics) of the backward transport. Only meaningful with refraction.
    pub intensity_correction: bool,
    /// Cook–Torrance highlights; their Fresnel term needs an index change, so only with refraction.
    pub specular: bool,
    pub clip: bool,
    /// η comes from a second volume (baked into the gradient volume; no shader switch).
    pub eta_volume: bool,
    pub orthographic: bool,
    /// Reconstruction of ∇η in the gradient volume; only used with refraction.
    pub gradient: Gradient,
    /// Light transport: forward beams, or backward lookups.
    pub transport: LightTransport,
    /// Multiple scattering by lattice-Boltzmann diffusion in an illumination grid
    /// (`render::lbm`); only when the particles scatter.
    pub lbm: bool,
    /// Multiple scattering, spread mode: beams carry scattered light and its spread (forward
    /// beams without refraction only).
    pub scatter: bool,
    /// No orientation volume (the device has no room for it, `PreparedScene::fit_to_device`):
    /// the view takes the layers' orientation from six samples of the volume.
    pub sampled_layers: bool,
    /// The view reads the beams' deposited light through an image over the same memory
    /// (`ACC_IMAGE`): on a CPU driver, which gathers texel fetches and loads a storage
    /// buffer invocation by invocation. The same light to the bit either way.
    pub deposit_image: bool,
}

/// Diagnostic buffers `--debug-view` can show instead of the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum DebugView {
    #[default]
    Image,
    Light,
    LightDirection,
    Intensity,
    Medium,
}

impl DebugView {
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "image" => DebugView::Image,
            "light" => DebugView::Light,
            "light-direction" => DebugView::LightDirection,
            "intensity" => DebugView::Intensity,
            "medium" => DebugView::Medium,
            _ => return None,
        })
    }

    pub fn code(self) -> u32 {
        self as u32
    }
}

impl Features {
    pub fn for_scene(scene: &Scene, tf: &TransferFunctions) -> Self {
        let q = &scene.quality;
        let refraction = q.refracts(tf);
        Features {
            refraction,
            medium: !tf.medium_is_white(),
            light_filter: q.light_filter && scene.light.softness > 0.0,
            intensity_correction: refraction && q.intensity_correction && q.light_transport == LightTransport::Backward,
            specular: refraction && q.specular && scene.shading.specular > 0.0,
            clip: scene.clip.is_some(),
            eta_volume: refraction && scene.has_eta_volume(),
            orthographic: scene.camera.projection == Projection::Orthographic,
            // Without refraction no gradient is computed: one variant is enough.
            gradient: if refraction { q.gradient } else { Gradient::Central },
            transport: q.light_transport,
            lbm: q.multiple_scattering == MultipleScattering::Lbm && tf.scatters(),
            scatter: Self::spread(scene, tf, refraction),
            sampled_layers: false,
            deposit_image: false,
        }
    }

    /// Whether the spread mode runs: asked for, or `auto` with transfer functions that
    /// scatter, and the forward beams without refraction (`Scene::validate` refuses spread
    /// with the backward transport; the renderer with refraction).
    fn spread(scene: &Scene, tf: &TransferFunctions, refraction: bool) -> bool {
        let q = &scene.quality;
        let wanted = match q.multiple_scattering {
            MultipleScattering::Spread => true,
            MultipleScattering::Auto => tf.scatters(),
            MultipleScattering::None | MultipleScattering::Lbm => false,
        };
        wanted && q.light_transport == LightTransport::Beams && !refraction
    }

    /// Every combination of the boolean shader switches (for shader validation), and the
    /// spread mode with each combination it runs with (beams, no refraction).
    pub fn all_combinations() -> Vec<Features> {
        let plain = Self::combinations_without_scatter();
        let spread = plain
            .iter()
            .filter(|f| f.transport == LightTransport::Beams && !f.refraction)
            .map(|f| Features { scatter: true, ..*f })
            .collect::<Vec<_>>();
        plain.into_iter().chain(spread).collect()
    }

    fn combinations_without_scatter() -> Vec<Features> {
        (0u32..256)
            .map(|bits| {
                let b = |i: u32| bits & (1 << i) != 0;
                Features {
                    refraction: b(0),
                    medium: b(1),
                    light_filter: b(2),
                    intensity_correction: b(3),
                    specular: b(4),
                    clip: b(5),
                    eta_volume: false,
                    orthographic: b(6),
                    gradient: Gradient::Central,
                    transport: if b(7) {
                        LightTransport::Backward
                    } else {
                        LightTransport::Beams
                    },
                    lbm: false,
                    scatter: false,
                    // Both ways, with the projection's switch rather than doubling the count.
                    sampled_layers: b(6),
                    // Both ways where the beams deposit (refraction), with the medium's switch.
                    deposit_image: b(0) && b(1),
                }
            })
            .collect()
    }

    /// The `override` constants of this variant, as naga expects them.
    pub fn constants(&self, debug: DebugView, precision: Precision) -> Vec<(&'static str, f64)> {
        let f = |b: bool| if b { 1.0 } else { 0.0 };
        vec![
            ("REFRACTION", f(self.refraction)),
            ("MEDIUM", f(self.medium)),
            ("LIGHT_FILTER", f(self.light_filter)),
            ("INTENSITY_CORRECTION", f(self.intensity_correction)),
            ("SPECULAR", f(self.specular)),
            ("CLIP", f(self.clip)),
            ("ORTHOGRAPHIC", f(self.orthographic)),
            ("BEAMS", f(self.transport == LightTransport::Beams)),
            ("F32_STATE", f(precision == Precision::F32)),
            ("DEBUG_VIEW", debug.code() as f64),
            ("SCATTER", f(self.scatter)),
            // Every safeguard on; see `Renderer` for the test-only way to switch them off.
            ("SAFEGUARDS_OFF", 0.0),
            ("LBM", f(self.lbm)),
            ("SAMPLED_LAYERS", f(self.sampled_layers)),
            ("ACC_IMAGE", f(self.deposit_image)),
            // The GPU's side; a render sets its own (`state::plan`, `Renderer`).
            ("TILE", super::shaders::Pass::TILE as f64),
            // One plane (a voxel at Δs 1), and a plane per dispatch; a render sets its own
            // (`state::plan`).
            ("BACK_PLANES", 1.0),
            ("LIGHT_GROUPS", 0.0),
            ("LIGHT_LISTS", 0.0),
            ("LIGHT_EDGE_STEPS", 0.0),
        ]
    }

    /// A short human-readable list, e.g. "refraction+medium+caustics".
    pub fn describe(&self) -> String {
        let mut v = Vec::new();
        for (on, name) in [
            (self.refraction, "refraction"),
            (
                self.refraction && (self.intensity_correction || self.transport == LightTransport::Beams),
                "caustics",
            ),
            (self.medium, "medium"),
            (self.light_filter, "soft-light"),
            (self.specular, "specular"),
            (self.clip, "clip"),
            (self.eta_volume, "eta-volume"),
            (self.orthographic, "orthographic"),
            (self.gradient == Gradient::Forward, "forward-gradient"),
            (self.gradient == Gradient::FourthOrder, "fourth-order-gradient"),
            (self.transport == LightTransport::Backward, "backward"),
            (self.lbm, "lbm"),
            (self.scatter, "spread"),
            (self.sampled_layers, "sampled-layers"),
        ] {
            if on {
                v.push(name);
            }
        }
        if v.is_empty() {
            "plain".into()
        } else {
            v.join("+")
        }
    }
}

/// What a prepared scene needs of the renderer (an inherent method kept next to `Features`,
/// so `scene` does not depend on `render`).
impl crate::scene::PreparedScene {
    pub fn features(&self) -> Features {
        Features {
            sampled_layers: !self.orientation_volume,
            ..Features::for_scene(&self.scene, &self.tf)
        }
    }
}
