//! Where a volume lies in the patient, and showing it in anatomical orientation.
//!
//! Every loader that knows the patient coordinate system of its file fills a [`PatientFrame`]:
//! the direction of each voxel axis and the position of the first voxel in DICOM's patient
//! coordinates, LPS (x towards the patient's left, y posterior, z superior; NIfTI's RAS is
//! converted). For display, [`Loaded::into_display`] reorders and flips the voxel axes so that
//! they run as close as possible to the display axes: x to the patient's left, y superior and
//! z posterior. The renderer's default camera looks along +z with +y up and +x to the right, so
//! it then shows the anterior view with the head up, as 3D Slicer's default 3D view does. Data
//! whose axes are oblique to the body keep a small residual rotation, which the named views of
//! the camera compensate ([`PatientFrame::display_from_world`]).

use glam::{DMat3, DVec3, Mat3};

use super::{Loaded, Volume};

/// LPS direction of each display axis: x = left, y = superior, z = posterior.
pub const DISPLAY_AXES: [DVec3; 3] = [DVec3::X, DVec3::Z, DVec3::Y];

/// Residual rotations smaller than this many degrees are not mentioned in the notes.
const OBLIQUE_NOTE_DEG: f64 = 0.5;

/// The patient coordinates of a voxel grid.
#[derive(Clone, Debug, PartialEq)]
pub struct PatientFrame {
    /// Unit LPS direction of voxel axes x, y and z.
    pub axes: [DVec3; 3],
    /// LPS position (mm) of the centre of voxel (0, 0, 0).
    pub origin: DVec3,
    /// Where the file keeps it, e.g. "DICOM ImageOrientationPatient" or "NIfTI sform".
    pub source: &'static str,
}

impl PatientFrame {
    /// A frame from axis directions of any length (NIfTI and NRRD scale them by the spacing).
    /// `None` when an axis is zero or not finite, or the axes are (nearly) coplanar: such a
    /// file says nothing usable about the orientation.
    pub fn new(axes: [DVec3; 3], origin: DVec3, source: &'static str) -> Option<PatientFrame> {
        if !axes.iter().all(|a| a.is_finite() && a.length() > 0.0) || !origin.is_finite() {
            return None;
        }
        let axes = axes.map(DVec3::normalize);
        // |det| of unit vectors is the volume of their parallelepiped: 1 when orthogonal.
        let det = DMat3::from_cols(axes[0], axes[1], axes[2]).determinant();
        (det.abs() > 0.1).then_some(PatientFrame { axes, origin, source })
    }

    /// RAS directions and origin (NIfTI, NRRD "right-anterior-superior") converted to LPS.
    pub fn from_ras(axes: [DVec3; 3], origin: DVec3, source: &'static str) -> Option<PatientFrame> {
        let lps = |v: DVec3| DVec3::new(-v.x, -v.y, v.z);
        PatientFrame::new(axes.map(lps), lps(origin), source)
    }

    /// Three letters naming the direction each voxel axis runs towards, as in DICOM and NIfTI
    /// ("LPS": x towards the left, y posterior, z superior); lower case when the axis is more
    /// than 30° off the letter's direction.
    pub fn axis_codes(&self) -> String {
        self.axes
            .iter()
            .map(|a| {
                let (k, v) =
                    (0..3)
                        .map(|k| (k, a[k]))
                        .fold((0, 0.0f64), |best, c| if c.1.abs() > best.1.abs() { c } else { best });
                let letter = match (k, v >= 0.0) {
                    (0, true) => 'L',
                    (0, false) => 'R',
                    (1, true) => 'P',
                    (1, false) => 'A',
                    (_, true) => 'S',
                    (_, false) => 'I',
                };
                if v.abs() >= 30f64.to_radians().cos() {
                    letter
                } else {
                    letter.to_ascii_lowercase()
                }
            })
            .collect()
    }

