//! Renders averaged over jittered sampling lattices (`render --accumulate N`).
//!
//! Where a thin or sharp feature falls between planes, or a surface between the beams of the
//! light grid, its brightness depends on where the lattices happen to lie: woodgrain along
//! tilted surfaces, bands under side light. Each render of the sequence moves the planes by a
//! fraction of the plane distance and the light grid by a fraction of a cell (a stratified
//! sequence for the planes, Halton bases 2 and 3 for the grid), so the patterns move from render
//! to render and their average is the lattices' mean.

use super::{RenderError, RenderOutput, RenderRequest, Renderer};
use crate::render::PreparedScene;

/// The lattice offsets of render `j` of `n` ([`RenderRequest::jitter`]): the planes at j / n of
/// the plane distance, the light grid at the Halton points of index j in bases 2 and 3. Render
/// 0 is the standard sweep.
pub fn jitter_sequence(j: u32, n: u32) -> [f32; 3] {
    [j as f32 / n.max(1) as f32, radical_inverse(j, 2), radical_inverse(j, 3)]
}

fn radical_inverse(mut j: u32, base: u32) -> f32 {
    let (mut value, mut scale) = (0.0f64, 1.0f64 / base as f64);
    while j > 0 {
        value += (j % base) as f64 * scale;
        j /= base;
        scale /= base as f64;
    }
    value as f32
}

/// The mean of `n` renders of `prepared` over [`jitter_sequence`] (`n` = 1: one standard
/// render). The statistics are the last render's, with the GPU time summed; `progress` is
/// called with the number of renders done.
pub fn accumulate(
    renderer: &mut Renderer,
    prepared: &PreparedScene,
    req: &RenderRequest,
    n: u32,
    mut progress: impl FnMut(u32),
) -> Result<RenderOutput, RenderError> {
    let n = n.max(1);
    let mut sum: Option<RenderOutput> = None;
    let mut gpu_ms = 0.0;
    for j in 0..n {
        let mut r = req.clone();
        r.jitter = jitter_sequence(j, n);
        let out = renderer.render(prepared, &r)?;
        gpu_ms += out.stats.gpu_ms;
        sum = Some(match sum {
            None => out,
            Some(mut acc) => {
                acc.image.add(&out.image);
                acc.stats = out.stats;
                acc
            }
        });
        progress(j + 1);
    }
    let mut out = sum.expect("at least one render");
    out.image = out.image.scaled(1.0 / n as f32);
    out.stats.gpu_ms = gpu_ms;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sequence_starts_at_the_standard_sweep_and_stratifies_the_offsets() {
        assert_eq!(jitter_sequence(0, 8), [0.0; 3]);
        let n = 8;
        let mut planes: Vec<f32> = (0..n).map(|j| jitter_sequence(j, n)[0]).collect();
        planes.sort_by(f32::total_cmp);
        for (j, p) in planes.iter().enumerate() {
            assert!((p - j as f32 / n as f32).abs() < 1e-6, "{planes:?}");
        }
        // Halton base 2: 0, 1/2, 1/4, 3/4, …; base 3: 0, 1/3, 2/3, 1/9, …
        assert_eq!(jitter_sequence(3, n)[1], 0.75);
        assert!((jitter_sequence(3, n)[2] - 1.0 / 9.0).abs() < 1e-6);
        for j in 0..64 {
            let o = jitter_sequence(j, 64);
            assert!(o.iter().all(|v| (0.0..1.0).contains(v)), "{o:?}");
        }
    }
}
