//! Shared test harness: a validated GPU context, rendering helpers and image metrics.
#![allow(dead_code)]

use std::sync::Arc;

use caustica::gpu::{Context, ContextDesc, DeviceSelector};
use caustica::render::{DebugView, PreparedScene, RenderOutput, RenderRequest, Renderer};
use caustica::scene::{Quality, Scene};
use caustica::transfer::{ColorRamp, Curve, TransferFunctions};
use caustica::volume::Volume;

/// A renderer on the default device with the Khronos validation layer required.
pub struct Gpu {
    pub renderer: Renderer,
    pub ctx: Arc<Context>,
}

impl Gpu {
    pub fn new() -> Gpu {
        let ctx = Context::new(&ContextDesc {
            device: DeviceSelector::Auto,
            validation: true,
            require_validation: true,
            ..Default::default()
        })
        .expect("a Vulkan device with the validation layer (run .ci/ensure-vulkan --test)");
        Gpu {
            renderer: Renderer::new(ctx.clone()).expect("shaders compile"),
            ctx,
        }
    }

    pub fn render(&mut self, prepared: &PreparedScene, req: &RenderRequest) -> RenderOutput {
        let out = self.renderer.render(prepared, req).expect("render succeeds");
        self.assert_clean();
        out
    }

    /// A diagnostic buffer at relative depth `depth`.
    pub fn debug(&mut self, prepared: &PreparedScene, size: u32, view: DebugView, depth: f32) -> RenderOutput {
        let mut req = RenderRequest::new(size, size);
        req.debug_view = view;
        req.debug_depth = depth;
        self.render(prepared, &req)
    }

    /// The validation canary: any error reported by the layer fails the test.
    pub fn assert_clean(&self) {
        assert_eq!(
            self.ctx.validation_errors(),
            0,
            "Vulkan validation errors: {:#?}",
            self.ctx.validation_messages()
        );
    }
}

/// Transfer functions with a constant η and white medium.
pub fn plain_tf(opacity: Vec<[f32; 2]>, color: Vec<[f32; 4]>) -> TransferFunctions {
    TransferFunctions {
        name: None,
        opacity: Curve { points: opacity },
        color: ColorRamp { points: color },
        eta: Curve::constant(1.0),
        medium: ColorRamp::constant([1.0; 3]),
        albedo: None,
        anisotropy: None,
    }
}

/// An orthographic head-on view with the light along the view axis and a black background.
pub fn head_on_scene(tf: &TransferFunctions) -> Scene {
    Scene::head_on("test", tf, 1.0, Quality::default())
}

/// A volume of `n`³ voxels from a function of the voxel centre in [0, 1]³.
pub fn volume_from(n: usize, f: impl Fn(f32, f32, f32) -> f32) -> Volume {
    let mut data = Vec::with_capacity(n * n * n);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let c = |i: usize| (i as f32 + 0.5) / n as f32;
                data.push(f(c(x), c(y), c(z)));
            }
        }
    }
    Volume::new([n, n, n], [1.0; 3], data).expect("valid test volume")
}

/// Smooth sphere of value `value`, radius `r` (fraction of the box), centre (0.5, 0.5, 0.5),
/// edge about 1.5 voxels wide.
pub fn sphere(n: usize, r: f32, value: f32) -> Volume {
    volume_from(n, |x, y, z| {
        let d = ((x - 0.5).powi(2) + (y - 0.5).powi(2) + (z - 0.5).powi(2)).sqrt();
        let edge = 1.5 / n as f32;
        value * (0.5 - (d - r) / edge).clamp(0.0, 1.0)
    })
}

pub fn prepared(scene: Scene, volume: Volume, tf: TransferFunctions) -> PreparedScene {
    PreparedScene::from_parts(scene, volume, tf).expect("scene prepares")
}

/// Luminance of a linear RGB pixel.
pub fn luminance(p: &[f32; 4]) -> f32 {
    0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]
}

/// Mean and maximum absolute per-channel difference of two images (RGB).
pub fn diff(a: &[[f32; 4]], b: &[[f32; 3]]) -> (f32, f32) {
    assert_eq!(a.len(), b.len());
    let mut sum = 0.0f64;
    let mut max = 0.0f32;
    for (p, q) in a.iter().zip(b) {
        for c in 0..3 {
            let d = (p[c] - q[c]).abs();
            sum += d as f64;
            max = max.max(d);
        }
    }
    ((sum / (3 * a.len()) as f64) as f32, max)
}
