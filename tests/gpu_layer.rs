//! What the gpu layer's types cannot rule out at compile time it refuses at run time: a
//! dispatch with a descriptor set that leaves a binding empty, that was made for a pipeline
//! laid out otherwise, or with immediates of the wrong size; a write of a resource the binding cannot
//! take. (Dropping or rewriting a resource a pending
//! command uses does not compile; see the `compile_fail` examples of `Recorder` and
//! `DescriptorSet`.)

mod common;

use caustica::gpu::{
    Buffer, ComputePipeline, DescriptorSet, Format, Image, ImageDesc, Recorder, Resource, ShaderSource,
};
use caustica::render::shaders::Pass;
use caustica::render::{DebugView, Features, Immediates};
use caustica::scene::Precision;

fn pipeline(gpu: &common::Gpu, pass: Pass) -> ComputePipeline {
    let source = pass.parse().unwrap();
    let compiled = source
        .specialise("main", &Features::default().constants(DebugView::Image, Precision::F16))
        .unwrap();
    ComputePipeline::new(&gpu.ctx, pass.file(), &compiled).unwrap()
}

/// A pipeline writing one 16-bit storage texture.
fn storage_image_pipeline(gpu: &common::Gpu) -> ComputePipeline {
    let source = ShaderSource::parse(
        "store.wgsl",
        "@group(0) @binding(0) var out: texture_storage_2d<rgba16float, write>;\n\
         @compute @workgroup_size(1) fn main() { textureStore(out, vec2<i32>(0), vec4<f32>(1.0)); }",
    )
    .unwrap();
    ComputePipeline::new(&gpu.ctx, "store", &source.specialise("main", &[]).unwrap()).unwrap()
}

