//! What the gpu layer's types cannot rule out at compile time it refuses at run time: a
//! dispatch with a descriptor set that leaves a binding empty, that was made for another
//! pipeline, or with immediates of the wrong size; a write of a resource the binding cannot
//! take. (Dropping or rewriting a resource a pending
//! command uses does not compile; see the `compile_fail` examples of `Recorder` and
//! `DescriptorSet`.)

mod common;

use caustica::gpu::{ComputePipeline, DescriptorSet, Format, Image, ImageDesc, Recorder, Resource};
use caustica::render::shaders::Pass;
use caustica::render::{DebugView, Features, Immediates};
use caustica::scene::Precision;

fn pipeline(gpu: &common::Gpu, pass: Pass) -> ComputePipeline {
    let source = pass.parse(Precision::F16).unwrap();
    let compiled = source
        .specialise("main", &Features::default().constants(DebugView::Image))
        .unwrap();
    ComputePipeline::new(&gpu.ctx, pass.file(), &compiled).unwrap()
}

#[test]
fn dispatch_refuses_incomplete_or_foreign_sets_and_wrong_immediates() {
    let gpu = common::Gpu::new();
    let init = pipeline(&gpu, Pass::Init);
    let finish = pipeline(&gpu, Pass::Finish);
    let image = Image::new(
        &gpu.ctx,
        ImageDesc::storage_2d("target", Format::R32G32B32A32_SFLOAT, 4, 4),
    )
    .unwrap();
    let mut partial = DescriptorSet::new(&gpu.ctx, &init, "partial").unwrap();
    partial.write(&[("image_out", Resource::Image(&image))]).unwrap();
    let foreign = DescriptorSet::new(&gpu.ctx, &finish, "made for finish").unwrap();
    let push = [0u8; std::mem::size_of::<Immediates>()];

    let mut rec = Recorder::new(&gpu.ctx, "refused dispatches").unwrap();
    let err = rec.dispatch(&init, &partial, &push, [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("not written"), "{err}");
    let err = rec.dispatch(&init, &foreign, &push, [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("made for"), "{err}");
    // Refused when writing: an image for the uniform block, a name the shader does not
    // declare, an image of another format than the binding's (light_out is rgba16float).
    let mut other = DescriptorSet::new(&gpu.ctx, &init, "mismatch").unwrap();
    assert!(other.write(&[("P", Resource::Image(&image))]).is_err());
    assert!(other.write(&[("no_such_binding", Resource::Image(&image))]).is_err());
    let err = other.write(&[("light_out", Resource::Image(&image))]).unwrap_err();
    assert!(err.to_string().contains("declares"), "{err}");
    let err = rec.dispatch(&init, &partial, &push[..4], [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("immediates"), "{err}");
    // Nothing was recorded, so the (empty) submission is valid.
    rec.submit_and_wait().unwrap();
    gpu.assert_clean();
}