    /// [`PatientFrame::axis_codes`] in words: "left, posterior, superior".
    pub fn axis_words(&self) -> String {
        self.axis_codes()
            .chars()
            .map(|c| match c.to_ascii_uppercase() {
                'L' => "left",
                'R' => "right",
                'A' => "anterior",
                'P' => "posterior",
                'S' => "superior",
                _ => "inferior",
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The order and signs of the voxel axes that bring them closest to the display axes:
    /// display axis j is voxel axis `order[j]`, reversed where `flip[j]`.
    pub fn display_permutation(&self) -> ([usize; 3], [bool; 3]) {
        const ORDERS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
        let score = |o: &[usize; 3]| (0..3).map(|j| self.axes[o[j]].dot(DISPLAY_AXES[j]).abs()).sum::<f64>();
        let order = ORDERS
            .iter()
            .copied()
            .fold((ORDERS[0], f64::NEG_INFINITY), |best, o| {
                let s = score(&o);
                if s > best.1 + 1e-12 {
                    (o, s)
                } else {
                    best
                }
            })
            .0;
        let dots = [0, 1, 2].map(|j| self.axes[order[j]].dot(DISPLAY_AXES[j]));
        let mut flip = dots.map(|d| d < 0.0);
        // The result must not be a mirror image of the patient: when the flipped axes would
        // form a frame of the other handedness than the display axes (possible only for
        // strongly oblique frames), also flip the least aligned axis.
        let signed = |j: usize| {
            if flip[j] {
                -self.axes[order[j]]
            } else {
                self.axes[order[j]]
            }
        };
        let display = DMat3::from_cols(DISPLAY_AXES[0], DISPLAY_AXES[1], DISPLAY_AXES[2]).determinant();
        if DMat3::from_cols(signed(0), signed(1), signed(2)).determinant() * display < 0.0 {
            let weakest = (0..3).fold(0, |w, j| if dots[j].abs() < dots[w].abs() { j } else { w });
            flip[weakest] = !flip[weakest];
        }
        (order, flip)
    }

    /// Rotation from the renderer's world axes (the voxel axes, scaled) to the display axes:
    /// the identity when the voxel axes run exactly along the body's axes. Column k is voxel
    /// axis k in display coordinates; a sheared frame is orthonormalised first.
    pub fn display_from_world(&self) -> Mat3 {
        let m = DMat3::from_cols_array_2d(&self.axes.map(|a| [0, 1, 2].map(|j| a.dot(DISPLAY_AXES[j]))));
        // Gram–Schmidt keeps x exact, then y in the x–y plane.
        let x = m.x_axis.normalize_or(DVec3::X);
        let y = (m.y_axis - x * x.dot(m.y_axis)).normalize_or(DVec3::Y);
        // A rotation: the flips of the display permutation keep the handedness.
        DMat3::from_cols(x, y, x.cross(y)).as_mat3()
    }

    /// Degrees between the voxel axes and the nearest body axes, whatever their order: 0 for
    /// axial, sagittal and coronal grids.
    pub fn obliquity_deg(&self) -> f64 {
        let (order, flip) = self.display_permutation();
        let axes = [0, 1, 2].map(|j| {
            if flip[j] {
                -self.axes[order[j]]
            } else {
                self.axes[order[j]]
            }
        });
        PatientFrame { axes, ..self.clone() }.oblique_deg()
    }

    /// Angle in degrees of the residual rotation [`PatientFrame::display_from_world`].
    pub fn oblique_deg(&self) -> f64 {
        let r = self.display_from_world().as_dmat3();
        let cos = ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) * 0.5).clamp(-1.0, 1.0);
        cos.acos().to_degrees()
    }
}

impl Loaded {
    /// The volume with its voxel axes reordered and flipped to run along the display axes
    /// (patient left, superior, posterior; see the module documentation). Volumes without a
    /// patient frame are returned unchanged.
    pub fn into_display(mut self) -> Loaded {
        let Some(frame) = self.meta.patient.clone() else {
            return self;
        };
        let (order, flip) = frame.display_permutation();
        let before = frame.axis_codes();
        if order != [0, 1, 2] || flip.contains(&true) {
            let v = &self.volume;
            let dims = order.map(|a| v.dims[a]);
            let spacing = order.map(|a| v.spacing[a]);
            let data = permute(v, order, flip);
            let mut origin = frame.origin;
            for j in 0..3 {
                if flip[j] {
                    origin += frame.axes[order[j]] * ((dims[j] - 1) as f64 * f64::from(spacing[j]));
                }
            }
            let axes = [0, 1, 2].map(|j| {
                if flip[j] {
                    -frame.axes[order[j]]
                } else {
                    frame.axes[order[j]]
                }
            });
            self.volume = Volume {
                dims,
                spacing,
                data,
                value_range: v.value_range,
            };
            self.meta.patient = Some(PatientFrame { axes, origin, ..frame });
            self.meta.notes.push(format!(
                "shown in anatomical orientation: voxel axes {before} reordered to {}",
                self.meta
                    .patient
                    .as_ref()
                    .map(PatientFrame::axis_codes)
                    .unwrap_or_default()
            ));
        }
        if let Some(frame) = &self.meta.patient {
            let deg = frame.oblique_deg();
            if deg > OBLIQUE_NOTE_DEG {
                self.meta.notes.push(format!(
                    "oblique: the voxel axes are {deg:.1}° off the body's axes; named views turn the camera to match"
                ));
            }
        }
        self
    }
}

/// The samples of `v` with axis j (of the display, or of the textures: `Volume::with_axes`)
/// taken from voxel axis `order[j]`, reversed where `flip[j]`.
///
/// Copied in blocks of `PERMUTE_BLOCK`³ voxels where the output's rows run along a source axis
/// other than x: a whole row read in one go takes one sample from each of as many cache lines,
/// and pages, a row or a slab apart; a block reads whole lines and writes whole rows. The CT
/// head (256×108×256 voxels as displayed) reordered for a view along x took 64–76 ms row by
/// row and takes 20–30 ms in blocks.
pub(super) fn permute(v: &Volume, order: [usize; 3], flip: [bool; 3]) -> Vec<f32> {
    let strides = [1, v.dims[0], v.dims[0] * v.dims[1]];
    let dims = order.map(|a| v.dims[a]);
    let mut start = 0isize;
    let mut step = [0isize; 3];
    for j in 0..3 {
        let s = strides[order[j]] as isize;
        if flip[j] {
            start += (dims[j] as isize - 1) * s;
            step[j] = -s;
        } else {
            step[j] = s;
        }
    }
    if order[0] == 0 {
        // The output's rows are the source's (reversed or not): row by row.
        let mut out = Vec::with_capacity(v.data.len());
        for z in 0..dims[2] as isize {
            for y in 0..dims[1] as isize {
                let row = start + y * step[1] + z * step[2];
                out.extend((0..dims[0] as isize).map(|x| v.data[(row + x * step[0]) as usize]));
            }
        }
        return out;
    }
    let mut out = vec![0.0; v.data.len()];
    let b = PERMUTE_BLOCK;
    let (nx, ny) = (dims[0], dims[1]);
    for z0 in (0..dims[2]).step_by(b) {
        for y0 in (0..dims[1]).step_by(b) {
            for x0 in (0..dims[0]).step_by(b) {
                let x1 = (x0 + b).min(nx);
                for z in z0..(z0 + b).min(dims[2]) {
                    for y in y0..(y0 + b).min(dims[1]) {
                        let src = start + y as isize * step[1] + z as isize * step[2];
                        let dst = (z * ny + y) * nx;
                        for (x, o) in (x0..x1).zip(&mut out[dst + x0..dst + x1]) {
                            *o = v.data[(src + x as isize * step[0]) as usize];
                        }
                    }
                }
            }
        }
    }
    out
}

/// The edge of `permute`'s blocks: 16 f32 fill a 64-byte cache line, and a block's 16² source
/// lines (16 KiB) stay in the L1 cache while it is copied.
const PERMUTE_BLOCK: usize = 16;

#[cfg(test)]
mod tests {
    use super::super::meta::{Format, VolumeMeta};
    use super::*;

