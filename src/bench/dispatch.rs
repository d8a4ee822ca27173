//! The device's own cost of a compute dispatch, measured apart from the renderer: the floor
//! under the fixed cost of a plane that `bench --speed` reports. On a CPU driver every
//! dispatch that has work wakes the driver's threads and waits for the last of them, whatever
//! the shader does; how long that takes depends on the machine (its cores, its hypervisor) and
//! on the moment, so the fixed cost is also given in these units, measured in the same run.

use std::sync::Arc;

use crate::gpu::{
    Buffer, ComputePipeline, Context, DescriptorSet, GpuError, Recorder, Resource, ShaderSource, Timestamps,
};

/// A shader that does next to nothing: each invocation adds 1 to its own word. Workgroups of
/// 16 invocations, as the renderer's tiles of 4 × 4.
const SHADER: &str = r#"
@group(0) @binding(0) var<storage, read_write> words: array<u32>;

@compute @workgroup_size(16, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    words[id.x] = words[id.x] + 1u;
}
"#;

/// Invocations per workgroup of [`SHADER`].
const GROUP: u32 = 16;

/// The dispatches that are timed, each followed by the barrier the renderer puts between its
/// passes (compute writes before compute and indirect reads).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DispatchKind {
    /// An indirect dispatch whose arguments say no workgroups (the renderer's lists that are
    /// empty on a plane).
    IndirectEmpty,
    /// One workgroup: a tiny plane's light tiles.
    One,
    /// Eight workgroups: enough for every thread of a CPU driver to take some.
    Eight,
}

impl DispatchKind {
    pub const ALL: [DispatchKind; 3] = [DispatchKind::IndirectEmpty, DispatchKind::One, DispatchKind::Eight];

    pub fn groups(self) -> u32 {
        match self {
            DispatchKind::IndirectEmpty => 0,
            DispatchKind::One => 1,
            DispatchKind::Eight => 8,
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            DispatchKind::IndirectEmpty => "indirect, no workgroups",
            DispatchKind::One => "1 workgroup",
            DispatchKind::Eight => "8 workgroups",
        }
    }
}

/// Milliseconds per dispatch (with its barrier) of each kind: the median over the rounds.
#[derive(Clone, Debug)]
pub struct DispatchCost {
    pub ms: Vec<(DispatchKind, f64)>,
    /// Dispatches per round and kind, and rounds.
    pub per_round: u32,
    pub rounds: u32,
}

impl DispatchCost {
    pub fn ms_of(&self, kind: DispatchKind) -> Option<f64> {
        self.ms.iter().find(|(k, _)| *k == kind).map(|m| m.1)
    }

    /// What a dispatch that has work costs: the smaller of the one- and eight-workgroup
    /// dispatches' (both have the same hand-over; a shader this short adds little).
    pub fn with_work_ms(&self) -> Option<f64> {
        match (self.ms_of(DispatchKind::One), self.ms_of(DispatchKind::Eight)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
}

/// Times `per_round` dispatches of each kind in one submission, `rounds` times, and checks
/// afterwards that every dispatch with work ran (each invocation's word counts its
/// dispatches): a count that is off is an error, not a time.
pub fn measure(ctx: &Arc<Context>, per_round: u32, rounds: u32) -> Result<DispatchCost, GpuError> {
    let source = ShaderSource::parse("dispatch cost", SHADER)?;
    let pipeline = ComputePipeline::new(ctx, "dispatch cost", &source.specialise("main", &[])?)?;
    let words = Buffer::new_storage(ctx, "dispatch cost words", (8 * GROUP * 4) as u64)?;
    // The indirect arguments: no workgroups (filled with zeros below).
    let args = Buffer::new_storage(ctx, "dispatch cost arguments", 12)?;
    let mut readback = Buffer::new_readback(ctx, "dispatch cost read-back", words.size)?;
    let mut set = DescriptorSet::new(ctx, &pipeline, "dispatch cost")?;
    set.write(&[("words", Resource::Buffer(&words))])?;
    let ts = Timestamps::new(ctx, 2)?;
    let mut ms: Vec<(DispatchKind, Vec<f64>)> = DispatchKind::ALL.iter().map(|&k| (k, Vec::new())).collect();

    let mut rec = Recorder::new(ctx, "dispatch cost: clear")?;
    rec.fill(&words, 0);
    rec.fill(&args, 0);
    // The fills made visible to compute shaders, then to the indirect reads.
    rec.compute_to_indirect();
    rec.submit_and_wait()?;
    for _ in 0..rounds {
        for (kind, times) in ms.iter_mut() {
            let mut rec = Recorder::new(ctx, "dispatch cost")?;
            rec.reset_timestamps(&ts);
            rec.timestamp(&ts, 0);
            for _ in 0..per_round {
                if *kind == DispatchKind::IndirectEmpty {
                    rec.dispatch_indirect(&pipeline, &set, &[], &args, 0)?;
                } else {
                    rec.dispatch(&pipeline, &set, &[], [kind.groups(), 1, 1])?;
                }
                rec.compute_to_indirect();
            }
            rec.timestamp(&ts, 1);
            rec.submit_and_wait()?;
            let total: f64 = ts.read_ms()?.iter().sum();
            times.push(total / per_round.max(1) as f64);
        }
    }

    let mut rec = Recorder::new(ctx, "dispatch cost: read back")?;
    rec.compute_to_transfer();
    rec.copy_buffer(&words, &mut readback, words.size);
    rec.submit_and_wait()?;
    let counts: Vec<u32> = bytemuck::pod_collect_to_vec(readback.read()?);
    // Invocations of the first workgroup ran in every dispatch with work; those of the other
    // seven in the eight-workgroup ones only.
    let with_work =
        |groups: u32| DispatchKind::ALL.iter().filter(|k| k.groups() >= groups).count() as u32 * per_round * rounds;
    for (i, &c) in counts.iter().enumerate() {
        let expected = with_work(i as u32 / GROUP + 1);
        if c != expected {
            return Err(GpuError::Shader {
                name: "dispatch cost".into(),
                message: format!("invocation {i} ran {c} times, {expected} dispatches asked for it"),
            });
        }
    }
    Ok(DispatchCost {
        ms: ms.into_iter().map(|(k, mut t)| (k, super::median(&mut t))).collect(),
        per_round,
        rounds,
    })
}
