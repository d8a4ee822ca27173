//! `caustica bench` end to end at tiny sizes, and the error metric against a wrong image.

mod common;

use caustica::bench::{self, compare, Linear, Plan, Setting};
use caustica::reference::photons::PhotonSettings;
use caustica::reference::{self, ReferenceSettings};
use caustica::render::RenderRequest;
use common::Gpu;

/// A cheap reference: coarse photon lattice and steps (the point here is the plumbing).
fn cheap_reference() -> ReferenceSettings {
    ReferenceSettings {
        photons: PhotonSettings {
            rays_per_voxel2: 2.0,
            step_voxels: 0.5,
            ..PhotonSettings::default()
        },
        view_step_voxels: 0.5,
        ..ReferenceSettings::default()
    }
}

#[test]
fn tiny_bench_writes_table_csv_and_plot() {
    let gpu = Gpu::new();
    let base = Setting::base(32);
    let settings = vec![
        base.clone(),
        Setting {
            label: "sample distance 2".into(),
            sample_distance: 2.0,
            ..base.clone()
        },
        Setting {
            label: "viewport 64²".into(),
            size: 64,
            ..base.clone()
        },
        Setting {
            label: "beams per texel 0.5".into(),
            beams_per_texel: 0.5,
            ..base.clone()
        },
        Setting {
            label: "backward transport".into(),
            light_transport: caustica::scene::LightTransport::Backward,
            ..base
        },
    ];
    let plan = Plan {
        scenes: vec!["ball-lens".into()],
        resolution: 24,
        reference_size: 32,
        reference: cheap_reference(),
        settings,
        frames: 2,
        highlights: true,
    };
    let dir = std::env::temp_dir().join(format!("caustica-bench-test-{}", std::process::id()));
    let report = bench::run(gpu.ctx.clone(), &plan, &dir, false).expect("bench runs");
    gpu.assert_clean();
    assert_eq!(report.rows.len(), 5);
    // CSV: a header and one line per setting with finite, positive measurements.
    let csv = std::fs::read_to_string(&report.csv).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 6, "{csv}");
    assert!(lines[0].starts_with("scene,setting,sample_distance,viewport"));
    for line in &lines[1..] {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields.len(), 20, "{line}");
        let number = |i: usize| {
            fields[i]
                .parse::<f64>()
                .unwrap_or_else(|_| panic!("field {i} of {line}"))
        };
        assert!(
            number(9) > 0.0 && number(10) <= number(9) && number(9) <= number(11),
            "times: {line}"
        );
        assert!(number(12).is_finite() && number(12) > 0.0, "rel. L1: {line}");
    }
    // Half the sample distance means about half the planes.
    assert!(report.rows[1].planes < report.rows[0].planes);
    // Half the beams per texel and axis means about a quarter of the light grid's cells (its
    // extent is rounded up to whole cells, which weighs more in the coarser grid), and the
    // CSV gives the setting and the grid.
    let cells = |r: &bench::Row| f64::from(r.light_grid[0]) * f64::from(r.light_grid[1]);
    let ratio = cells(&report.rows[3]) / cells(&report.rows[0]);
    eprintln!(
        "light grids {:?} and {:?}: ratio {ratio:.3}",
        report.rows[0].light_grid, report.rows[3].light_grid
    );
    assert!(
        (0.2..0.33).contains(&ratio),
        "light grid cells at half the beams per texel: ratio {ratio}"
    );
    let last: Vec<&str> = lines[4].split(',').collect();
    assert_eq!(last[16], "0.5", "{}", lines[4]);
    assert_eq!(last[17], report.rows[3].light_grid[0].to_string(), "{}", lines[4]);
    // The backward transport is another renderer of the light: the CSV names it, and its
    // image (caustics by the intensity law, not by the beams' density) is another distance
    // from the reference.
    assert!(lines[4].ends_with(",beams") && lines[5].ends_with(",backward"), "{csv}");
    assert_ne!(report.rows[4].error.rel_l1, report.rows[0].error.rel_l1);
    // Markdown: the table with a row per setting.
    let md = std::fs::read_to_string(&report.markdown).unwrap();
    assert!(md.contains("| scene | setting |"));
    assert_eq!(md.lines().filter(|l| l.starts_with("| ball-lens |")).count(), 5);
    // The plot decodes and has the first series' colour in it.
    let png = image::open(&report.plot).expect("plot is a PNG").to_rgb8();
    assert_eq!(png.dimensions(), (960, 600));
    assert!(png.pixels().any(|p| p.0 == [31, 119, 180]), "no data points drawn");
    assert!(dir.join("ball-lens-reference.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_error_metric_reports_a_wrong_image_as_wrong() {
    // The GPU image of a scene against its reference, and a deliberately wrong image (the
    // same GPU image upside down: floor where the sky is) against the same reference: the
    // metric must tell them apart by a wide margin.
    let mut gpu = Gpu::new();
    let size = 32;
    // Highlights off: the bounds below were measured without them (the GPU's Fresnel term
    // still depends on the plane distance; see docs/accuracy.md).
    let p = bench::bench_scene("luneburg", 32, false).unwrap();
    let reference = Linear::from_image(&reference::render(&p, size, size, &cheap_reference(), false).unwrap());
    let right = Linear::from_image(&gpu.render(&p, &RenderRequest::new(size, size)).image);
    let mut flipped = right.clone();
    for y in 0..size as usize {
        for x in 0..size as usize {
            flipped.pixels[y * size as usize + x] = right.pixels[(size as usize - 1 - y) * size as usize + x];
        }
    }
    let ok = compare(&right, &reference).unwrap();
    let bad = compare(&flipped, &reference).unwrap();
    eprintln!("right image: {ok:?}; wrong image: {bad:?}");
    // Measured on lavapipe: right 0.17 relative L1 (mostly the GPU's banding on the ground
    // slab of a 32³ volume), upside down 0.37, and 9 pixels between the brightest points.
    assert!(ok.rel_l1 < 0.25, "the GPU image is far from the reference: {ok:?}");
    assert!(bad.rel_l1 > 0.3 && bad.rel_l1 > 1.8 * ok.rel_l1, "{bad:?} vs {ok:?}");
    assert!(bad.peak_px > 4.0, "{bad:?}");
    // A black image is wrong by exactly 100%.
    let black = Linear {
        pixels: vec![[0.0; 3]; right.pixels.len()],
        ..right
    };
    assert!((compare(&black, &reference).unwrap().rel_l1 - 1.0).abs() < 1e-12);
}

#[test]
fn tiny_light_bench_measures_the_planes_it_names() {
    // The light-transport table end to end at a toy size: a ball of R = 6 voxels at 24²,
    // two planes, one sample distance, two variants (the second one changes nothing). Each
    // plane measured is the sweep plane nearest the wanted depth, and both variants measure
    // the same light.
    use caustica::bench::light::{self, LightPlan, Variant};
    use caustica::reference::plane_light::PlaneSettings;
    let gpu = Gpu::new();
    let plan = LightPlan {
        radius: 6.0,
        size: 24,
        depths: vec![1.5, 3.0],
        sample_distances: vec![0.5],
        variants: vec![
            Variant::new("a", |_| {}),
            Variant::new("b", |s| s.quality.precision = caustica::scene::Precision::F32),
        ],
        frames: 1,
        reference: PlaneSettings {
            rays_per_texel: 2,
            ..PlaneSettings::default()
        },
    };
    let dir = std::env::temp_dir().join(format!("caustica-light-bench-test-{}", std::process::id()));
    let report = light::run(gpu.ctx.clone(), &plan, &dir).expect("light bench runs");
    gpu.assert_clean();
    // Two rows of the voxelised ball's exact trace (CPU, no GPU time), then two per variant.
    assert_eq!(report.rows.len(), 6);
    let (voxels, gpu_rows) = report.rows.split_at(2);
    for r in voxels {
        assert_eq!(r.variant, light::VOXELS_LABEL);
        assert!(
            r.rel_l1.is_finite() && r.ms_per_plane.is_nan() && r.beams_per_texel.is_nan(),
            "{r:?}"
        );
        // Voxelising a 6-voxel ball moves its light, but not wholesale: same power in the frame.
        assert!((0.9..1.1).contains(&r.total_power_ratio), "{r:?}");
    }
    for r in &report.rows {
        // The sweep plane nearest the wanted depth: within half a plane spacing (0.5 voxel).
        assert!((r.plane_r - r.depth_r).abs() * plan.radius <= 0.25 + 1e-6, "{r:?}");
        assert!(r.exact_max > 0.0, "{r:?}");
    }
    for r in gpu_rows {
        assert!(r.rel_l1.is_finite() && r.ms_per_plane > 0.0, "{r:?}");
        // One-voxel texels, a beam per texel asked for: the cap of 1.5 per voxel does not
        // bind, so one is traced (the grid's cells are whole pixels: exact).
        assert!((r.beams_per_texel - 1.0).abs() < 1e-6, "{r:?}");
        // Both renderers see the light leave the ball: the frame holds about the same power.
        assert!((0.5..2.0).contains(&r.total_power_ratio), "{r:?}");
    }
    // f32 buffers change the light by less than 1% of the error the table reports.
    let (a, b) = (&gpu_rows[0], &gpu_rows[2]);
    assert_eq!(
        (a.plane_index, a.variant.as_str(), b.variant.as_str()),
        (b.plane_index, "a", "b")
    );
    assert!(
        (a.rel_l1 - b.rel_l1).abs() < 0.01 * a.rel_l1.max(0.01),
        "{a:?} vs {b:?}"
    );
    let csv = std::fs::read_to_string(&report.csv).unwrap();
    assert_eq!(csv.lines().count(), 7, "{csv}");
    assert!(csv.starts_with("transport,sample_distance,depth_r,plane_r"));
    let md = std::fs::read_to_string(&report.markdown).unwrap();
    assert_eq!(
        md.lines()
            .filter(|l| l.starts_with("| a |") || l.starts_with("| b |"))
            .count(),
        4
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn tiny_speed_bench_counts_the_memory_it_reports() {
    // The speed table end to end at toy sizes: one scene at 8² (the fixed cost), 16² and 32².
    use caustica::bench::speed::{self, SpeedPlan, SpeedScene};
    let gpu = Gpu::new();
    let plan = SpeedPlan {
        scenes: vec![SpeedScene::builtin("ball-lens", Some(24)).expect("built-in scene")],
        sizes: vec![16, 32],
        tiny_size: 8,
        frames: 1,
    };
    let dir = std::env::temp_dir().join(format!("caustica-speed-bench-test-{}", std::process::id()));
    let report = speed::run(gpu.ctx.clone(), &plan, &dir, false).expect("speed bench runs");
    gpu.assert_clean();
    assert_eq!(
        report.rows.iter().map(|r| (r.size, r.tiny)).collect::<Vec<_>>(),
        [(8, true), (16, false), (32, false)]
    );
    for r in &report.rows {
        assert!(r.planes > 0 && r.gpu_ms.median > 0.0, "{r:?}");
        // One frame at 16² and 32²: the passes' times are those of the frame timed pass by
        // pass, split at timestamps between the passes, so they add up to its total (to the
        // rounding of the sums). The tiny viewport takes several frames (`TINY_FRAMES`), and
        // each pass's median may come from another frame than the total's.
        let passes: f64 = r.pass_ms.iter().sum();
        let total = r.pass_frames_ms.median;
        assert!(r.pass_ms.iter().all(|&ms| ms >= 0.0) && passes > 0.0, "{r:?}");
        if !r.tiny {
            assert!((passes - total).abs() <= 1e-9 * total, "{r:?}");
        }
        // The meter sees every allocation, so the peak holds at least the textures and the
        // state buffers that were alive together during the frame.
        assert!(
            r.peak_memory.device_local >= r.texture_bytes + r.state_bytes && r.texture_bytes > 0,
            "{r:?}"
        );
    }
    // The light grid follows the viewport: four times the cells at twice the edge, within
    // the one-cell rounding of each side.
    let (a, b) = (&report.rows[1], &report.rows[2]);
    let cells = |r: &speed::SpeedRow| (r.light_grid[0] * r.light_grid[1]) as f64;
    assert!((3.0..5.0).contains(&(cells(b) / cells(a))), "{a:?} {b:?}");
    let fit = &report.fits[0];
    assert!(
        fit.exponent.is_some_and(f64::is_finite) && fit.fixed_ms_per_plane.is_some(),
        "{fit:?}"
    );
    // The light's work is counted where its tiles are listed, and grows with the grid.
    let steps = |r: &speed::SpeedRow| r.light_steps.expect("ball-lens lists its light tiles") as f64;
    assert!(steps(a) > 0.0 && steps(b) > steps(a), "{a:?} {b:?}");
    let csv = std::fs::read_to_string(&report.csv).unwrap();
    assert_eq!(csv.lines().count(), 4, "{csv}");
    assert!(csv.starts_with("scene,features,viewport,tiny,planes"));
    assert!(csv.contains(",light_tile_steps,"), "{csv}");
    assert!(
        csv.lines()
            .next()
            .unwrap()
            .ends_with(",light_ms,view_ms,listing_ms,finish_ms,pass_frames_gpu_ms_median,tile_side"),
        "{csv}"
    );
    // An edit of the opacity curve keeps the volume images: only the two pre-integrated tables
    // (16-bit rgba, TABLE_SIZE² texels each) are copied in, and the render takes at least its
    // GPU part.
    let edit = fit.edit.expect("the bench times edits");
    let tables = 2 * (caustica::transfer::TABLE_SIZE * caustica::transfer::TABLE_SIZE * 8) as u64;
    assert_eq!((edit.size, edit.upload_bytes), (16, tables), "{edit:?}");
    assert!(
        edit.wall_ms.median >= edit.gpu_ms.median && edit.gpu_ms.median > 0.0,
        "{edit:?}"
    );
    let fit_csv = std::fs::read_to_string(&report.fit_csv).unwrap();
    assert_eq!(fit_csv.lines().count(), 2, "{fit_csv}");
    assert!(
        fit_csv
            .lines()
            .next()
            .unwrap()
            .ends_with(",edit_upload_bytes,fixed_dispatches_per_plane,dispatch_ms"),
        "{fit_csv}"
    );
    assert!(
        fit_csv.lines().nth(1).unwrap().contains(&format!(",{tables},")),
        "{fit_csv}"
    );
    // The device's cost of a dispatch is measured beside the fixed cost (its dispatches all
    // ran: `dispatch::measure` counts them), and the sweep's dispatches are counted: with
    // listed light tiles each plane has two light dispatches (the listed tiles and those at
    // the edge), and a view pass over several planes adds three (the view, its tiles, the
    // light's lists), so between two and three per plane.
    let cost = report
        .dispatch_cost
        .as_ref()
        .expect("the tiny viewport brings the dispatch cost");
    assert_eq!(cost.ms.len(), 3, "{cost:?}");
    assert!(cost.ms.iter().all(|(_, ms)| ms.is_finite() && *ms >= 0.0), "{cost:?}");
    let per_plane = fit.fixed_dispatches_per_plane.expect("counted at the tiny viewport");
    assert!((2.0..3.0).contains(&per_plane), "{per_plane} dispatches per plane");
    assert!(
        fit_csv.lines().nth(1).unwrap().split(',').nth(9) == Some(format!("{per_plane:.5}").as_str()),
        "{fit_csv}"
    );
    // The fixed cost is the median of several frames even where the others take one.
    let md = std::fs::read_to_string(&report.markdown).unwrap();
    assert!(
        md.contains(&format!("the median of {} frames there", speed::TINY_FRAMES)),
        "{md}"
    );
    assert!(
        md.contains("Dispatch cost of this device: indirect, no workgroups"),
        "{md}"
    );
    // The plot draws the scene in colour (the grid, axes and text are grey): its legend's
    // disc (radius 5: 81 pixels) and its two sizes' points (radius 3: 29 pixels each, far
    // apart), with the line between them and the proportional line from the smaller on top;
    // the discs alone bound the count from below.
    let plot = image::open(&report.plot).expect("speed.png decodes").to_rgb8();
    let coloured = plot
        .pixels()
        .filter(|p| {
            let [r, g, b] = p.0.map(i32::from);
            (r - g).abs().max((g - b).abs()) > 30
        })
        .count();
    assert!(
        coloured >= 81 + 2 * 29,
        "{coloured} coloured pixels in {}",
        report.plot.display()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn tiny_scatter_bench_adds_the_lattice_light_to_the_beams() {
    // The scattering bench end to end at its smallest: one b, one plane behind the baseline,
    // none and lbm. Beyond the plumbing (one CSV row per mode and plane, the columns scripts
    // read), the light it measures for lbm holds the lattice's scattered fluence, which the
    // light view alone lacks: lbm's light reaches further from the axis than none's (the
    // same unscattered beam), and only lbm's rows name lattice steps.
    use caustica::bench::scatter::{self, ScatterPlan};
    use caustica::bench::scatter_modes::{ModeVariant, CSV_HEADER};
    use caustica::scene::MultipleScattering;
    let gpu = Gpu::new();
    let mut plan = ScatterPlan::quick();
    plan.premoze_photons = 500;
    plan.modes.scattering = vec![0.2];
    plan.modes.depths = vec![7.0, 20.0];
    plan.modes.photons = 2_000;
    plan.modes.variants = vec![
        ModeVariant::new(MultipleScattering::None, 1.0, 4),
        ModeVariant::new(MultipleScattering::Lbm, 1.0, 4),
    ];
    let dir = std::env::temp_dir().join(format!("caustica-scatter-bench-test-{}", std::process::id()));
    let report = scatter::run(gpu.ctx.clone(), &plan, &dir, false).expect("scatter bench runs");
    gpu.assert_clean();
    let csv = std::fs::read_to_string(&report.csv).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3, "{csv}");
    assert_eq!(lines[0], CSV_HEADER);
    let columns = CSV_HEADER.split(',').count();
    for line in &lines[1..] {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields.len(), columns, "{line}");
        let number = |name: &str| {
            let i = CSV_HEADER.split(',').position(|c| c == name).unwrap();
            fields[i].parse::<f64>().unwrap_or(f64::NAN)
        };
        assert!(number("gpu_ms") > 0.0, "{line}");
        assert!(
            number("mc_width_voxels") > 1.0 && number("profile_rel_l1").is_finite(),
            "{line}"
        );
        let lbm = fields[1] == "lbm";
        assert_eq!(number("lbm_iterations") > 0.0, lbm, "{line}");
    }
    let (none, lbm) = (&report.rows[0], &report.rows[1]);
    // The hole's beam alone has an rms radius of about √2 voxels (R/√2, R = 2; measured
    // 1.41); the lattice's glow 16 voxels into the slab spreads over the whole 30-voxel window
    // (measured 13.9).
    assert!(
        none.rms_radius < 3.0 && lbm.rms_radius > 2.0 * none.rms_radius,
        "{none:?} {lbm:?}"
    );
    let md = std::fs::read_to_string(&report.markdown).unwrap();
    assert!(
        md.contains("Eq. 18") && md.contains("| lbm, cells of 4 voxels |"),
        "{md}"
    );
    assert!(image::open(&report.plot).is_ok());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_gpu_bench_script_gathers_the_device_and_both_speed_tables() {
    // `.ci/gpu-bench` is what a machine with a GPU runs; here its QUICK mode on lavapipe, so
    // that the script cannot rot between the rare runs on a GPU.
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/.ci/gpu-bench");
    let dir = std::env::temp_dir().join(format!("caustica-gpu-bench-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let run = |binary: &str| {
        std::process::Command::new("bash")
            .arg(script)
            .arg(&dir)
            .env("QUICK", "1")
            .env("CAUSTICA", binary)
            .output()
            .expect("run bash")
    };
    let missing = run("/nonexistent/caustica");
    let stderr = String::from_utf8_lossy(&missing.stderr);
    assert!(!missing.status.success(), "a missing binary must fail: {stderr}");
    assert!(
        stderr.contains("no caustica binary at /nonexistent/caustica"),
        "{stderr}"
    );

    let out = run(env!("CARGO_BIN_EXE_caustica"));
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{log}");
    let summary = std::fs::read_to_string(dir.join("summary.md")).expect("summary.md written");
    // The device list, then the goal's table (supernova alone) and the scaling table (at
    // least the two built-in scenes), each with a row per viewport and the fit.
    assert!(summary.contains("\n[0] "), "no device line:\n{summary}");
    let goal = summary.find("## goal:").expect("goal section");
    let scaling = summary.find("## scaling:").expect("scaling section");
    assert!(goal < scaling, "{summary}");
    let (goal_text, scaling_text) = (&summary[goal..scaling], &summary[scaling..]);
    // A row per viewport, 8² (the fixed cost), 16² and 32², and the fit's row.
    let rows = |text: &str, scene: &str| text.matches(&format!("| {scene} |")).count();
    assert_eq!(rows(goal_text, "supernova"), 4, "{goal_text}");
    assert_eq!(
        rows(goal_text, "ball-lens"),
        0,
        "the goal is the supernova alone:\n{goal_text}"
    );
    for size in ["| 8² |", "| 16² |", "| 32² |"] {
        assert!(
            goal_text.contains(size) && scaling_text.contains(size),
            "{size}:\n{summary}"
        );
    }
    for scene in ["ball-lens", "supernova"] {
        assert_eq!(rows(scaling_text, scene), 4, "{scene} in:\n{scaling_text}");
    }
    for run in ["goal", "scaling"] {
        for file in ["speed.md", "speed.csv", "speed-fit.csv", "speed.png"] {
            assert!(dir.join(run).join(file).is_file(), "{run}/{file} missing");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
