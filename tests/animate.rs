//! `caustica animate` end to end, at tiny sizes (volumes of 16³, frames of at most 24²):
//! frames equal `caustica render` of the matching scenes bit for bit; shards together equal
//! the unsharded run; resuming skips present frames and re-renders stale ones; a transfer-
//! function key halfway equals the interpolated functions; time-series frames hold and blend;
//! MP4 output with and without ffmpeg; bad shards and ranges are usage errors.
//!
//! The renders run with the validation layer required, so a validation error fails them.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use caustica::volume::nrrd::write_nrrd;
use caustica::volume::Volume;

const EXIT_USAGE: i32 = 2;

struct Scratch(PathBuf);

impl Scratch {
    fn new(tag: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!("caustica-animate-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("create scratch dir");
        Scratch(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.path(name);
        fs::write(&p, text).expect("write scratch file");
        p
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

fn command(dir: &Path, args: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_caustica"));
    cmd.args(args).current_dir(dir).env("CAUSTICA_VALIDATION", "require");
    cmd
}

fn shown(args: &[&str], out: &Output) -> String {
    format!(
        "caustica {}\nstdout:\n{}\nstderr:\n{}",
        args.join(" "),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Runs caustica in `dir` and asserts success; returns stderr.
fn ok(dir: &Path, args: &[&str]) -> String {
    let out = command(dir, args).output().expect("run caustica");
    assert!(out.status.success(), "failed: {}", shown(args, &out));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs caustica in `dir` and asserts the exit code; returns (stdout, stderr).
fn fails(dir: &Path, args: &[&str], code: i32) -> (String, String) {
    let out = command(dir, args).output().expect("run caustica");
    assert_eq!(out.status.code(), Some(code), "{}", shown(args, &out));
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "{}", shown(args, &out));
    (String::from_utf8_lossy(&out.stdout).into_owned(), stderr)
}

fn tf_file(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("transfer_functions")
        .join(name)
        .display()
        .to_string()
}

/// The ball-lens volume at 16³ with the given camera yaw and the built-in scene's light.
fn scene(yaw: f32) -> String {
    format!(
        "transfer = {:?}\n[volume]\nkind = \"builtin\"\nname = \"ball-lens\"\nresolution = 16\n\
         [camera]\nyaw_deg = {yaw:?}\npitch_deg = 30.0\ndistance = 2.6\n[light]\npolar_deg = 40.0\nazimuth_deg = -30.0\n",
        tf_file("ball-lens.json")
    )
}

fn exr_pixels(path: &Path) -> Vec<[u32; 4]> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |r, _| (r.width(), vec![[0u32; 4]; r.width() * r.height()]),
        |(w, px): &mut (usize, Vec<[u32; 4]>), pos, (r, g, b, a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r.to_bits(), g.to_bits(), b.to_bits(), a.to_bits()]
        },
    )
    .unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
    image.layer_data.channel_data.pixels.1
}

fn png_pixels(path: &Path) -> Vec<u8> {
    image::open(path)
        .unwrap_or_else(|e| panic!("read {}: {e}", path.display()))
        .to_rgba8()
        .into_raw()
}

fn frame(dir: &Path, k: u32, ext: &str) -> PathBuf {
    dir.join(format!("frame_{k:06}.{ext}"))
}

/// A 3-frame orbit equals three `render` calls with the matching cameras, bit for bit
/// (linear float EXR), and the three frames differ from each other.
#[test]
fn three_frame_orbit_equals_three_renders() {
    let s = Scratch::new("orbit");
    s.write("base.toml", &scene(0.0));
    ok(
        &s.0,
        &[
            "animate",
            "base.toml",
            "--yaw",
            "0,90",
            "--frames",
            "3",
            "--size",
            "24x20",
            "--format",
            "exr",
            "-o",
            "frames",
        ],
    );
    let mut frames = Vec::new();
    for (k, yaw) in [(0, 0.0), (1, 45.0), (2, 90.0)] {
        let name = format!("yaw{k}.toml");
        s.write(&name, &scene(yaw));
        let out = format!("render{k}.exr");
        ok(&s.0, &["render", &name, "--size", "24x20", "-o", &out]);
        let f = exr_pixels(&frame(&s.path("frames"), k, "exr"));
        assert!(
            f == exr_pixels(&s.path(&out)),
            "frame {k} differs from render at yaw {yaw}"
        );
        frames.push(f);
    }
    assert!(frames[0] != frames[1] && frames[1] != frames[2], "the camera moves");
}

/// The ball-lens volume at 16³ with a clip plane and the given light and clip offset.
fn swept_scene(polar: f32, azimuth: f32, offset: f32) -> String {
    format!(
        "transfer = {:?}\n[volume]\nkind = \"builtin\"\nname = \"ball-lens\"\nresolution = 16\n\
         [light]\npolar_deg = {polar:?}\nazimuth_deg = {azimuth:?}\n[clip]\nnormal = [1.0, 0.0, 0.5]\noffset = {offset:?}\n",
        tf_file("ball-lens.json")
    )
}

/// Light and clip-plane sweeps combined: each frame equals `render` of the scene with the
/// swept values, bit for bit.
#[test]
fn light_and_clip_sweeps_equal_renders_of_the_swept_scenes() {
    let s = Scratch::new("sweeps");
    s.write("base.toml", &swept_scene(0.0, 0.0, 0.0));
    ok(
        &s.0,
        &[
            "animate",
            "base.toml",
            "--light-polar",
            "20,60",
            "--light-azimuth",
            "-30,30",
            "--clip",
            "0.5,-0.5",
            "--frames",
            "3",
            "--size",
            "20x20",
            "--format",
            "exr",
            "-o",
            "frames",
        ],
    );
    let mut frames = Vec::new();
    for (k, (polar, azimuth, offset)) in [(20.0, -30.0, 0.5), (40.0, 0.0, 0.0), (60.0, 30.0, -0.5)]
        .into_iter()
        .enumerate()
    {
        let name = format!("s{k}.toml");
        s.write(&name, &swept_scene(polar, azimuth, offset));
        let out = format!("render{k}.exr");
        ok(&s.0, &["render", &name, "--size", "20x20", "-o", &out]);
        let f = exr_pixels(&frame(&s.path("frames"), k as u32, "exr"));
        assert!(f == exr_pixels(&s.path(&out)), "frame {k} differs from {name}");
        frames.push(f);
    }
    assert!(
        frames[0] != frames[1] && frames[1] != frames[2],
        "light and clip plane move"
    );
}

/// Shards 0/2 and 1/2 together equal the unsharded run (pixels, embedded hashes and
/// manifest); `--check` sees what is missing; a resumed run renders only missing frames;
/// a changed animation re-renders only the frames it changes and `--check` reports the
/// others as stale.
#[test]
fn shards_equal_the_unsharded_run_and_resume_skips_present_frames() {
    let s = Scratch::new("shards");
    let tracks = [
        "animate",
        "--scene",
        "ball-lens",
        "--resolution",
        "16",
        "--yaw",
        "0,120",
        "--light-polar",
        "20,60",
    ];
    let run = |extra: &[&str]| {
        let mut args = tracks.to_vec();
        args.extend_from_slice(&["--frames", "5", "--size", "16x16"]);
        args.extend_from_slice(extra);
        ok(&s.0, &args)
    };
    run(&["-o", "all"]);
    run(&["-o", "split", "--shard", "0/2"]);
    let (stdout, _) = fails(&s.0, &["animate", "--check", "split"], 1);
    assert!(
        stdout.contains("3 of 5 frames present") && stdout.contains("missing: 1, 3"),
        "{stdout}"
    );
    run(&["-o", "split", "--shard", "1/2"]);
    ok(&s.0, &["animate", "--check", "split"]);
    let (all, split) = (s.path("all"), s.path("split"));
    for k in 0..5 {
        assert_eq!(
            png_pixels(&frame(&all, k, "png")),
            png_pixels(&frame(&split, k, "png")),
            "frame {k}"
        );
        assert_eq!(
            fs::read(frame(&all, k, "png")).unwrap(),
            fs::read(frame(&split, k, "png")).unwrap()
        );
    }
    assert_eq!(
        fs::read(all.join("manifest.json")).unwrap(),
        fs::read(split.join("manifest.json")).unwrap()
    );
    assert_ne!(png_pixels(&frame(&all, 0, "png")), png_pixels(&frame(&all, 4, "png")));
    // The animation file written next to the frames renders the same frames again.
    ok(
        &s.0,
        &["animate", "all/animation.toml", "-o", "again", "--range", "4..4"],
    );
    assert_eq!(
        fs::read(frame(&all, 4, "png")).unwrap(),
        fs::read(frame(&s.path("again"), 4, "png")).unwrap()
    );

    // Resume: only the deleted frame is rendered again; the others are left untouched.
    let mtime = |k| fs::metadata(frame(&split, k, "png")).unwrap().modified().unwrap();
    let before: Vec<_> = (0..5).map(mtime).collect();
    fs::remove_file(frame(&split, 2, "png")).unwrap();
    let stderr = run(&["-o", "split"]);
    assert!(
        stderr.contains("rendered 1 of 5 frames") && stderr.contains("4 already present"),
        "{stderr}"
    );
    for k in [0, 1, 3, 4] {
        assert_eq!(mtime(k), before[k as usize], "frame {k} was not rewritten");
    }
    assert_eq!(png_pixels(&frame(&all, 2, "png")), png_pixels(&frame(&split, 2, "png")));
    let stderr = run(&["-o", "split"]);
    assert!(stderr.contains("nothing to render"), "{stderr}");

    // A changed light sweep: frame 0 (polar 20 in both) stays, frame 1 is stale and
    // re-rendered; frames 2..4 are reported stale.
    let mut changed = tracks.to_vec();
    *changed.last_mut().unwrap() = "20,68";
    changed.extend_from_slice(&["--frames", "5", "--size", "16x16", "-o", "split", "--range", "0..1"]);
    let stderr = ok(&s.0, &changed);
    assert!(
        stderr.contains("rendered 1 of 2 frames") && stderr.contains("1 already present"),
        "{stderr}"
    );
    let (stdout, stderr) = fails(&s.0, &["animate", "--check", "split"], 1);
    assert!(stdout.contains("stale: 2..4"), "{stdout}");
    assert!(stderr.contains("0 missing and 3 stale"), "{stderr}");
}

/// A transfer-function key halfway equals a render with the interpolated functions: points
/// moved halfway (same counts), and a colour ramp with one point against one with two
/// (values at both positions). All values are dyadic, so the halfway points are exact.
#[test]
fn transfer_key_halfway_equals_the_interpolated_functions() {
    let s = Scratch::new("tf");
    s.write(
        "a.json",
        r#"{"opacity": [[0.25, 0.0], [0.5, 0.5]], "color": [[0.0, 1.0, 1.0, 1.0]], "eta": [[0.0, 1.0], [0.5, 1.5]]}"#,
    );
    s.write(
        "b.json",
        r#"{"opacity": [[0.5, 0.0], [0.75, 1.0]], "color": [[0.0, 1.0, 0.5, 0.0], [1.0, 0.0, 0.5, 1.0]], "eta": [[0.0, 1.0], [0.5, 1.25]]}"#,
    );
    s.write(
        "mid.json",
        r#"{"opacity": [[0.375, 0.0], [0.625, 0.75]], "color": [[0.0, 1.0, 0.75, 0.5], [1.0, 0.5, 0.75, 1.0]], "eta": [[0.0, 1.0], [0.5, 1.375]]}"#,
    );
    let common = ["--scene", "ball-lens", "--resolution", "16", "--size", "20x20"];
    let mut args = vec![
        "animate",
        "--transfer-keys",
        "a.json,b.json",
        "--frames",
        "3",
        "--format",
        "exr",
        "-o",
        "f",
    ];
    args.extend_from_slice(&common);
    ok(&s.0, &args);
    let mut args = vec!["render", "--transfer", "mid.json", "-o", "mid.exr"];
    args.extend_from_slice(&common);
    ok(&s.0, &args);
    let mid = exr_pixels(&s.path("mid.exr"));
    assert!(
        exr_pixels(&frame(&s.path("f"), 1, "exr")) == mid,
        "frame 1 is the halfway functions"
    );
    assert!(exr_pixels(&frame(&s.path("f"), 0, "exr")) != mid, "frame 0 is key a");
}

/// Writes frame `k` of a series: a sphere of value (k + 1)/4 inside a shell of half that.
fn series_frame(path: &Path, k: usize, n: usize) -> Volume {
    let value = (k + 1) as f32 * 0.25;
    let mut data = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let c = |i: usize| (i as f32 + 0.5) / n as f32 - 0.5;
                let r = (c(x).powi(2) + c(y).powi(2) + c(z).powi(2)).sqrt();
                data.push(if r < 0.25 {
                    value
                } else if r < 0.4 {
                    value * 0.5
                } else {
                    0.0
                });
            }
        }
    }
    let v = Volume::new([n, n, n], [1.0; 3], data).expect("valid volume");
    write_nrrd(path, &v, false).expect("write frame");
    v
}

