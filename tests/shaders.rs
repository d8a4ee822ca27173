//! Every shader pass compiles and validates with naga in every feature variant, and a
//! representative set of variants also builds as a Vulkan pipeline under the validation layer.

mod common;

use caustica::gpu::{BindingKind, ComputePipeline};
use caustica::render::shaders::Pass;
use caustica::render::{DebugView, Features};
use caustica::scene::Precision;

const DEBUG_VIEWS: [DebugView; 5] = [
    DebugView::Image,
    DebugView::Light,
    DebugView::LightDirection,
    DebugView::Intensity,
    DebugView::Medium,
];

#[test]
fn every_variant_compiles_and_validates() {
    // Every feature combination (both transports) at both precisions for the image, and every
    // diagnostic view of each: passes × (256 + 64 with the spread mode: beams without
    // refraction) × (2 + 4) variants.
    let mut count = 0;
    for pass in Pass::ALL {
        let source = pass.parse().unwrap_or_else(|e| panic!("{e}"));
        for features in Features::all_combinations() {
            let mut variants = vec![(DebugView::Image, Precision::F32)];
            variants.extend(DEBUG_VIEWS.iter().map(|d| (*d, Precision::F16)));
            for (debug, precision) in variants {
                let compiled = source
                    .specialise(pass.entry(), &features.constants(debug, precision))
                    .unwrap_or_else(|e| panic!("{:?} {features:?} {debug:?} {precision:?}: {e}", pass));
                let spirv = &compiled.spirv;
                assert!(spirv.len() > 100 && spirv[0] == 0x0723_0203, "not SPIR-V");
                count += 1;
            }
        }
    }
    assert_eq!(count, Pass::ALL.len() * (256 + 64) * 6);
}

#[test]
fn every_binding_is_a_storage_buffer_or_a_scene_texture() {
    // The state lives in storage buffers so that no shader reads a uniform or push-constant
    // value in a branch (lavapipe recompiles such shaders whenever the value changes: once per
    // plane). The only uniform-like block is the immediates, read through `dispatch_plane`.
    for pass in Pass::ALL {
        let source = pass.parse().unwrap();
        for b in &source.layout().bindings {
            assert!(
                !matches!(b.kind, BindingKind::UniformBuffer),
                "{pass:?}: {} is a uniform buffer",
                b.name
            );
        }
        let text = pass.source();
        let direct = text.matches("I.plane_index").count();
        assert_eq!(direct, 1, "{pass:?}: the plane index is read outside dispatch_plane");
    }
}

#[test]
fn every_override_is_set_by_features() {
    // A new `override` in the WGSL that `Features::constants` does not set would silently keep
    // its default in every variant.
    let names: Vec<&str> = Features::default()
        .constants(DebugView::Image, Precision::F16)
        .iter()
        .map(|(n, _)| *n)
        .collect();
    for pass in Pass::ALL {
        for o in pass.parse().unwrap().override_names() {
            assert!(names.contains(&o.as_str()), "override {o} of {:?} is not set", pass);
        }
    }
}

#[test]
fn representative_variants_build_on_the_device() {
    let gpu = common::Gpu::new();
    let all = Features {
        refraction: true,
        medium: true,
        light_filter: true,
        intensity_correction: true,
        specular: true,
        clip: true,
        eta_volume: true,
        orthographic: false,
        gradient: caustica::scene::Gradient::Central,
        transport: caustica::scene::LightTransport::Beams,
        lbm: true,
        scatter: false,
        sampled_layers: false,
        deposit_image: true,
    };
    let mut backward = all;
    backward.transport = caustica::scene::LightTransport::Backward;
    // The spread mode with everything it runs with (beams, no refraction).
    let spread = Features {
        refraction: false,
        specular: false,
        intensity_correction: false,
        eta_volume: false,
        scatter: true,
        ..all
    };
    let mut variants = vec![Features::default(), all, backward, spread];
    for i in 0..10 {
        let mut f = Features::default();
        match i {
            0 => f.refraction = true,
            1 => f.medium = true,
            2 => f.light_filter = true,
            3 => f.intensity_correction = true,
            4 => f.specular = true,
            5 => f.clip = true,
            6 => f.eta_volume = true,
            7 => f.orthographic = true,
            8 => f.sampled_layers = true,
            _ => {
                f.refraction = true;
                f.transport = caustica::scene::LightTransport::Backward;
            }
        }
        variants.push(f);
    }
    for (pass, precision) in Pass::ALL
        .into_iter()
        .flat_map(|p| [(p, Precision::F16), (p, Precision::F32)])
    {
        let source = pass.parse().unwrap();
        let variants = if precision == Precision::F16 {
            &variants[..]
        } else {
            &variants[..3]
        };
        for f in variants {
            let compiled = source
                .specialise(pass.entry(), &f.constants(DebugView::Image, precision))
                .unwrap();
            ComputePipeline::new(&gpu.ctx, "variant check", &compiled)
                .unwrap_or_else(|e| panic!("{pass:?} {precision:?} {f:?}: {e}"));
        }
    }
    gpu.assert_clean();
}
