//! Tests of the procedural scenes: ranges, dims, continuity and where each material lies.

use super::*;

fn assert_well_formed(vol: &Volume, dims: [usize; 3]) {
    assert_eq!(vol.dims, dims);
    assert_eq!(vol.data.len(), dims.iter().product::<usize>());
    assert_eq!(vol.spacing, [1.0; 3]);
    assert!(vol.data.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
    assert!(vol.value_range[0] >= 0.0 && vol.value_range[1] <= 1.0);
    assert!(vol.value_range[1] > vol.value_range[0]);
}

/// Largest difference between neighbouring voxels. With ~1.5-voxel smoothing a unit step
/// changes by at most ~0.85 per voxel; a hard edge would change by the full value.
fn max_neighbour_step(vol: &Volume) -> f32 {
    let [nx, ny, nz] = vol.dims;
    let mut worst = 0.0f32;
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let v = vol.get(x, y, z);
                if x + 1 < nx {
                    worst = worst.max((vol.get(x + 1, y, z) - v).abs());
                }
                if y + 1 < ny {
                    worst = worst.max((vol.get(x, y + 1, z) - v).abs());
                }
                if z + 1 < nz {
                    worst = worst.max((vol.get(x, y, z + 1) - v).abs());
                }
            }
        }
    }
    worst
}

fn count_near(vol: &Volume, value: f32, tolerance: f32) -> usize {
    vol.data.iter().filter(|v| (**v - value).abs() <= tolerance).count()
}

#[test]
fn ball_lens_has_ground_and_glass() {
    let vol = ball_lens(32);
    assert_well_formed(&vol, [32, 20, 32]);
    assert_eq!(vol.get(5, 0, 27), 1.0);
    // Sphere centre: ground top 1.6, radius 5.12, centre y = 9.79 → voxel 9.
    assert!((vol.get(16, 9, 16) - 0.5).abs() < 1e-3);
    assert_eq!(vol.get(0, 19, 0), 0.0);
    assert!(max_neighbour_step(&vol) < 0.9);
}

#[test]
fn glass_has_all_materials() {
    let vol = glass(64);
    assert_well_formed(&vol, [64, 64, 64]);
    assert_eq!(vol.get(2, 1, 2), 1.0);
    assert_eq!(vol.get(2, 40, 63), 1.0);
    assert_eq!(vol.get(2, 60, 2), 0.0);
    // Inside the bowl below the liquid level, on the axis.
    assert!((vol.get(32, 26, 32) - 0.7).abs() < 1e-3, "{}", vol.get(32, 26, 32));
    assert!(count_near(&vol, 0.7, 1e-3) > 1000);
    // Thin glass only reaches its full value where the wall is thicker than the edge blur.
    let full_glass = count_near(&vol, 0.4, 0.01);
    let partial_glass = count_near(&vol, 0.2, 0.19);
    assert!(full_glass > 200 && partial_glass > 2000, "{full_glass} {partial_glass}");
    // Air inside the bowl above the liquid.
    assert!(vol.get(32, 37, 32) < 0.01, "{}", vol.get(32, 37, 32));
    assert!(max_neighbour_step(&vol) < 0.9);
}

#[test]
fn supernova_is_layered() {
    let vol = supernova(32);
    assert_well_formed(&vol, [32; 3]);
    let core = vol.get(16, 17, 16);
    assert!((0.62..=0.9).contains(&core), "{core}");
    assert!((vol.get(3, 0, 3) - 1.0).abs() < 1e-3);
    assert_eq!(vol.get(0, 31, 0), 0.0);
    assert!(count_near(&vol, 0.55, 0.05) > 500);
    assert!(count_near(&vol, 0.3, 0.01) > 200);
    assert!(max_neighbour_step(&vol) < 0.9);
}

