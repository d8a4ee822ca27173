//! The uniform block shared with the shaders (`Params` in `shaders/common.wgsl`).

use bytemuck::{Pod, Zeroable};

/// Mirrors `struct Params` in `shaders/common.wgsl` field by field (std140: mat4 and vec4 only).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Params {
    pub volume_from_view: [[f32; 4]; 4],
    pub gradient_to_view: [[f32; 4]; 4],
    pub world_from_view: [[f32; 4]; 4],
    pub clip_plane: [f32; 4],
    pub projection: [f32; 4],
    pub plane: [f32; 4],
    pub light_dir: [f32; 4],
    pub light_color: [f32; 4],
    pub shading: [f32; 4],
    pub size: [f32; 4],
    pub texel: [f32; 4],
    pub background: [f32; 4],
    pub limits: [f32; 4],
    /// x: largest concentration of the light (quality.max_concentration); y: half-width of an
    /// index interface for the Fresnel term (view units); z: beams with light tiles listed:
    /// the margin around the volume's box within which beams are stepped (view units); w: 1 when
    /// the value outside the volume absorbs and shows nothing (refracted view rays that leave
    /// the box for good end there).
    pub budget: [f32; 4],
    /// Light grid: plane-0 pixel coordinates of cell (0, 0)'s corner, stride (pixels per
    /// cell), cell area over pixel area on plane 0.
    pub beam_origin: [f32; 4],
    /// Light grid: width, height, tiles in x, workgroups.
    pub beam_grid: [u32; 4],
    /// Pixels whose rays can meet the volume: x0, y0, x1, y1 (half-open).
    pub rect: [u32; 4],
    /// View tiles in x, view workgroups, workgroups per dispatch row, light channels.
    pub tiles: [u32; 4],
    /// Bricks along x, y, z; bit 0: view tiles are listed per plane (else all are
    /// dispatched), bit 1: light tiles no view ray can read stop being stepped, bit 2: listed
    /// view tiles whose rays meet no visible brick are skipped.
    pub culling: [u32; 4],
    /// Beams: texture units per view unit along each axis at most (to turn the margin of
    /// `budget.z` into texture coordinates); w unused (whether light tiles are listed is the
    /// pipelines' `LIGHT_LISTS` override).
    pub light_box: [f32; 4],
    /// x: planes of the beams' power before their segment kept at once (the view passes read
    /// the unrefracted beams'; refracted beams deposit their own from `BACK_PLANES` back;
    /// `front_power_region` in beams.wgsl); z: slots of deposited light; y and w unused (the
    /// planes back along its light line a view sample reads are the pipelines' `BACK_PLANES`
    /// override).
    pub sweep: [u32; 4],
    /// The atlas of deposited light (`acc_level` in beams.wgsl): words per row, words per
    /// layer (a channel of a slot); the rest unused.
    pub deposits: [u32; 4],
}

/// Mirrors `struct Immediates` (push constants).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Immediates {
    pub plane_index: u32,
    pub seed: u32,
    /// View pass: the planes it advances its rays over; tiles pass: those of the next view
    /// pass (0: no view tiles to list).
    pub view_steps: u32,
    /// The view pass's number in the sweep (the ring of view tile lists).
    pub view_list: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The WGSL struct must have the same size and member offsets as the Rust one.
    #[test]
    fn params_layout_matches_wgsl() {
        let src = format!(
            "{}\n@compute @workgroup_size(1) fn main() {{ _ = P.sweep; _ = I.seed; }}",
            crate::render::shaders::COMMON
        );
        let module = naga::front::wgsl::parse_str(&src).expect("common.wgsl parses");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let find = |name: &str| {
            module
                .types
                .iter()
                .find(|(_, t)| t.name.as_deref() == Some(name))
                .map(|(h, t)| (h, t.clone()))
                .unwrap()
        };
        let (h, ty) = find("Params");
        assert_eq!(layouter[h].size as usize, std::mem::size_of::<Params>());
        let naga::TypeInner::Struct { members, .. } = ty.inner else {
            panic!()
        };
        let expected = [
            0, 64, 128, 192, 208, 224, 240, 256, 272, 288, 304, 320, 336, 352, 368, 384, 400, 416, 432, 448, 464, 480,
        ];
        let offsets: Vec<u32> = members.iter().map(|m| m.offset).collect();
        assert_eq!(offsets, expected);
        assert_eq!(std::mem::offset_of!(Params, limits), 336);
        assert_eq!(std::mem::offset_of!(Params, clip_plane), 192);
        let (h, _) = find("Immediates");
        assert_eq!(layouter[h].size as usize, std::mem::size_of::<Immediates>());
    }
}