/// A series interpolated in time: at t = 1 the frame is `render --time 1` of the same scene,
/// at t = 0.5 it is the render of the voxel-wise mean of frames 0 and 1 (dyadic values, so
/// the mean is exact).
#[test]
fn time_series_frames_hold_and_blend() {
    let s = Scratch::new("series");
    let vols: Vec<Volume> = (0..3)
        .map(|k| series_frame(&s.path(&format!("t{k}.nrrd")), k, 16))
        .collect();
    let mean: Vec<f32> = vols[0]
        .data
        .iter()
        .zip(&vols[1].data)
        .map(|(a, b)| 0.5 * a + 0.5 * b)
        .collect();
    write_nrrd(
        &s.path("mean.nrrd"),
        &Volume::new([16; 3], [1.0; 3], mean).unwrap(),
        false,
    )
    .unwrap();
    let scene = |volume: &str| {
        format!(
            "window = [0.0, 1.0]\ntransfer = {{ opacity = [[0.0, 0.0], [1.0, 0.8]], color = [[0.0, 1.0, 0.5, 0.0], [1.0, 0.0, 0.5, 1.0]] }}\n\
             [volume]\n{volume}\n[light]\nsoftness = 0.0\n"
        )
    };
    s.write("series.toml", &scene("kind = \"series\"\npattern = \"t*.nrrd\""));
    s.write("mean.toml", &scene("kind = \"file\"\npath = \"mean.nrrd\""));
    let size = ["--size", "16x16"];
    let mut args = vec![
        "animate",
        "series.toml",
        "--time-series",
        "0..2",
        "--time-mode",
        "interpolate",
    ];
    args.extend_from_slice(&["--frames", "5", "--format", "exr", "-o", "f"]);
    args.extend_from_slice(&size);
    ok(&s.0, &args);
    ok(
        &s.0,
        &[
            "render",
            "series.toml",
            "--time",
            "1",
            "-o",
            "t1.exr",
            "--size",
            "16x16",
        ],
    );
    ok(&s.0, &["render", "mean.toml", "-o", "mean.exr", "--size", "16x16"]);
    let f = |k| exr_pixels(&frame(&s.path("f"), k, "exr"));
    assert!(f(2) == exr_pixels(&s.path("t1.exr")), "t = 1 is frame 1");
    assert!(
        f(1) == exr_pixels(&s.path("mean.exr")),
        "t = 0.5 is the mean of frames 0 and 1"
    );
    assert!(f(1) != f(0) && f(1) != f(2));
}