#[test]
fn luneburg_is_graded() {
    let vol = luneburg(32);
    assert_well_formed(&vol, [32, 24, 32]);
    // Centre y = 1.44 + 11.04 = 12.48 → voxel 12 is within half a voxel of the centre.
    let centre = vol.get(16, 12, 16);
    assert!(centre > 0.79 && centre <= 0.8, "{centre}");
    let profile: Vec<f32> = (16..26).map(|x| vol.get(x, 12, 16)).collect();
    assert!(profile.windows(2).all(|w| w[1] <= w[0]), "{profile:?}");
    assert_eq!(vol.get(27, 12, 16), 0.0);
    assert_eq!(vol.get(3, 0, 3), 1.0);
    assert!(max_neighbour_step(&vol) < 0.9);
}

#[test]
fn thin_structures_has_body_legs_and_checker() {
    let vol = thin_structures(64);
    assert_well_formed(&vol, [64, 48, 64]);
    assert!((vol.get(32, 19, 32) - 0.35).abs() < 1e-3);
    assert!(count_near(&vol, 0.6, 1e-3) > 100);
    // Checker squares are 8 voxels: (4, 4) and (12, 4) lie in different squares.
    assert!((vol.get(4, 0, 4) - 0.9).abs() < 1e-3);
    assert!((vol.get(12, 0, 4) - 1.0).abs() < 1e-3);
    assert!((vol.get(12, 0, 12) - 0.9).abs() < 1e-3);
    assert_eq!(vol.get(0, 47, 0), 0.0);
    assert!(max_neighbour_step(&vol) < 0.9);
}

#[test]
fn generate_by_name() {
    for name in SCENE_VOLUMES {
        let vol = generate(name, 32).expect("known scene");
        assert_eq!(vol.dims[0], 32);
        let again = generate(name, 32).expect("known scene");
        assert_eq!(vol.data, again.data, "{name} is not deterministic");
    }
    let err = generate("nope", 32).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("'nope'"), "{text}");
    assert!(SCENE_VOLUMES.iter().all(|n| text.contains(n)), "{text}");
    assert!(matches!(generate("glass", 100_000), Err(VolumeError::TooLarge { .. })));
    assert_eq!(generate("luneburg", 0).expect("raised").dims[0], MIN_RESOLUTION);
}

#[test]
fn smoothstep_edges() {
    assert_eq!(smoothstep(0.0, 1.0, -1.0), 0.0);
    assert_eq!(smoothstep(0.0, 1.0, 2.0), 1.0);
    assert_eq!(smoothstep(0.0, 1.0, 0.5), 0.5);
    assert_eq!(smoothstep(1.0, 0.0, 2.0), 0.0);
}

#[test]
fn the_objects_part_is_the_scene_without_its_supports() {
    for name in SCENE_VOLUMES {
        let whole = generate(name, 32).expect("known scene");
        let objects = generate_part(name, 32, Part::Objects).expect("known scene");
        assert_eq!(objects.dims, whole.dims, "{name}");
        // The values keep their meaning: the range is the transfer functions' domain.
        assert_eq!(objects.value_range, [0.0, 1.0], "{name}");
        // The bottom layer is ground in every scene (0.9–1.0; bound 0.85); none of it is left
        // (bound 0.01: the objects stand on the ground, none reaches into its bottom layer).
        let bottom = |v: &Volume| (0..whole.dims[0]).map(|x| v.get(x, 0, 2)).fold(0.0f32, f32::max);
        assert!(bottom(&whole) > 0.85, "{name}: no ground in the whole scene");
        assert!(
            bottom(&objects) < 0.01,
            "{name}: ground left in the objects ({})",
            bottom(&objects)
        );
        // Elsewhere the objects are what the whole scene holds there (or less, where a
        // support covered them).
        assert!(whole.data.iter().zip(&objects.data).all(|(w, o)| o <= w), "{name}");
        let kept = whole
            .data
            .iter()
            .zip(&objects.data)
            .filter(|(w, o)| **w > 0.0 && (*w - *o).abs() < 1e-6)
            .count();
        assert!(kept > 0, "{name}: no object voxel kept");
    }
    // The glass's back wall is a support too.
    let objects = generate_part("glass", 64, Part::Objects).unwrap();
    assert_eq!(objects.get(2, 40, 63), 0.0);
}
