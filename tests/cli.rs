//! The `caustica` command line on bad input: every case must fail with the documented exit
//! code and a message that names the problem, never panic, and never write an output file.
//!
//! All of these fail before a Vulkan device is needed. To keep it that way the binary runs
//! with the Vulkan driver list pointed at a file that does not exist: a case that reached
//! the GPU would exit with code 3 instead of the code it expects.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const EXIT_INPUT: i32 = 1;
const EXIT_USAGE: i32 = 2;

/// A fresh directory under the system temp dir, removed again on drop.
struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    fn new(name: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!("caustica-cli-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("create scratch dir");
        Scratch { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.path(name);
        fs::write(&path, bytes).expect("write scratch file");
        path
    }

    /// The image a failing render must not create.
    fn output(&self) -> PathBuf {
        self.path("out.png")
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.dir);
    }
}

/// Runs `caustica args...` in `dir` without access to any Vulkan driver.
fn caustica(dir: &Path, args: &[&str]) -> Output {
    let missing_icd = dir.join("no-such-vulkan-driver.json");
    Command::new(env!("CARGO_BIN_EXE_caustica"))
        .args(args)
        .current_dir(dir)
        .env("VK_ICD_FILENAMES", &missing_icd)
        .env("VK_DRIVER_FILES", &missing_icd)
        .env_remove("CAUSTICA_VALIDATION")
        .output()
        .expect("run the caustica binary")
}

/// `caustica render args... -o out.png` in the scratch dir; asserts that it fails with `code`,
/// that stderr mentions every string of `expected`, and that no image was written.
fn render_fails(scratch: &Scratch, args: &[&str], code: i32, expected: &[&str]) -> String {
    let output = scratch.output();
    let mut all = vec!["render"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["-o", output.to_str().expect("utf-8 temp path")]);
    let out = caustica(&scratch.dir, &all);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let shown = format!("caustica {}\nstderr:\n{stderr}", all.join(" "));
    assert_eq!(out.status.code(), Some(code), "wrong exit code for {shown}");
    assert!(!stderr.contains("panicked"), "panic in {shown}");
    for text in expected {
        assert!(stderr.contains(text), "stderr should mention '{text}': {shown}");
    }
    assert!(!output.exists(), "{} was written by {shown}", output.display());
    stderr
}

/// A scene file using the built-in ball-lens volume (small) and the given transfer source.
fn scene_with_transfer(transfer: &str) -> String {
    format!("transfer = {transfer}\n\n[volume]\nkind = \"builtin\"\nname = \"ball-lens\"\nresolution = 16\n")
}

#[test]
fn missing_scene_file() {
    let s = Scratch::new("missing-scene");
    render_fails(
        &s,
        &["no-such-scene.toml"],
        EXIT_INPUT,
        &["cannot read scene file", "no-such-scene.toml", "No such file"],
    );
}

#[test]
fn missing_volume_file() {
    let s = Scratch::new("missing-volume");
    render_fails(
        &s,
        &["no-such-volume.nrrd"],
        EXIT_INPUT,
        &["no-such-volume.nrrd", "No such file"],
    );
}

#[test]
fn volume_file_of_unknown_format() {
    let s = Scratch::new("unknown-format");
    s.write("head.xyz", [0u8; 64]);
    render_fails(
        &s,
        &["head.xyz"],
        EXIT_INPUT,
        &["unknown volume format", "head.xyz", ".nrrd"],
    );
}

#[test]
fn truncated_raw_volume() {
    let s = Scratch::new("raw-truncated");
    s.write("short.raw", vec![0u8; 1000]);
    render_fails(
        &s,
        &["short.raw", "--raw-dims", "10x10x10", "--raw-type", "u16"],
        EXIT_INPUT,
        &["short.raw", "has 1000 bytes", "need 2000 bytes"],
    );
}

#[test]
fn raw_dims_that_do_not_match_the_data() {
    let s = Scratch::new("raw-extra");
    s.write("long.raw", vec![0u8; 1500]);
    render_fails(
        &s,
        &["long.raw", "--raw-dims", "10x10x10", "--raw-type", "u8"],
        EXIT_INPUT,
        &[
            "long.raw",
            "has 1500 bytes",
            "need only 1000 bytes",
            "dims don't match the data",
        ],
    );
}

#[test]
fn unknown_raw_scalar_type() {
    let s = Scratch::new("raw-type");
    s.write("v.raw", vec![0u8; 8]);
    render_fails(
        &s,
        &["v.raw", "--raw-dims", "2x2x2", "--raw-type", "q16"],
        EXIT_INPUT,
        &["unsupported scalar type 'q16'", "u16"],
    );
}

