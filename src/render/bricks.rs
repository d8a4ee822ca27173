//! Empty-space skipping: which 8³ bricks of the volume can change light or colour at all. A
//! brick is empty when, over the range of data values in it (one voxel wider on each side,
//! what trilinear sampling reaches), the opacity is zero and the medium colour is white: a
//! segment there composites nothing and lets all light through. The GPU skips tiles of view
//! rays whose next segments lie in empty bricks; with refraction the bricks where η changes
//! count too (`add_refracting`), and a tile is skipped only until one of its rays is bent.

use super::occupancy::ValueRanges;
use crate::transfer::TransferFunctions;

/// Voxels per brick edge.
pub const BRICK: usize = 8;

/// Per brick (x fastest): 1 if something in it absorbs or shows (or, after
/// [`add_refracting`], η changes in it), else 0; and the brick counts along each axis.
pub struct Bricks {
    pub flags: Vec<u32>,
    pub dims: [u32; 3],
}

/// The largest value of a piecewise-linear function (`points` as in `transfer::Curve` with
/// the value in column `k`) over [a, b], and its smallest, as (min, max).
fn range_of<const N: usize>(points: &[[f32; N]], k: usize, a: f32, b: f32, eval: impl Fn(f32) -> f32) -> (f32, f32) {
    let mut lo = eval(a).min(eval(b));
    let mut hi = eval(a).max(eval(b));
    for p in points {
        if p[0] > a && p[0] < b {
            lo = lo.min(p[k]);
            hi = hi.max(p[k]);
        }
    }
    (lo, hi)
}

/// Whether values in [a, b] (transfer-function domain) absorb or show anything.
pub(super) fn visible(tf: &TransferFunctions, a: f32, b: f32) -> bool {
    let (_, alpha) = range_of(&tf.opacity.points, 1, a, b, |x| tf.opacity.eval(x));
    if alpha > 0.0 {
        return true;
    }
    (1..=3).any(|k| range_of(&tf.medium.points, k, a, b, |x| tf.medium.eval(x)[k - 1]).0 < 1.0)
}

/// Whether the value outside the volume (0: the textures' border) absorbs or shows nothing,
/// so that light passing outside the volume's box keeps its power.
pub fn clear_outside(tf: &TransferFunctions) -> bool {
    !visible(tf, 0.0, 0.0)
}

/// The bricks whose particles absorb or show under `tf`, from the value ranges of the cells of
/// [`BRICK`] voxels ([`ValueRanges`]: bricks at the volume's faces also reach the zero outside
/// it).
pub fn visible_bricks(ranges: &ValueRanges, tf: &TransferFunctions) -> Bricks {
    let cells = ranges.visible(tf);
    Bricks {
        flags: cells.flags.iter().map(|&f| u32::from(f)).collect(),
        dims: cells.cells.map(|n| n as u32),
    }
}

