//! Histogram of a volume's samples, computed once at load: percentile windows, `caustica info`
//! and the default transfer function read it instead of scanning the samples again.

/// Number of equal-width bins between the minimum and the maximum sample.
pub const HISTOGRAM_BINS: usize = 256;

/// Fraction of samples left out at each end by the automatic window (0.5 %): a few hot
/// voxels (metal in CT, spikes in simulations) must not squeeze everything else into a sliver.
pub const WINDOW_TAIL: f32 = 0.005;

/// Samples (evenly strided) from which the window percentiles are computed exactly; the bins
/// alone are too coarse when outliers stretch the range.
const PERCENTILE_SAMPLES: usize = 1 << 20;

#[derive(Clone, Debug, PartialEq)]
pub struct Histogram {
    /// `[min, max]` of the samples; bin `i` covers `min + i * width .. min + (i + 1) * width`.
    pub range: [f32; 2],
    pub counts: Vec<u64>,
    /// The [`WINDOW_TAIL`] and 1 − [`WINDOW_TAIL`] quantiles, exact on up to 2^20 samples.
    pub tails: [f32; 2],
}

impl Histogram {
    pub fn new(data: &[f32], range: [f32; 2]) -> Histogram {
        let mut counts = vec![0u64; HISTOGRAM_BINS];
        let width = range[1] - range[0];
        if width > 0.0 && width.is_finite() {
            let scale = HISTOGRAM_BINS as f32 / width;
            for &v in data {
                let bin = ((v - range[0]) * scale) as usize;
                counts[bin.min(HISTOGRAM_BINS - 1)] += 1;
            }
        } else {
            counts[0] = data.len() as u64;
        }
        let stride = data.len().div_ceil(PERCENTILE_SAMPLES).max(1);
        let mut sample: Vec<f32> = data.iter().step_by(stride).copied().collect();
        let tails = if sample.is_empty() {
            range
        } else {
            let last = sample.len() - 1;
            let at = |q: f32| ((q * last as f32).round() as usize).min(last);
            let (lo_at, hi_at) = (at(WINDOW_TAIL), at(1.0 - WINDOW_TAIL));
            let lo = *sample.select_nth_unstable_by(lo_at, f32::total_cmp).1;
            let hi = *sample.select_nth_unstable_by(hi_at, f32::total_cmp).1;
            [lo, hi]
        };
        Histogram { range, counts, tails }
    }

    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    fn bin_width(&self) -> f32 {
        (self.range[1] - self.range[0]) / HISTOGRAM_BINS as f32
    }

    /// Lower edge of bin `i`.
    pub fn bin_start(&self, i: usize) -> f32 {
        self.range[0] + i as f32 * self.bin_width()
    }

    /// The value below which a fraction `q` ∈ [0, 1] of the samples lies, interpolated
    /// linearly inside the bin that contains it.
    pub fn quantile(&self, q: f32) -> f32 {
        let total = self.total();
        if total == 0 || self.range[1] <= self.range[0] {
            return self.range[0];
        }
        let target = q.clamp(0.0, 1.0) as f64 * total as f64;
        let mut below = 0.0f64;
        for (i, &c) in self.counts.iter().enumerate() {
            let next = below + c as f64;
            if next >= target && c > 0 {
                let t = ((target - below) / c as f64) as f32;
                return self.bin_start(i) + t.clamp(0.0, 1.0) * self.bin_width();
            }
            below = next;
        }
        self.range[1]
    }

    /// The automatic window: from the 0.5th to the 99.5th percentile, or the whole range when
    /// those coincide (a volume that is nearly all one value).
    pub fn percentile_window(&self) -> [f32; 2] {
        let [lo, hi] = self.tails;
        if hi > lo {
            [lo, hi]
        } else {
            self.range
        }
    }

    /// Index of the fullest bin: the background (air, empty space) in most volumes.
    pub fn mode_bin(&self) -> usize {
        let mut best = 0;
        for (i, &c) in self.counts.iter().enumerate() {
            if c > self.counts[best] {
                best = i;
            }
        }
        best
    }

    /// A text sketch of the distribution: `rows` lines of value, count and a bar.
    pub fn summary(&self, rows: usize) -> Vec<String> {
        let rows = rows.clamp(1, HISTOGRAM_BINS);
        let per_row = HISTOGRAM_BINS.div_ceil(rows);
        let grouped: Vec<u64> = self.counts.chunks(per_row).map(|c| c.iter().sum()).collect();
        let peak = grouped.iter().copied().max().unwrap_or(0).max(1);
        grouped
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                // Log scale: the background peak would otherwise flatten everything else.
                let bar = ((c as f64 + 1.0).ln() / (peak as f64 + 1.0).ln() * 40.0).round() as usize;
                format!("{:>12.4} {:>12} {}", self.bin_start(i * per_row), c, "#".repeat(bar))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_uniform_ramp() {
        let data: Vec<f32> = (0..=1000).map(|i| i as f32).collect();
        let h = Histogram::new(&data, [0.0, 1000.0]);
        assert_eq!(h.total(), 1001);
        // Bins are 1000/256 ≈ 3.9 wide, so quantiles land within one bin of the exact value.
        for q in [0.1f32, 0.5, 0.9] {
            assert!((h.quantile(q) - q * 1000.0).abs() < 4.0, "q {q}: {}", h.quantile(q));
        }
        let [lo, hi] = h.percentile_window();
        assert_eq!([lo, hi], [5.0, 995.0]);
    }

    #[test]
    fn outliers_do_not_stretch_the_window() {
        let mut data = vec![0.0f32; 5000];
        data.extend((0..5000).map(|i| i as f32 / 5000.0 * 100.0));
        data.push(1.0e6); // one hot voxel
        let h = Histogram::new(&data, [0.0, 1.0e6]);
        let [lo, hi] = h.percentile_window();
        assert_eq!(lo, 0.0);
        assert!(
            (hi - 99.0).abs() < 0.1,
            "the window should ignore the single outlier: {hi}"
        );
        assert_eq!(h.mode_bin(), 0);
    }

    #[test]
    fn constant_volume_falls_back_to_its_range() {
        let h = Histogram::new(&[3.0; 10], [3.0, 3.0]);
        assert_eq!(h.counts[0], 10);
        assert_eq!(h.percentile_window(), [3.0, 3.0]);
        assert_eq!(h.summary(4).len(), 4);
    }
}