/// An executable script `ffmpeg` in `dir`.
fn fake_ffmpeg(dir: &Path, body: &str) {
    let path = dir.join("ffmpeg");
    fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
    use std::os::unix::fs::PermissionsExt;
    fs::set_permissions(&path, fs::Permissions::from_mode(0o755)).unwrap();
}

/// MP4 output: without ffmpeg on the PATH the command fails with a clear message and keeps
/// the frames; a failing ffmpeg is reported with its message; with the real ffmpeg the
/// present frames are encoded without rendering again, odd sizes padded to even ones.
#[test]
fn mp4_needs_ffmpeg_and_keeps_the_frames_without_it() {
    let s = Scratch::new("mp4");
    let no_ffmpeg = s.path("bin-empty");
    fs::create_dir_all(&no_ffmpeg).unwrap();
    let args = [
        "animate",
        "--scene",
        "ball-lens",
        "--resolution",
        "16",
        "--frames",
        "2",
        "--size",
        "17x15",
        "--yaw",
        "0,30",
        "-o",
        "movie.mp4",
    ];
    let out = command(&s.0, &args).env("PATH", &no_ffmpeg).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", shown(&args, &out));
    let stderr = String::from_utf8_lossy(&out.stderr);
    for text in [
        "movie.mp4",
        "ffmpeg is not on the PATH",
        "apt-get install ffmpeg",
        "movie_frames",
    ] {
        assert!(stderr.contains(text), "stderr should mention '{text}': {stderr}");
    }
    assert!(!s.path("movie.mp4").exists());
    ok(&s.0, &["animate", "--check", "movie_frames"]);

    let failing = s.path("bin-failing");
    fs::create_dir_all(&failing).unwrap();
    fake_ffmpeg(&failing, "echo 'Unknown encoder libx264' >&2; exit 1");
    let out = command(&s.0, &args).env("PATH", &failing).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", shown(&args, &out));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("ffmpeg failed") && stderr.contains("Unknown encoder libx264"),
        "{stderr}"
    );
    assert!(stderr.contains("nothing to render"), "the frames were kept: {stderr}");
    assert!(!s.path("movie.mp4").exists());

    let found = Command::new("ffprobe").arg("-version").output();
    assert!(
        found.is_ok_and(|o| o.status.success()),
        "ffmpeg/ffprobe not found: install the Debian package ffmpeg (`.ci/ensure-vulkan --test` does)"
    );
    let stderr = ok(&s.0, &args);
    assert!(
        stderr.contains("nothing to render") && stderr.contains("wrote movie.mp4"),
        "{stderr}"
    );
    let probe = Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args([
            "-show_entries",
            "stream=codec_name,width,height,nb_read_frames",
            "-of",
            "csv=p=0",
        ])
        .arg(s.path("movie.mp4"))
        .output()
        .unwrap();
    let info = String::from_utf8_lossy(&probe.stdout);
    assert_eq!(info.trim(), "h264,18,16,2", "codec, padded size and frame count");
}