#[test]
fn inline_transfer_function_with_opacity_above_one() {
    let s = Scratch::new("tf-range");
    s.write(
        "scene.toml",
        scene_with_transfer("{ opacity = [[0.0, 0.0], [1.0, 1.5]] }"),
    );
    render_fails(
        &s,
        &["scene.toml"],
        EXIT_INPUT,
        &[
            "scene file scene.toml (TOML): invalid transfer function",
            "opacity point 1",
            "1.5",
            "outside [0, 1]",
        ],
    );
}

#[test]
fn a_scene_value_out_of_range_names_the_scene_file() {
    let s = Scratch::new("scene-range");
    let mut text = scene_with_transfer("{ opacity = [[0.0, 0.0], [1.0, 0.5]] }");
    text += "\n[quality]\nsample_distance = 40\n";
    s.write("scene.toml", text);
    render_fails(
        &s,
        &["scene.toml"],
        EXIT_INPUT,
        &["scene file scene.toml (TOML): invalid scene: quality.sample_distance 40 must be in [0.01, 16]"],
    );
}

#[test]
fn transfer_function_file_with_decreasing_points() {
    let s = Scratch::new("tf-order");
    s.write("tf.json", r#"{ "opacity": [[0.0, 0.0], [0.6, 0.5], [0.3, 1.0]] }"#);
    s.write("scene.toml", scene_with_transfer("\"tf.json\""));
    render_fails(
        &s,
        &["scene.toml"],
        EXIT_INPUT,
        &[
            "transfer-function JSON file",
            "tf.json: invalid transfer function",
            "opacity point 2",
            "decreasing",
        ],
    );
}

#[test]
fn transfer_option_replaces_the_transfer_functions_of_a_builtin_scene() {
    // An invalid file given with --transfer must be read (and rejected) even when the
    // built-in scene has transfer functions of its own.
    let s = Scratch::new("tf-override");
    s.write("tf.json", r#"{ "opacity": [[0.0, 2.0]] }"#);
    render_fails(
        &s,
        &["--scene", "ball-lens", "--transfer", "tf.json"],
        EXIT_INPUT,
        &["tf.json: invalid transfer function", "opacity point 0"],
    );
}

#[test]
fn transfer_function_for_a_volume_file_that_is_not_json() {
    let s = Scratch::new("tf-json");
    s.write("v.raw", vec![0u8; 8]);
    s.write("tf.json", "opacity: [[0, 0]]");
    render_fails(
        &s,
        &["v.raw", "--raw-dims", "2x2x2", "--transfer", "tf.json"],
        EXIT_INPUT,
        &["tf.json", "not valid JSON"],
    );
}

#[test]
fn scene_with_an_unknown_field() {
    let s = Scratch::new("toml-field");
    let text = scene_with_transfer("{ opacity = [[0.0, 0.0], [1.0, 1.0]] }") + "\n[camera]\nyaw = 10.0\n";
    s.write("scene.toml", text);
    render_fails(
        &s,
        &["scene.toml"],
        EXIT_INPUT,
        &["scene.toml", "is invalid", "unknown field `yaw`", "yaw_deg"],
    );
}

#[test]
fn scene_with_a_value_of_the_wrong_type() {
    let s = Scratch::new("toml-type");
    let text = scene_with_transfer("{ opacity = [[0.0, 0.0], [1.0, 1.0]] }") + "\n[light]\npolar_deg = \"high\"\n";
    s.write("scene.toml", text);
    render_fails(
        &s,
        &["scene.toml"],
        EXIT_INPUT,
        &["scene.toml", "is invalid", "polar_deg", "invalid type"],
    );
}

#[test]
fn scene_with_the_light_behind_the_planes() {
    let s = Scratch::new("light-angle");
    let text = scene_with_transfer("{ opacity = [[0.0, 0.0], [1.0, 1.0]] }") + "\n[light]\npolar_deg = 95.0\n";
    s.write("scene.toml", text);
    render_fails(&s, &["scene.toml"], EXIT_INPUT, &["light.polar_deg 95", "[0, 89]"]);
}

#[test]
fn corrupt_nrrd_header() {
    let s = Scratch::new("nrrd-header");
    let mut bytes = b"NRRD0004\ntype: flot\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n".to_vec();
    bytes.extend_from_slice(&[0u8; 32]);
    s.write("bad.nrrd", bytes);
    render_fails(
        &s,
        &["bad.nrrd"],
        EXIT_INPUT,
        &["NRRD header", "bad.nrrd", "line 2", "flot"],
    );
}

#[test]
fn unknown_builtin_scene_lists_the_available_ones() {
    let s = Scratch::new("unknown-scene");
    render_fails(
        &s,
        &["--scene", "no-such-scene"],
        EXIT_INPUT,
        &[
            "unknown built-in scene 'no-such-scene'",
            "ball-lens",
            "luneburg",
            "glass-wine",
        ],
    );
}

#[test]
fn zero_image_size_is_a_usage_error() {
    let s = Scratch::new("size");
    render_fails(
        &s,
        &["--scene", "ball-lens", "--size", "0x10"],
        EXIT_USAGE,
        &["--size", "at least 1"],
    );
}

#[test]
fn a_frame_budget_that_is_not_a_time_is_a_usage_error() {
    // Parsed before a display or a device is looked for.
    let s = Scratch::new("frame-budget");
    for bad in ["-3", "abc", "inf", "NaN"] {
        let arg = format!("--frame-budget={bad}");
        let out = caustica(&s.dir, &["view", "--scene", "ball-lens", &arg]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(EXIT_USAGE), "caustica view {arg}:\n{stderr}");
        assert!(
            stderr.contains("--frame-budget") && stderr.contains("not a time in ms"),
            "caustica view {arg}:\n{stderr}"
        );
    }
}

#[test]
fn unknown_debug_view_is_a_usage_error() {
    let s = Scratch::new("debug-view");
    render_fails(
        &s,
        &["--scene", "ball-lens", "--debug-view", "normals"],
        EXIT_USAGE,
        &["--debug-view", "'normals'", "light-direction"],
    );
}

#[test]
fn accumulate_with_a_debug_view_or_zero_renders_is_a_usage_error() {
    let s = Scratch::new("accumulate");
    render_fails(
        &s,
        &["--scene", "ball-lens", "--accumulate", "4", "--debug-view", "light"],
        EXIT_USAGE,
        &["--accumulate", "--debug-view"],
    );
    render_fails(
        &s,
        &["--scene", "ball-lens", "--accumulate", "0"],
        EXIT_USAGE,
        &["--accumulate", "0"],
    );
}

#[test]
fn pass_timings_without_timings_is_a_usage_error() {
    let s = Scratch::new("pass-timings");
    render_fails(
        &s,
        &["--scene", "ball-lens", "--pass-timings"],
        EXIT_USAGE,
        &["--pass-timings", "--timings"],
    );
}

#[test]
fn render_without_input_says_what_to_give() {
    let s = Scratch::new("no-input");
    render_fails(&s, &[], EXIT_INPUT, &["give a scene file", "--scene"]);
}

#[test]
fn scenes_lists_the_builtin_scenes() {
    let s = Scratch::new("scenes");
    let out = caustica(&s.dir, &["scenes"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "caustica scenes failed: {out:?}");
    for name in ["ball-lens", "luneburg", "glass-beer", "supernova", "thin-structures"] {
        assert!(
            stdout.lines().any(|l| l.starts_with(name)),
            "'{name}' missing from:\n{stdout}"
        );
    }
}

#[test]
fn dataset_writes_an_nrrd_file() {
    let s = Scratch::new("dataset");
    let path = s.path("ball.nrrd");
    let out = caustica(
        &s.dir,
        &[
            "dataset",
            "ball-lens",
            "--resolution",
            "16",
            "-o",
            path.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "caustica dataset failed: {out:?}");
    let bytes = fs::read(&path).expect("dataset output exists");
    assert!(
        bytes.starts_with(b"NRRD000"),
        "not an NRRD file: {:?}",
        &bytes[..bytes.len().min(16)]
    );
    assert!(
        String::from_utf8_lossy(&bytes).contains("sizes: 16 "),
        "header should give 16 voxels along x"
    );
}

#[test]
fn dataset_with_an_unknown_name_fails() {
    let s = Scratch::new("dataset-name");
    let path = s.path("x.nrrd");
    let out = caustica(&s.dir, &["dataset", "teapot", "-o", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(EXIT_INPUT), "{stderr}");
    assert!(stderr.contains("'teapot'") && stderr.contains("ball-lens"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!path.exists());
}

#[test]
fn bench_rejects_unknown_scenes_and_zero_frames_before_the_gpu() {
    let s = Scratch::new("bench");
    for (args, expected) in [
        (
            &["bench", "--scenes", "ball-lens,nope"][..],
            "unknown built-in scene 'nope'",
        ),
        (
            &["bench", "--quick", "--frames", "0"][..],
            "--frames must be at least 1",
        ),
    ] {
        let out = caustica(&s.dir, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(EXIT_INPUT), "{args:?}: {stderr}");
        assert!(
            stderr.contains(expected),
            "{args:?}: '{stderr}' should mention '{expected}'"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(!s.path("bench").exists(), "{args:?} created the output directory");
    }
}