/// Marks the bricks where η changes as well (for refracting scenes): a texel of the gradient
/// volume (`gradient.rs`, ∇η in xyz, `gradient_dims` voxels over the same box, which may
/// differ from the volume's) within a voxel of the brick has a gradient other than zero, as
/// `bends` says of each ([`super::gradient::bend_map`]). A view ray that has not been bent
/// yet skips only bricks where neither happens.
pub fn add_refracting(bricks: &mut Bricks, dims: [usize; 3], bends: &[bool], gradient_dims: [usize; 3]) {
    let nb = bricks.dims.map(|n| n as usize);
    // The gradient voxels over brick i along an axis, one voxel wider on each side.
    let range = |i: usize, a: usize| {
        let scale = gradient_dims[a] as f64 / dims[a] as f64;
        let lo = ((i * BRICK) as f64 * scale).floor() as usize;
        let hi = (((i + 1) * BRICK) as f64 * scale).ceil() as usize;
        lo.saturating_sub(1)..(hi + 1).min(gradient_dims[a])
    };
    let spans = [0, 1, 2].map(|a| (0..nb[a]).map(|i| range(i, a)).collect::<Vec<_>>());
    let changes = super::occupancy::over_boxes(bends, gradient_dims, &spans, false, |&b| b, |a, b| a || b);
    for (flag, changes) in bricks.flags.iter_mut().zip(changes) {
        if *flag == 0 {
            *flag = u32::from(changes);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::gradient::bend_map;
    use crate::transfer::{ColorRamp, Curve};

    /// The bricks of a volume of `dims` voxels with 16-bit samples.
    fn bricks(samples: &[u16], dims: [usize; 3], tf: &TransferFunctions) -> Bricks {
        visible_bricks(&ValueRanges::new(samples, dims, BRICK), tf)
    }

    fn tf(opacity: Vec<[f32; 2]>, medium: Vec<[f32; 4]>) -> TransferFunctions {
        TransferFunctions {
            name: None,
            opacity: Curve { points: opacity },
            color: ColorRamp::constant([1.0; 3]),
            eta: Curve::constant(1.0),
            medium: ColorRamp { points: medium },
            albedo: None,
            anisotropy: None,
        }
    }

    #[test]
    fn a_brick_is_empty_only_where_nothing_absorbs() {
        // 24³ voxels: 0 everywhere but one voxel of 0.8 in brick (1, 1, 1).
        let dims = [24, 24, 24];
        let mut samples = vec![0u16; 24 * 24 * 24];
        samples[(12 * 24 + 12) * 24 + 12] = (0.8 * 65535.0) as u16;
        // Opacity only above 0.5: just the brick holding the voxel (and any brick whose
        // one-voxel border reaches it: none, it is in the middle of its brick).
        let t = tf(vec![[0.0, 0.0], [0.5, 0.0], [0.6, 1.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
        let b = bricks(&samples, dims, &t);
        assert_eq!(b.dims, [3, 3, 3]);
        assert_eq!(b.flags.iter().sum::<u32>(), 1);
        assert_eq!(b.flags[(3 + 1) * 3 + 1], 1);
        // A peak of opacity between two control points inside the range still counts.
        let peaked = tf(
            vec![[0.0, 0.0], [0.3, 0.0], [0.4, 0.5], [0.45, 0.0]],
            vec![[0.0, 1.0, 1.0, 1.0]],
        );
        assert_eq!(bricks(&samples, dims, &peaked).flags[(3 + 1) * 3 + 1], 1);
        // A tinted medium at the background value makes every brick count.
        let tinted = tf(vec![[0.0, 0.0]], vec![[0.0, 0.9, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]]);
        assert!(bricks(&samples, dims, &tinted).flags.iter().all(|f| *f == 1));
    }

    #[test]
    fn bricks_where_eta_changes_count_for_refracting_scenes() {
        // 24³ voxels, nothing visible; one gradient texel (∇η ≠ 0) at voxel (12, 12, 12):
        // brick (1, 1, 1) only (it is in the middle of that brick).
        let dims = [24, 24, 24];
        let clear = tf(vec![[0.0, 0.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
        let mut b = bricks(&vec![0u16; 24 * 24 * 24], dims, &clear);
        assert_eq!(b.flags.iter().sum::<u32>(), 0);
        let mut texels = vec![[half::f16::ZERO; 4]; 24 * 24 * 24];
        texels[(12 * 24 + 12) * 24 + 12][1] = half::f16::from_f32(-0.2);
        // η itself (w) away from the change does not count.
        texels[0][3] = half::f16::from_f32(0.4);
        add_refracting(&mut b, dims, &bend_map(&texels), dims);
        assert_eq!(b.flags.iter().sum::<u32>(), 1);
        assert_eq!(b.flags[(3 + 1) * 3 + 1], 1);
        // A gradient volume of twice the resolution over the same box: its voxel 31 (the
        // volume's 15.75) is within a (fine) voxel of the boundary between bricks 1 and 2 along
        // each axis, so it counts for all eight bricks there; its voxel 24 (12.25) for one.
        let fine = [48, 48, 48];
        let mut texels = vec![[half::f16::ZERO; 4]; 48 * 48 * 48];
        texels[(24 * 48 + 24) * 48 + 24][0] = half::f16::from_f32(0.1);
        let mut b = bricks(&vec![0u16; 24 * 24 * 24], dims, &clear);
        add_refracting(&mut b, dims, &bend_map(&texels), fine);
        assert_eq!(b.flags.iter().sum::<u32>(), 1);
        texels[(31 * 48 + 31) * 48 + 31][0] = half::f16::from_f32(0.1);
        let mut b = bricks(&vec![0u16; 24 * 24 * 24], dims, &clear);
        add_refracting(&mut b, dims, &bend_map(&texels), fine);
        assert_eq!(b.flags.iter().sum::<u32>(), 8);
        assert_eq!(b.flags[(2 * 3 + 2) * 3 + 2], 1);
    }
}