    fn loaded(dims: [usize; 3], frame: Option<PatientFrame>) -> Loaded {
        let n = dims.iter().product();
        let volume = Volume::new(dims, [1.0, 2.0, 3.0], (0..n).map(|i| i as f32).collect()).unwrap();
        let mut meta = VolumeMeta::new(Format::Nifti, None);
        meta.patient = frame;
        Loaded::new(volume, meta)
    }

    /// LPS position of voxel `i` of a loaded volume.
    fn position(l: &Loaded, i: [usize; 3]) -> DVec3 {
        let f = l.meta.patient.as_ref().unwrap();
        (0..3).fold(f.origin, |p, a| {
            p + f.axes[a] * (i[a] as f64 * f64::from(l.volume.spacing[a]))
        })
    }

    #[test]
    fn every_order_and_flip_takes_each_voxel_from_its_place() {
        // Sides that leave partial blocks at both ends of `PERMUTE_BLOCK`'s multiples.
        let dims = [2 * PERMUTE_BLOCK + 5, PERMUTE_BLOCK + 4, PERMUTE_BLOCK + 2];
        let n = dims.iter().product();
        let v = Volume::new(dims, [1.0; 3], (0..n).map(|i| i as f32).collect()).unwrap();
        let orders = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
        for order in orders {
            for bits in 0..8 {
                let flip = [bits & 1 != 0, bits & 2 != 0, bits & 4 != 0];
                let out = permute(&v, order, flip);
                let d = order.map(|a| dims[a]);
                assert_eq!(out.len(), n);
                for (i, &value) in out.iter().enumerate() {
                    let c = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
                    let mut at = [0; 3];
                    for j in 0..3 {
                        at[order[j]] = if flip[j] { d[j] - 1 - c[j] } else { c[j] };
                    }
                    assert_eq!(value, v.get(at[0], at[1], at[2]), "{order:?} {flip:?} at {c:?}");
                }
            }
        }
    }

