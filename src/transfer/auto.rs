//! The transfer functions used when a volume file is rendered without any: the CT preset for
//! data in Hounsfield units, otherwise a ramp that starts above the histogram's background.

use std::path::Path;

use super::{ColorRamp, Curve, TransferFunctions};
use crate::volume::{Histogram, Units, VolumeMeta};

/// The CT preset (air, soft tissue and bone with their refractive indices, amber medium),
/// written for the window [`crate::volume::CT_WINDOW`].
const CT_PRESET: &str = include_str!("../../transfer_functions/ct-amber.json");

/// Opacity per voxel at the top of the default ramp: dense enough to show surfaces, light
/// enough that a few hundred voxels of material do not hide everything behind them.
const RAMP_TOP_OPACITY: f32 = 0.5;
/// Margin above the background peak, as a fraction of the window, before opacity starts.
const BACKGROUND_MARGIN: f32 = 0.05;

/// Transfer functions for a volume: the CT preset for Hounsfield data, otherwise an opacity
/// ramp from just above the background peak (the fullest histogram bin) to the window top.
pub fn default_for(meta: &VolumeMeta, histogram: &Histogram, window: [f32; 2]) -> TransferFunctions {
    if meta.units == Units::Hounsfield {
        if let Ok(tf) = TransferFunctions::from_json(CT_PRESET, Path::new("ct-amber.json")) {
            return tf;
        }
    }
    let start = background_end(histogram, window);
    TransferFunctions {
        name: Some(format!("automatic (opacity from {start:.2} of the window)")),
        opacity: Curve {
            points: vec![[0.0, 0.0], [start, 0.0], [1.0, RAMP_TOP_OPACITY]],
        },
        color: ColorRamp {
            points: vec![[0.0, 1.0, 0.8, 0.6], [1.0, 1.0, 1.0, 1.0]],
        },
        ..TransferFunctions::default()
    }
}

/// Where, in [0, 1] of the window, the background peak ends. When the peak is in the upper
/// half the background is not the low end (inverted data); then opacity starts at 0.1.
fn background_end(histogram: &Histogram, window: [f32; 2]) -> f32 {
    let width = window[1] - window[0];
    if width.is_nan() || width <= 0.0 {
        return 0.1;
    }
    let mode = histogram.mode_bin();
    let peak_top = histogram.bin_start(mode + 1);
    let x = (peak_top - window[0]) / width + BACKGROUND_MARGIN;
    if x.is_finite() && x < 0.5 {
        x.max(BACKGROUND_MARGIN)
    } else {
        0.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Format, CT_WINDOW};

    #[test]
    fn hounsfield_data_gets_the_ct_preset() {
        let meta = VolumeMeta::new(Format::Nrrd, None).with_modality("CT");
        let h = Histogram::new(&[-1000.0, 0.0, 1000.0], [-1000.0, 1000.0]);
        let tf = default_for(&meta, &h, CT_WINDOW);
        assert_eq!(tf.name.as_deref(), Some("ct-amber"));
        // Air (−1000 HU → 0) is transparent, bone (1000 HU → 0.67) opaque.
        assert_eq!(tf.opacity.eval(0.0), 0.0);
        assert!(tf.opacity.eval(0.67) > 0.5);
    }

    #[test]
    fn other_data_starts_opacity_above_the_background_peak() {
        let mut data = vec![10.0f32; 9000];
        data.extend((0..1000).map(|i| 10.0 + i as f32 * 0.09));
        let h = Histogram::new(&data, [10.0, 100.0]);
        let meta = VolumeMeta::new(Format::Nifti, None);
        let tf = default_for(&meta, &h, [10.0, 100.0]);
        assert_eq!(tf.opacity.eval(0.0), 0.0);
        assert_eq!(tf.opacity.eval(0.05), 0.0, "the background peak must stay transparent");
        assert!(tf.opacity.eval(1.0) > 0.4);
        tf.validate().expect("valid");
    }
}
