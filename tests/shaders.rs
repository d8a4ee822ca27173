//! Every shader pass compiles and validates with naga in every feature variant, and a
//! representative set of variants also builds as a Vulkan pipeline under the validation layer.

mod common;

use caustica::gpu::{BindingKind, ComputePipeline, Format};
use caustica::render::shaders::Pass;
use caustica::render::{DebugView, Features};
use caustica::scene::Precision;

#[test]
fn every_variant_compiles_and_validates() {
    let mut count = 0;
    for pass in Pass::ALL {
        let source = pass.parse(Precision::F16).unwrap_or_else(|e| panic!("{e}"));
        let debug_views: &[DebugView] = if pass == Pass::Finish {
            &[
                DebugView::Image,
                DebugView::Light,
                DebugView::LightDirection,
                DebugView::Intensity,
                DebugView::Medium,
            ]
        } else {
            &[DebugView::Image]
        };
        for features in Features::all_combinations() {
            for debug in debug_views {
                let compiled = source
                    .specialise("main", &features.constants(*debug))
                    .unwrap_or_else(|e| panic!("{:?} {features:?} {debug:?}: {e}", pass));
                let spirv = &compiled.spirv;
                assert!(spirv.len() > 100 && spirv[0] == 0x0723_0203, "not SPIR-V");
                count += 1;
            }
        }
    }
    assert_eq!(count, 256 * 7);
}

#[test]
fn full_precision_variants_compile_with_32_bit_storage() {
    for pass in Pass::ALL {
        let parsed = pass.parse(Precision::F32).unwrap_or_else(|e| panic!("{e}"));
        // At f32 no storage binding is left at 16 bits; at f16 the colour state is.
        let formats = |p: Precision| -> Vec<Format> {
            let source = if p == Precision::F32 {
                &parsed
            } else {
                &pass.parse(p).unwrap()
            };
            source
                .layout()
                .bindings
                .iter()
                .filter_map(|b| match b.kind {
                    BindingKind::StorageImage { format, .. } => Some(format),
                    _ => None,
                })
                .collect()
        };
        assert!(
            formats(Precision::F32)
                .iter()
                .all(|f| *f == Format::R32G32B32A32_SFLOAT),
            "{pass:?} still declares 16-bit storage"
        );
        assert!(formats(Precision::F16).contains(&Format::R16G16B16A16_SFLOAT));
        for features in Features::all_combinations().into_iter().step_by(17) {
            parsed
                .specialise("main", &features.constants(DebugView::Image))
                .unwrap_or_else(|e| panic!("{pass:?} {features:?}: {e}"));
        }
    }
}

#[test]
fn every_override_is_set_by_features() {
    // A new `override` in the WGSL that `Features::constants` does not set would silently keep
    // its default in every variant.
    let names: Vec<&str> = Features::default()
        .constants(DebugView::Image)
        .iter()
        .map(|(n, _)| *n)
        .collect();
    for pass in Pass::ALL {
        for o in pass.parse(Precision::F16).unwrap().override_names() {
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
    };
    let mut variants = vec![Features::default(), all];
    for i in 0..9 {
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
            _ => {
                f.refraction = true;
                f.gradient = caustica::scene::Gradient::Forward;
            }
        }
        variants.push(f);
    }
    for (pass, precision) in Pass::ALL
        .into_iter()
        .flat_map(|p| [(p, Precision::F16), (p, Precision::F32)])
    {
        let source = pass.parse(precision).unwrap();
        let variants = if precision == Precision::F16 {
            &variants[..]
        } else {
            &variants[..2]
        };
        for f in variants {
            let compiled = source.specialise("main", &f.constants(DebugView::Image)).unwrap();
            ComputePipeline::new(&gpu.ctx, "variant check", &compiled)
                .unwrap_or_else(|e| panic!("{pass:?} {precision:?} {f:?}: {e}"));
        }
    }
    gpu.assert_clean();
}