    #[test]
    fn axial_lps_data_is_reordered_so_superior_is_up_and_posterior_away() {
        // DICOM axial: x left, y posterior, z superior.
        let frame = PatientFrame::new([DVec3::X, DVec3::Y, DVec3::Z], DVec3::new(-10.0, 5.0, 7.0), "test").unwrap();
        assert_eq!(frame.axis_codes(), "LPS");
        let before = loaded([4, 3, 2], Some(frame));
        let after = before.clone().into_display();
        assert_eq!(after.volume.dims, [4, 2, 3]);
        assert_eq!(after.volume.spacing, [1.0, 3.0, 2.0]);
        assert_eq!(after.meta.patient.as_ref().unwrap().axis_codes(), "LSP");
        // Every voxel keeps its value and its place in the patient.
        for z in 0..3 {
            for y in 0..2 {
                for x in 0..4 {
                    let v = after.volume.get(x, y, z);
                    let old = [v as usize % 4, (v as usize / 4) % 3, v as usize / 12];
                    assert_eq!(old, [x, z, y]);
                    assert!((position(&after, [x, y, z]) - position(&before, old)).length() < 1e-9);
                }
            }
        }
        assert!(after
            .meta
            .patient
            .unwrap()
            .display_from_world()
            .abs_diff_eq(Mat3::IDENTITY, 1e-6));
    }