#[test]
fn dispatch_refuses_incomplete_or_foreign_sets_and_wrong_immediates() {
    let gpu = common::Gpu::new();
    let init = pipeline(&gpu, Pass::Init);
    // Laid out otherwise than `init` (init.wgsl and finish.wgsl declare the same bindings,
    // so a set made for either serves both).
    let store = storage_image_pipeline(&gpu);
    let image = Image::new(
        &gpu.ctx,
        ImageDesc::storage_2d("target", Format::R32G32B32A32_SFLOAT, 4, 4),
    )
    .unwrap();
    let buffer = Buffer::new_storage(&gpu.ctx, "target buffer", 64).unwrap();
    let mut partial = DescriptorSet::new(&gpu.ctx, &init, "partial").unwrap();
    partial.write(&[("image_out", Resource::Buffer(&buffer))]).unwrap();
    let foreign = DescriptorSet::new(&gpu.ctx, &store, "made for store").unwrap();
    let push = [0u8; std::mem::size_of::<Immediates>()];

    let mut rec = Recorder::new(&gpu.ctx, "refused dispatches").unwrap();
    let err = rec.dispatch(&init, &partial, &push, [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("not written"), "{err}");
    let err = rec.dispatch(&init, &foreign, &push, [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("made for"), "{err}");
    // Refused when writing: an image for the parameter buffer, a name the shader does not
    // declare, an image of another format than the binding's (`out` is rgba16float).
    let mut other = DescriptorSet::new(&gpu.ctx, &init, "mismatch").unwrap();
    assert!(other.write(&[("params", Resource::Image(&image))]).is_err());
    assert!(other.write(&[("no_such_binding", Resource::Image(&image))]).is_err());
    let mut stored = DescriptorSet::new(&gpu.ctx, &store, "format mismatch").unwrap();
    let err = stored.write(&[("out", Resource::Image(&image))]).unwrap_err();
    assert!(err.to_string().contains("declares"), "{err}");
    let err = rec.dispatch(&init, &partial, &push[..4], [1, 1, 1]).unwrap_err();
    assert!(err.to_string().contains("immediates"), "{err}");
    // Nothing was recorded, so the (empty) submission is valid.
    rec.submit_and_wait().unwrap();
    gpu.assert_clean();
}

/// The beams' and view rays' state lives in 2D array storage images that shaders read and
/// write in place: each layer is its own texel, and what one dispatch stores the next loads.
#[test]
fn array_images_keep_a_texel_per_layer_from_dispatch_to_dispatch() {
    let gpu = common::Gpu::new();
    let source = ShaderSource::parse(
        "layers.wgsl",
        "@group(0) @binding(0) var img: texture_storage_2d_array<rgba32float, read_write>;\n\
         @compute @workgroup_size(1) fn write_layers() {\n\
             for (var l = 0; l < 3; l++) { textureStore(img, vec2<i32>(1, 0), l, vec4<f32>(f32(l + 1))); }\n\
         }\n\
         @compute @workgroup_size(1) fn gather() {\n\
             textureStore(img, vec2<i32>(1, 0), 0, textureLoad(img, vec2<i32>(1, 0), 2) + textureLoad(img, vec2<i32>(1, 0), 1));\n\
         }",
    )
    .unwrap();
    let write = ComputePipeline::new(&gpu.ctx, "write", &source.specialise("write_layers", &[]).unwrap()).unwrap();
    let gather = ComputePipeline::new(&gpu.ctx, "gather", &source.specialise("gather", &[]).unwrap()).unwrap();
    let desc = ImageDesc::storage_2d_array("layers", Format::R32G32B32A32_SFLOAT, 2, 1, 3);
    let image = Image::new(
        &gpu.ctx,
        ImageDesc {
            usage: desc.usage | ash::vk::ImageUsageFlags::TRANSFER_SRC,
            ..desc
        },
    )
    .unwrap();
    let mut sets = Vec::new();
    for p in [&write, &gather] {
        let mut set = DescriptorSet::new(&gpu.ctx, p, "layers").unwrap();
        set.write(&[("img", Resource::Image(&image))]).unwrap();
        sets.push(set);
    }
    let mut readback = Buffer::new_readback(&gpu.ctx, "layer 0", 2 * 16).unwrap();
    let mut rec = Recorder::new(&gpu.ctx, "layers").unwrap();
    rec.init_layout(&[&image]);
    rec.dispatch(&write, &sets[0], &[], [1, 1, 1]).unwrap();
    rec.compute_to_compute();
    rec.dispatch(&gather, &sets[1], &[], [1, 1, 1]).unwrap();
    rec.compute_to_transfer();
    rec.copy_to_buffer(&image, &mut readback);
    rec.submit_and_wait().unwrap();
    let texel: Vec<f32> = bytemuck::cast_slice::<u8, f32>(&readback.read().unwrap()[16..32]).to_vec();
    // Layers 2 and 1 held 3 and 2: one texel for all layers would have read 3 twice.
    assert_eq!(texel, vec![5.0; 4]);
    gpu.assert_clean();
}

/// The sweep's passes share one descriptor set, bound once while they follow each other: a
/// set serves every pipeline laid out as the one it was made for (entry points of one
/// module), stays bound from one to the next, and is bound again after a pipeline with a set
/// of its own. Each pass sees the words the one before left.
#[test]
fn a_set_serves_the_pipelines_laid_out_alike_and_is_bound_again_after_another() {
    let gpu = common::Gpu::new();
    let source = ShaderSource::parse(
        "shared.wgsl",
        "@group(0) @binding(0) var<storage, read_write> words: array<u32>;\n\
         @compute @workgroup_size(4) fn add(@builtin(global_invocation_id) id: vec3<u32>) {\n\
             words[id.x] = words[id.x] + id.x + 1u;\n\
         }\n\
         @compute @workgroup_size(4) fn double(@builtin(global_invocation_id) id: vec3<u32>) {\n\
             words[id.x] = 2u * words[id.x];\n\
         }",
    )
    .unwrap();
    let add = ComputePipeline::new(&gpu.ctx, "add", &source.specialise("add", &[]).unwrap()).unwrap();
    let double = ComputePipeline::new(&gpu.ctx, "double", &source.specialise("double", &[]).unwrap()).unwrap();
    // Another layout: a second buffer beside the words.
    let other_source = ShaderSource::parse(
        "other.wgsl",
        "@group(0) @binding(0) var<storage, read> k: array<u32>;\n\
         @group(0) @binding(1) var<storage, read_write> other: array<u32>;\n\
         @compute @workgroup_size(4) fn main(@builtin(global_invocation_id) id: vec3<u32>) {\n\
             other[id.x] = k[0];\n\
         }",
    )
    .unwrap();
    let other = ComputePipeline::new(&gpu.ctx, "other", &other_source.specialise("main", &[]).unwrap()).unwrap();
    let words = Buffer::new_storage(&gpu.ctx, "words", 16).unwrap();
    let other_words = Buffer::new_storage(&gpu.ctx, "other words", 16).unwrap();
    let k = Buffer::new_storage_from(&gpu.ctx, "k", &7u32.to_le_bytes()).unwrap();
    let mut shared = DescriptorSet::new(&gpu.ctx, &add, "shared").unwrap();
    shared.write(&[("words", Resource::Buffer(&words))]).unwrap();
    let mut own = DescriptorSet::new(&gpu.ctx, &other, "own").unwrap();
    own.write(&[("k", Resource::Buffer(&k)), ("other", Resource::Buffer(&other_words))])
        .unwrap();
    let mut readback = Buffer::new_readback(&gpu.ctx, "words back", 16).unwrap();

    let mut rec = Recorder::new(&gpu.ctx, "shared set").unwrap();
    rec.fill(&words, 0);
    // add, double (the set left bound), the other pipeline with its own set, add again (the
    // shared set bound anew): ((0 + i + 1) · 2) + i + 1.
    for (pipeline, set) in [(&add, &shared), (&double, &shared), (&other, &own), (&add, &shared)] {
        rec.dispatch(pipeline, set, &[], [1, 1, 1]).unwrap();
        rec.compute_to_compute();
    }
    assert_eq!(rec.dispatches(), 4);
    rec.compute_to_transfer();
    rec.copy_buffer(&words, &mut readback, 16);
    rec.submit_and_wait().unwrap();
    let got: Vec<u32> = bytemuck::pod_collect_to_vec(readback.read().unwrap());
    assert_eq!(got, (0..4).map(|i| 3 * (i + 1)).collect::<Vec<u32>>());
    gpu.assert_clean();
}
