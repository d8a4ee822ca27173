//! The numerical safeguards of the renderer in one list: each clamp or epsilon of the shaders
//! has a bit here, mirrored by an `SG_*` constant in `shaders/common.wgsl` (checked by a test).
//! A render normally runs with every safeguard on; [`super::RenderRequest::safeguards_off`]
//! switches single ones off so tests can show what each prevents. The bits are `override`
//! constants, resolved when the pipeline is built, so they cost nothing at run time.

/// One safeguard: its bit, the constant it enforces and what goes wrong without it.
#[derive(Clone, Copy, Debug)]
pub struct Safeguard {
    pub bit: u32,
    pub name: &'static str,
    pub why: &'static str,
}

pub const LIGHT_MIN_Z: u32 = 1;
pub const VIEW_MIN_Z: u32 = 2;
pub const INTENSITY_RATIO: u32 = 4;
pub const CONCENTRATION: u32 = 8;
pub const FOLD: u32 = 16;
pub const MAX_RADIANCE_CLAMP: u32 = 64;
pub const FRESNEL_STEP: u32 = 128;
pub const GGX_ALPHA: u32 = 256;
pub const SEGMENT_OPACITY: u32 = 512;
pub const GRADIENT_LENGTH: u32 = 1024;
pub const DIRECTION_LENGTH: u32 = 2048;
pub const SATURATION: u32 = 4096;

/// Largest accumulated radiance in the colour buffer (`MAX_RADIANCE` in `common.wgsl`).
pub const MAX_RADIANCE: f32 = 16384.0;

/// Every shader safeguard, with the name of its bit in `common.wgsl` (`SG_` + name).
pub const ALL: [Safeguard; 12] = [
    Safeguard {
        bit: LIGHT_MIN_Z,
        name: "LIGHT_MIN_Z",
        why: "light turned parallel to the planes would divide by a zero z step",
    },
    Safeguard {
        bit: VIEW_MIN_Z,
        name: "VIEW_MIN_Z",
        why: "view rays turned back toward the camera would step to infinity",
    },
    Safeguard {
        bit: INTENSITY_RATIO,
        name: "INTENSITY_RATIO",
        why: "one plane could multiply the light by an unbounded area ratio",
    },
    Safeguard {
        bit: CONCENTRATION,
        name: "CONCENTRATION",
        why: "past a focus the backward scheme keeps concentrating light without bound",
    },
    Safeguard {
        bit: FOLD,
        name: "FOLD",
        why: "past a focus (crossed rays) light would still be concentrated",
    },
    Safeguard {
        bit: MAX_RADIANCE_CLAMP,
        name: "MAX_RADIANCE",
        why: "sums of sharp highlights overflow the 16-bit colour buffer",
    },
    Safeguard {
        bit: FRESNEL_STEP,
        name: "FRESNEL_STEP",
        why: "last-bit index differences act as total internal reflection",
    },
    Safeguard {
        bit: GGX_ALPHA,
        name: "GGX_ALPHA",
        why: "roughness 0 makes the GGX distribution 0/0",
    },
    Safeguard {
        bit: SEGMENT_OPACITY,
        name: "SEGMENT_OPACITY",
        why: "fully transparent segments rescale colour by 0/0",
    },
    Safeguard {
        bit: GRADIENT_LENGTH,
        name: "GRADIENT_LENGTH",
        why: "a zero gradient has no normal (0/0)",
    },
    Safeguard {
        bit: DIRECTION_LENGTH,
        name: "DIRECTION_LENGTH",
        why: "a zero direction vector cannot be normalised (0/0)",
    },
    Safeguard {
        bit: SATURATION,
        name: "SATURATION",
        why: "deposits summing past the fixed-point range would wrap around to small values",
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    fn wgsl_constants() -> Vec<(String, naga::Literal)> {
        let src = format!(
            "{}\n{}\n@compute @workgroup_size(1) fn main() {{}}",
            crate::render::shaders::COMMON,
            crate::render::shaders::OPTICS
        );
        let module = naga::front::wgsl::parse_str(&src).expect("common.wgsl parses");
        module
            .constants
            .iter()
            .filter_map(|(_, c)| {
                let name = c.name.clone()?;
                match module.global_expressions[c.init] {
                    naga::Expression::Literal(l) => Some((name, l)),
                    _ => None,
                }
            })
            .collect()
    }

    #[test]
    fn bits_and_limits_match_the_shaders() {
        let consts = wgsl_constants();
        let get = |name: &str| {
            consts
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, l)| *l)
                .unwrap_or_else(|| panic!("{name} missing in common.wgsl"))
        };
        let mut bits = 0;
        for sg in ALL {
            assert_eq!(
                get(&format!("SG_{}", sg.name)),
                naga::Literal::U32(sg.bit),
                "{}",
                sg.name
            );
            assert_eq!(bits & sg.bit, 0, "bit of {} used twice", sg.name);
            bits |= sg.bit;
        }
        let n_wgsl = consts.iter().filter(|(n, _)| n.starts_with("SG_")).count();
        assert_eq!(n_wgsl, ALL.len(), "a WGSL safeguard bit is not listed here");
        assert_eq!(get("MAX_RADIANCE"), naga::Literal::F32(MAX_RADIANCE));
    }
}