/// Runs caustica without any Vulkan driver: usage errors must be found before the GPU.
fn without_gpu(dir: &Path, args: &[&str]) -> Output {
    let missing_icd = dir.join("no-such-vulkan-driver.json");
    command(dir, args)
        .env("VK_ICD_FILENAMES", &missing_icd)
        .env("VK_DRIVER_FILES", &missing_icd)
        .env_remove("CAUSTICA_VALIDATION")
        .output()
        .unwrap()
}

/// Bad shards, ranges and option combinations are usage errors (exit 2) naming the
/// problem, found before any GPU work and before any file is written.
#[test]
fn bad_shards_and_ranges_are_usage_errors() {
    let s = Scratch::new("usage");
    let base = [
        "animate",
        "--scene",
        "ball-lens",
        "--resolution",
        "8",
        "--frames",
        "4",
        "-o",
        "out",
    ];
    let cases: &[(&[&str], &str)] = &[
        (&["--shard", "2/2"], "below the count"),
        (&["--shard", "1/0"], "at least 1"),
        (&["--shard", "a/2"], "INDEX/COUNT"),
        (&["--range", "3..1"], "after the last"),
        (&["--range", "2..4"], "4 frames"),
        (&["--range", "7"], "FIRST..LAST"),
        (&["--yaw", "10"], "two or more"),
        (&["--transfer-keys", "a.json"], "two or more"),
        (&["--time-series", "all"], "time-series input"),
        (&["--fps", "0"], "frames per second"),
        (&["--frames", "0"], "--frames"),
    ];
    for (extra, expected) in cases {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        let out = without_gpu(&s.0, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(EXIT_USAGE), "{}", shown(&args, &out));
        assert!(
            stderr.contains(expected),
            "stderr should mention '{expected}': {}",
            shown(&args, &out)
        );
        assert!(!s.path("out").exists(), "{}", shown(&args, &out));
    }
    let out = without_gpu(
        &s.0,
        &["animate", "--scene", "ball-lens", "-o", "out.mp4", "--format", "exr"],
    );
    assert_eq!(out.status.code(), Some(EXIT_USAGE));
    s.write("a.toml", "frames = 2\nsize = [4, 4]\n[scene]\ntransfer = { opacity = [[0.0, 0.0]] }\n[scene.volume]\nkind = \"builtin\"\nname = \"ball-lens\"\nresolution = 8\n");
    let out = without_gpu(&s.0, &["animate", "a.toml", "--yaw", "0,1", "-o", "out"]);
    assert_eq!(out.status.code(), Some(EXIT_USAGE));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--yaw cannot change the animation file"));
    let out = without_gpu(&s.0, &["animate", "--check", "no-such-dir"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("manifest.json"));
}
