//! The interactive viewer under a virtual X server (Xvfb) on the real Vulkan device: it
//! settles to full quality, the window is read back from the X server and compared with
//! `caustica render` of the same scene and size; the saved scene renders the same image; no
//! validation error (leaks at device destruction included) is reported.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A private X server on a free display number, killed on drop.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Xvfb {
        let found = Command::new("Xvfb")
            .arg("-help")
            .stderr(Stdio::null())
            .stdout(Stdio::null())
            .status();
        assert!(
            found.is_ok(),
            "the viewer tests need Xvfb (a virtual X server): run `.ci/ensure-vulkan --test` \
             or `apt-get install xvfb libxkbcommon-x11-0 libx11-xcb1`"
        );
        // `-displayfd 1`: Xvfb picks a free display itself and prints its number on stdout
        // once it accepts connections, so parallel tests never share a server.
        let mut child = Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "640x480x24", "-nolisten", "tcp"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("cannot start Xvfb");
        let mut line = String::new();
        let stdout = child.stdout.take().expect("Xvfb stdout");
        let read = BufReader::new(stdout).read_line(&mut line);
        let number = line.trim().parse::<u32>();
        match (read, number) {
            (Ok(_), Ok(n)) => Xvfb {
                child,
                display: format!(":{n}"),
            },
            _ => {
                let _ = child.kill();
                panic!("Xvfb did not report a display number (got '{}')", line.trim());
            }
        }
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("caustica-viewer-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs caustica with a time limit (a hung window must fail the test, not stall the suite).
fn caustica(args: &[&str], display: Option<&str>, limit: Duration) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_caustica"));
    cmd.args(args)
        .env("CAUSTICA_VALIDATION", "require")
        .env_remove("WAYLAND_DISPLAY")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    match display {
        Some(d) => cmd.env("DISPLAY", d),
        None => cmd.env_remove("DISPLAY"),
    };
    let mut child = cmd.spawn().expect("cannot start caustica");
    let start = Instant::now();
    loop {
        if let Ok(Some(_)) = child.try_wait() {
            return child.wait_with_output().unwrap();
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let out = child.wait_with_output().unwrap();
            panic!(
                "caustica {args:?} did not finish within {limit:?}\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn assert_ok(out: &Output, what: &str) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{what} failed ({}):\n{stderr}", out.status);
    // The validation layer reports objects still alive at vkDestroyDevice as errors, so this
    // also checks that the window and render thread shut down cleanly.
    assert!(
        !stderr.contains("validation error"),
        "{what}: validation errors:\n{stderr}"
    );
    stderr
}

fn rgb(path: &Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    (img.width(), img.height(), img.into_raw())
}

/// Largest and mean absolute difference of 8-bit channels.
fn compare(a: &Path, b: &Path) -> (u8, f64) {
    let (wa, ha, pa) = rgb(a);
    let (wb, hb, pb) = rgb(b);
    assert_eq!((wa, ha), (wb, hb), "{} and {} differ in size", a.display(), b.display());
    let d: Vec<u8> = pa.iter().zip(&pb).map(|(x, y)| x.abs_diff(*y)).collect();
    let max = d.iter().copied().max().unwrap_or(0);
    let mean = d.iter().map(|v| *v as f64).sum::<f64>() / d.len().max(1) as f64;
    (max, mean)
}

/// The window's full-quality frame is the render `caustica render` makes (same renderer,
/// same deterministic device, same float → sRGB8 conversion) and a 24-bit X visual stores
/// 8-bit channels losslessly, so the images should be identical. The tolerance allows one
/// level of rounding per channel (a driver may reorder float sums between two runs) and a
/// mean far below what any visible difference gives; `coarser_render_fails_the_comparison`
/// shows a real difference is far outside it.
const MAX_LEVELS: u8 = 1;
const MAX_MEAN_LEVELS: f64 = 0.05;

fn same_image(a: &Path, b: &Path) -> bool {
    let (max, mean) = compare(a, b);
    eprintln!("{} vs {}: max {max}, mean {mean:.4}", a.display(), b.display());
    max <= MAX_LEVELS && mean <= MAX_MEAN_LEVELS
}

/// A scene that differs from the built-in defaults in camera, light and transfer functions,
/// so the saved scene has to carry all of them.
const SCENE: &str = r#"
volume = { kind = "builtin", name = "ball-lens", resolution = 48 }
transfer = { opacity = [[0.0, 0.0], [0.45, 0.0], [0.5, 0.6]], color = [[0.0, 1.0, 0.9, 0.7]], eta = [[0.0, 1.0], [0.45, 1.0], [0.5, 1.4]] }
[camera]
yaw_deg = 25.0
pitch_deg = 30.0
distance = 2.6
[light]
polar_deg = 40.0
azimuth_deg = 60.0
softness = 0.1
"#;

#[test]
fn window_shows_the_offscreen_render_and_saved_scene_reproduces_it() {
    let dir = scratch("compare");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let (capture, saved, reference, from_saved, coarse) = (
        dir.join("window.png"),
        dir.join("saved.toml"),
        dir.join("render.png"),
        dir.join("saved.png"),
        dir.join("coarse.png"),
    );
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let x = Xvfb::start();
    let out = caustica(
        &[
            "view",
            &s(&scene),
            "--size",
            "96x80",
            "--no-panel",
            "--exit-after-idle",
            "--screenshot",
            &s(&capture),
            "--save-scene",
            &s(&saved),
        ],
        Some(&x.display),
        Duration::from_secs(120),
    );
    assert_ok(&out, "caustica view");
    drop(x);
    let limit = Duration::from_secs(60);
    let render = |input: &Path, output: &Path, extra: &[&str]| {
        let mut args = vec![
            "render".to_string(),
            s(input),
            "--size".into(),
            "96x80".into(),
            "-o".into(),
            s(output),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        let args: Vec<&str> = args.iter().map(|a| a.as_str()).collect();
        assert_ok(&caustica(&args, None, limit), "caustica render");
    };
    render(&scene, &reference, &[]);
    render(&saved, &from_saved, &[]);
    assert!(
        same_image(&capture, &reference),
        "the window differs from `caustica render`"
    );
    assert!(
        same_image(&from_saved, &capture),
        "the saved scene renders differently from the window"
    );

    // The comparison can fail: the preview level (twice the sample distance) is a different
    // image, and so is the window capture against it.
    render(&scene, &coarse, &["--sample-distance", "2"]);
    assert!(!same_image(&coarse, &capture), "a coarser render passes the comparison");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A resize reaches the renderer: after the window grows, the full frame is the render at the
/// new size, and shutting down after the resize is still clean.
#[test]
fn resized_window_renders_at_the_new_size() {
    let dir = scratch("resize");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let (capture, reference) = (dir.join("window.png"), dir.join("render.png"));
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let x = Xvfb::start();
    let out = caustica(
        &[
            "view",
            &s(&scene),
            "--size",
            "64x48",
            "--no-panel",
            "--resize-after-idle",
            "100x72",
            "--exit-after-idle",
            "--screenshot",
            &s(&capture),
        ],
        Some(&x.display),
        Duration::from_secs(120),
    );
    assert_ok(&out, "caustica view");
    drop(x);
    let args = ["render", &s(&scene), "--size", "100x72", "-o", &s(&reference)];
    assert_ok(&caustica(&args, None, Duration::from_secs(60)), "caustica render");
    assert!(
        same_image(&capture, &reference),
        "the resized window differs from `caustica render`"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn without_a_display_the_viewer_fails_with_a_clear_message() {
    let out = caustica(
        &[
            "view",
            "--scene",
            "ball-lens",
            "--resolution",
            "32",
            "--exit-after-idle",
        ],
        None,
        Duration::from_secs(60),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("cannot connect to a display"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}