    #[test]
    fn reversed_axes_are_flipped_and_positions_kept() {
        // NIfTI RAS+ storage (x towards the right, y anterior, z superior) in LPS.
        let frame = PatientFrame::from_ras([DVec3::X, DVec3::Y, DVec3::Z], DVec3::ZERO, "test").unwrap();
        assert_eq!(frame.axis_codes(), "RAS");
        let before = loaded([3, 4, 5], Some(frame));
        let after = before.clone().into_display();
        assert_eq!(after.volume.dims, [3, 5, 4]);
        assert_eq!(after.meta.patient.as_ref().unwrap().axis_codes(), "LSP");
        for i in [[0, 0, 0], [2, 4, 3], [1, 2, 0]] {
            let v = after.volume.get(i[0], i[1], i[2]) as usize;
            let old = [v % 3, (v / 3) % 4, v / 12];
            assert!((position(&after, i) - position(&before, old)).length() < 1e-9);
        }
    }

    #[test]
    fn oblique_frames_keep_a_residual_rotation() {
        let a = 10f64.to_radians();
        let x = DVec3::new(a.cos(), a.sin(), 0.0);
        let y = DVec3::new(-a.sin(), a.cos(), 0.0);
        let frame = PatientFrame::new([x, y, DVec3::Z], DVec3::ZERO, "test").unwrap();
        let after = loaded([2, 2, 2], Some(frame)).into_display();
        let f = after.meta.patient.as_ref().unwrap();
        assert!((f.oblique_deg() - 10.0).abs() < 1e-3, "{}", f.oblique_deg());
        // The residual maps each world axis (the voxel axes) to its display direction.
        let r = f.display_from_world();
        for k in 0..3 {
            let lps = f.axes[k];
            let display = DVec3::new(lps.x, lps.z, lps.y).as_vec3();
            assert!((r * glam::Vec3::AXES[k] - display).length() < 1e-5);
        }
        assert!(
            after.meta.notes.iter().any(|n| n.contains("oblique")),
            "{:?}",
            after.meta.notes
        );
    }

    #[test]
    fn degenerate_frames_and_volumes_without_one_are_left_alone() {
        assert!(PatientFrame::new([DVec3::X, DVec3::X, DVec3::Z], DVec3::ZERO, "t").is_none());
        assert!(PatientFrame::new([DVec3::X, DVec3::ZERO, DVec3::Z], DVec3::ZERO, "t").is_none());
        assert!(PatientFrame::new([DVec3::X, DVec3::Y, DVec3::NAN], DVec3::ZERO, "t").is_none());
        let plain = loaded([2, 3, 4], None);
        let same = plain.clone().into_display();
        assert_eq!(same.volume.dims, plain.volume.dims);
        assert_eq!(same.volume.data, plain.volume.data);
    }

    #[test]
    fn frames_of_either_handedness_are_shown_without_mirroring() {
        // A left-handed and a right-handed axial frame, and strongly oblique ones: the frame
        // after reordering always has the display axes' handedness.
        let n = DVec3::new(1.0, 1.0, 1.0).normalize();
        let reflection = |v: DVec3| v - 2.0 * n * n.dot(v);
        for axes in [
            [DVec3::X, DVec3::Y, DVec3::Z],
            [DVec3::X, DVec3::Y, -DVec3::Z],
            [DVec3::X, DVec3::Y, DVec3::Z].map(reflection),
            [DVec3::X, DVec3::Y, -DVec3::Z].map(reflection),
        ] {
            let after = loaded([2, 3, 4], PatientFrame::new(axes, DVec3::ZERO, "t")).into_display();
            let f = after.meta.patient.unwrap();
            let m = DMat3::from_cols(f.axes[0], f.axes[1], f.axes[2]);
            let d = DMat3::from_cols(DISPLAY_AXES[0], DISPLAY_AXES[1], DISPLAY_AXES[2]);
            assert!(m.determinant() * d.determinant() > 0.0, "{axes:?}");
            assert!((f64::from(f.display_from_world().determinant()) - 1.0).abs() < 1e-5);
        }
    }
}
