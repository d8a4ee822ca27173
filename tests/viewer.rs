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

/// Starts caustica with validation required; stderr goes to a file (a pipe nobody reads
/// could fill up and stall the viewer).
fn spawn(args: &[&str], display: Option<&str>, stderr: &Path) -> Child {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_caustica"));
    cmd.args(args)
        .env("CAUSTICA_VALIDATION", "require")
        .env_remove("WAYLAND_DISPLAY")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(stderr).unwrap());
    match display {
        Some(d) => cmd.env("DISPLAY", d),
        None => cmd.env_remove("DISPLAY"),
    };
    cmd.spawn().expect("cannot start caustica")
}

/// Waits for `child` with a time limit (a hung window must fail the test, not stall the
/// suite); returns its exit status and stderr.
fn finish(mut child: Child, stderr: &Path, limit: Duration, what: &str) -> (std::process::ExitStatus, String) {
    let start = Instant::now();
    loop {
        if let Ok(Some(status)) = child.try_wait() {
            return (status, std::fs::read_to_string(stderr).unwrap_or_default());
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "{what} did not finish within {limit:?}\n{}",
                std::fs::read_to_string(stderr).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Runs caustica to completion within `limit`.
fn caustica(args: &[&str], display: Option<&str>, limit: Duration) -> Output {
    let stderr = std::env::temp_dir().join(format!(
        "caustica-viewer-stderr-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    ));
    let child = spawn(args, display, &stderr);
    let (status, text) = finish(child, &stderr, limit, &format!("caustica {args:?}"));
    let _ = std::fs::remove_file(&stderr);
    Output {
        status,
        stdout: Vec::new(),
        stderr: text.into_bytes(),
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

/// Three 24³ frames of different built-in volumes, t0..t2.nrrd in `dir`; returns the pattern.
fn write_series(dir: &Path) -> String {
    for (k, name) in ["ball-lens", "glass", "supernova"].iter().enumerate() {
        let path = dir.join(format!("t{k}.nrrd"));
        let args = [
            "dataset",
            name,
            "-o",
            path.to_str().unwrap(),
            "--resolution",
            "24",
            "--raw",
        ];
        assert_ok(&caustica(&args, None, Duration::from_secs(60)), "caustica dataset");
    }
    dir.join("t*.nrrd").to_str().unwrap().to_string()
}

/// A bare time series (three small NRRD frames of different volumes) opens as `caustica
/// render` shows it: same frame (--time), same default transfer functions and window, and the
/// saved scene keeps the frame. Rendering another frame fails the comparison.
#[test]
fn time_series_frame_matches_the_offscreen_render() {
    let dir = scratch("series");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let limit = Duration::from_secs(60);
    let pattern = write_series(&dir);
    let (capture, saved, reference, other) = (
        dir.join("window.png"),
        dir.join("saved.toml"),
        dir.join("render.png"),
        dir.join("frame0.png"),
    );
    let x = Xvfb::start();
    let out = caustica(
        &[
            "view",
            &pattern,
            "--time",
            "1",
            "--size",
            "64x48",
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
    let stderr = assert_ok(&out, "caustica view");
    assert!(stderr.contains("frame 1 of 3"), "{stderr}");
    drop(x);
    let render = |time: &str, output: &Path| {
        let args = ["render", &pattern, "--time", time, "--size", "64x48", "-o", &s(output)];
        assert_ok(&caustica(&args, None, limit), "caustica render");
    };
    render("1", &reference);
    assert!(
        same_image(&capture, &reference),
        "the window differs from `caustica render --time 1`"
    );
    let text = std::fs::read_to_string(&saved).unwrap();
    assert!(text.contains("frame = 1") && text.contains("window = ["), "{text}");
    let from_saved = dir.join("saved.png");
    let args = ["render", &s(&saved), "--size", "64x48", "-o", &s(&from_saved)];
    assert_ok(&caustica(&args, None, limit), "caustica render of the saved scene");
    assert!(
        same_image(&from_saved, &capture),
        "the saved scene renders differently from the window"
    );
    render("0", &other);
    assert!(!same_image(&other, &capture), "frame 0 passes the comparison");
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

/// A GPU failure on the render thread (the device is lost at the first frame's submission)
/// ends `view --exit-after-idle` with the GPU exit code, not the one for bad input.
#[test]
fn a_lost_device_in_the_viewer_exits_4() {
    let x = Xvfb::start();
    let stderr_path = std::env::temp_dir().join(format!("caustica-viewer-lost-{}", std::process::id()));
    let args = [
        "view",
        "--scene",
        "ball-lens",
        "--resolution",
        "16",
        "--size",
        "64x48",
        "--no-panel",
        "--exit-after-idle",
    ];
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_caustica"));
    cmd.args(args)
        .env("DISPLAY", &x.display)
        .env("CAUSTICA_FAULT", "lost:1")
        .env_remove("WAYLAND_DISPLAY")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&stderr_path).unwrap());
    let child = cmd.spawn().expect("cannot start caustica");
    let (status, stderr) = finish(child, &stderr_path, Duration::from_secs(120), "view with a lost device");
    let _ = std::fs::remove_file(&stderr_path);
    assert_eq!(status.code(), Some(4), "{stderr}");
    assert!(stderr.contains("device was lost"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Real input through the X server (XTEST, as from a mouse and keyboard).
mod input {
    use std::time::{Duration, Instant};

    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::{AtomEnum, ClientMessageEvent, ConnectionExt as _, EventMask, InputFocus, Window};
    use x11rb::protocol::xtest::ConnectionExt as _;
    use x11rb::rust_connection::RustConnection;

    const KEY_PRESS: u8 = 2;
    const KEY_RELEASE: u8 = 3;
    const BUTTON_PRESS: u8 = 4;
    const BUTTON_RELEASE: u8 = 5;
    const MOTION: u8 = 6;

    pub struct X {
        conn: RustConnection,
        root: Window,
        window: Window,
        /// The viewer window's top-left corner on the screen.
        origin: (i16, i16),
    }

    impl X {
        /// Connects to `display` and waits for the window titled "caustica".
        pub fn find_window(display: &str) -> X {
            let (conn, screen) = x11rb::connect(Some(display)).expect("connect to Xvfb");
            let root = conn.setup().roots[screen].root;
            let start = Instant::now();
            while start.elapsed() < Duration::from_secs(60) {
                let children = conn.query_tree(root).unwrap().reply().unwrap().children;
                for w in children {
                    let name = conn
                        .get_property(false, w, AtomEnum::WM_NAME, AtomEnum::ANY, 0, 64)
                        .unwrap()
                        .reply()
                        .unwrap()
                        .value;
                    if name == b"caustica" {
                        let t = conn.translate_coordinates(w, root, 0, 0).unwrap().reply().unwrap();
                        return X {
                            conn,
                            root,
                            window: w,
                            origin: (t.dst_x, t.dst_y),
                        };
                    }
                }
                std::thread::sleep(Duration::from_millis(100));
            }
            panic!("no window titled 'caustica' appeared on {display}");
        }

        fn fake(&self, kind: u8, detail: u8, x: i16, y: i16) {
            self.conn
                .xtest_fake_input(kind, detail, 0, self.root, self.origin.0 + x, self.origin.1 + y, 0)
                .unwrap();
            self.conn.flush().unwrap();
            // Separate frames, as a real hand would produce.
            std::thread::sleep(Duration::from_millis(60));
        }

        /// A left-button drag inside the window, in `steps` moves.
        pub fn drag(&self, from: (i16, i16), to: (i16, i16), steps: i16) {
            self.fake(MOTION, 0, from.0, from.1);
            self.fake(BUTTON_PRESS, 1, from.0, from.1);
            for k in 1..=steps {
                let x = from.0 + (to.0 - from.0) * k / steps;
                let y = from.1 + (to.1 - from.1) * k / steps;
                self.fake(MOTION, 0, x, y);
            }
            self.fake(BUTTON_RELEASE, 1, to.0, to.1);
        }

        /// What a window manager sends when the user clicks the close button.
        pub fn close(&self) {
            let atom = |name: &[u8]| self.conn.intern_atom(false, name).unwrap().reply().unwrap().atom;
            let (protocols, delete) = (atom(b"WM_PROTOCOLS"), atom(b"WM_DELETE_WINDOW"));
            let event = ClientMessageEvent::new(32, self.window, protocols, [delete, x11rb::CURRENT_TIME, 0, 0, 0]);
            self.conn
                .send_event(false, self.window, EventMask::NO_EVENT, event)
                .unwrap();
            self.conn.flush().unwrap();
        }

        /// Gives the window the keyboard focus (the job of a window manager, which Xvfb runs
        /// without), then presses and releases the key that types `keysym`.
        pub fn key(&self, keysym: u32) {
            self.conn
                .set_input_focus(InputFocus::PARENT, self.window, x11rb::CURRENT_TIME)
                .unwrap();
            self.conn.flush().unwrap();
            std::thread::sleep(Duration::from_millis(200));
            let setup = self.conn.setup();
            let (min, max) = (setup.min_keycode, setup.max_keycode);
            let map = self
                .conn
                .get_keyboard_mapping(min, max - min + 1)
                .unwrap()
                .reply()
                .unwrap();
            let per = map.keysyms_per_keycode as usize;
            let index = map
                .keysyms
                .iter()
                .position(|k| *k == keysym)
                .expect("keysym on the keyboard map");
            let keycode = min + (index / per) as u8;
            self.fake(KEY_PRESS, keycode, 10, 10);
            self.fake(KEY_RELEASE, keycode, 10, 10);
        }
    }
}

/// Scripted input through the X server: a mouse drag orbits the camera, the view settles
/// again, the saved scene carries the new camera and renders what the window shows, and the
/// `q` key closes the window cleanly.
#[test]
fn mouse_drag_orbits_and_q_quits_cleanly() {
    let dir = scratch("input");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let (capture, saved, reference, log) = (
        dir.join("window.png"),
        dir.join("saved.toml"),
        dir.join("render.png"),
        dir.join("stderr.txt"),
    );
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let x = Xvfb::start();
    let args = [
        "view",
        &s(&scene),
        "--size",
        "96x80",
        "--no-panel",
        "--screenshot",
        &s(&capture),
        "--save-scene",
        &s(&saved),
    ];
    let child = spawn(&args, Some(&x.display), &log);
    let wait_for = |what: &str, done: &dyn Fn() -> bool| {
        let start = Instant::now();
        while !done() {
            assert!(
                start.elapsed() < Duration::from_secs(90),
                "timed out waiting for {what}\n{}",
                std::fs::read_to_string(&log).unwrap_or_default()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    };
    let read = |p: &Path| std::fs::read_to_string(p).unwrap_or_default();
    wait_for("the first full frame", &|| !read(&saved).is_empty());
    let first = read(&saved);
    let input = input::X::find_window(&x.display);
    input.drag((48, 40), (88, 40), 8);
    wait_for("the full frame after the drag", &|| {
        let now = read(&saved);
        !now.is_empty() && now != first
    });
    input.key(u32::from(b'q'));
    let (status, stderr) = finish(child, &log, Duration::from_secs(60), "caustica view");
    assert!(status.success(), "caustica view failed ({status}):\n{stderr}");
    assert!(!stderr.contains("validation error"), "validation errors:\n{stderr}");
    drop(x);

    let yaw = |text: &str| -> f32 {
        let scene: toml::Value = toml::from_str(text).unwrap();
        scene["camera"]["yaw_deg"].as_float().unwrap() as f32
    };
    // 40 pixels right at 0.4°/pixel turn the yaw down by up to 16° (egui keeps back the first
    // few pixels until it knows the press is a drag).
    let turned = yaw(&first) - yaw(&read(&saved));
    assert!((8.0..=16.5).contains(&turned), "yaw turned by {turned}°");
    let out = caustica(
        &["render", &s(&saved), "--size", "96x80", "-o", &s(&reference)],
        None,
        Duration::from_secs(60),
    );
    assert_ok(&out, "caustica render");
    assert!(
        same_image(&capture, &reference),
        "the window after the drag differs from the saved scene's render"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Stepping through a series with Page Down (real key presses through the X server): the
/// render thread loads the frames, the view settles on frame 2, the saved scene keeps it and
/// the window shows `caustica render --time 2`.
#[test]
fn page_down_steps_through_a_series() {
    let dir = scratch("step");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let pattern = write_series(&dir);
    let (capture, saved, reference, log) = (
        dir.join("window.png"),
        dir.join("saved.toml"),
        dir.join("render.png"),
        dir.join("stderr.txt"),
    );
    let x = Xvfb::start();
    let args = [
        "view",
        &pattern,
        "--size",
        "64x48",
        "--no-panel",
        "--screenshot",
        &s(&capture),
        "--save-scene",
        &s(&saved),
    ];
    let child = spawn(&args, Some(&x.display), &log);
    let read = |p: &Path| std::fs::read_to_string(p).unwrap_or_default();
    let wait_for = |what: &str, done: &dyn Fn() -> bool| {
        let start = Instant::now();
        while !done() {
            assert!(
                start.elapsed() < Duration::from_secs(90),
                "timed out waiting for {what}\n{}",
                read(&log)
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    };
    wait_for("the first full frame", &|| read(&saved).contains("frame = 0"));
    let input = input::X::find_window(&x.display);
    const PAGE_DOWN: u32 = 0xff56;
    input.key(PAGE_DOWN);
    input.key(PAGE_DOWN);
    // The capture of a settled frame is written just before its scene.
    wait_for("the full frame of frame 2", &|| read(&saved).contains("frame = 2"));
    input.key(u32::from(b'q'));
    let (status, stderr) = finish(child, &log, Duration::from_secs(60), "caustica view");
    assert!(status.success(), "caustica view failed ({status}):\n{stderr}");
    assert!(!stderr.contains("validation error"), "validation errors:\n{stderr}");
    drop(x);
    let args = [
        "render",
        &pattern,
        "--time",
        "2",
        "--size",
        "64x48",
        "-o",
        &s(&reference),
    ];
    assert_ok(&caustica(&args, None, Duration::from_secs(60)), "caustica render");
    assert!(
        same_image(&capture, &reference),
        "the window on frame 2 differs from `caustica render --time 2`"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The close button (the window manager's WM_DELETE_WINDOW message) while the view is
/// refining shuts down cleanly: the running render is cancelled, no validation error and no
/// object is left at device destruction.
#[test]
fn close_button_during_refinement_shuts_down_cleanly() {
    let dir = scratch("close");
    let log = dir.join("stderr.txt");
    let x = Xvfb::start();
    // A larger window, so the full frame is still rendering when the close arrives.
    let child = spawn(
        &[
            "view",
            "--scene",
            "ball-lens",
            "--resolution",
            "48",
            "--size",
            "320x240",
            "--frame-log",
        ],
        Some(&x.display),
        &log,
    );
    let input = input::X::find_window(&x.display);
    let start = Instant::now();
    while !std::fs::read_to_string(&log)
        .unwrap_or_default()
        .contains("frame: interactive")
    {
        assert!(start.elapsed() < Duration::from_secs(60), "no frame was shown");
        std::thread::sleep(Duration::from_millis(50));
    }
    input.close();
    let (status, stderr) = finish(child, &log, Duration::from_secs(60), "caustica view");
    assert!(status.success(), "caustica view failed ({status}):\n{stderr}");
    assert!(!stderr.contains("validation error"), "validation errors:\n{stderr}");
    assert!(
        !stderr.contains("frame: full"),
        "closed before the full frame:\n{stderr}"
    );
    // Each frame's line is followed by what the device spent of it, by pass: within the
    // frame's time, and the passes add up to it (five numbers rounded to 0.1 ms); then the
    // rest of the frame and what it copied into the scene textures (the first frame: all of
    // them).
    let lines: Vec<&str> = stderr.lines().collect();
    let at = lines
        .iter()
        .position(|l| l.starts_with("frame: interactive"))
        .expect("a frame line");
    let numbers = |l: &str| -> Vec<f64> {
        l.split(|c: char| !(c.is_ascii_digit() || c == '.'))
            .filter_map(|w| w.parse().ok())
            .collect()
    };
    let frame_ms = *numbers(lines[at]).last().unwrap();
    let gpu = lines.get(at + 1).copied().unwrap_or_default();
    assert!(gpu.starts_with("gpu: "), "no GPU line after the frame's:\n{stderr}");
    let g = numbers(gpu);
    assert_eq!(g.len(), 7, "{gpu}");
    assert!(g[6] > 0.0, "the first frame uploads the scene's textures: {gpu}");
    assert!(
        g[0] > 0.0 && g[0] <= frame_ms,
        "GPU {} ms of a {frame_ms} ms frame",
        g[0]
    );
    // Five numbers each rounded to 0.1 ms: at most 5 × 0.05 apart.
    assert!(
        (g[1] + g[2] + g[3] + g[4] - g[0]).abs() <= 0.3,
        "passes do not add up: {gpu}"
    );
    // Three numbers each rounded to 0.1 ms: at most 3 × 0.05 apart.
    assert!(
        (g[0] + g[5] - frame_ms).abs() <= 0.2,
        "GPU and other are not the frame: {gpu}"
    );
    drop(x);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The interactive level keeps within `--frame-budget`: where its frames take longer, its
/// planes move apart (up to 16 voxels from the 6 it starts at), while the budget leaves the
/// other levels alone and 0 keeps the interactive planes where they start.
#[test]
fn interactive_frames_move_their_planes_apart_to_keep_within_the_frame_budget() {
    let x = Xvfb::start();
    let run = |budget: &str| -> (Vec<u32>, Vec<u32>) {
        let out = caustica(
            &[
                "view",
                "--scene",
                "ball-lens",
                "--resolution",
                "32",
                "--size",
                "160x120",
                "--no-panel",
                "--exit-after-idle",
                "--frame-log",
                "--orbit-frames",
                "6",
                "--frame-budget",
                budget,
            ],
            Some(&x.display),
            Duration::from_secs(120),
        );
        let stderr = assert_ok(&out, "caustica view");
        // `frame: LEVEL WxH N planes T ms`
        let planes = |level: &str| -> Vec<u32> {
            stderr
                .lines()
                .filter(|l| l.starts_with(&format!("frame: {level} ")))
                .map(|l| {
                    let w: Vec<&str> = l.split_whitespace().collect();
                    let at = w.iter().position(|&t| t == "planes").expect("N planes");
                    w[at - 1].parse().expect("a plane count")
                })
                .collect()
        };
        (planes("interactive"), planes("full"))
    };
    let (fixed, fixed_full) = run("0");
    let (paced, paced_full) = run("0.001");
    assert!(
        fixed.len() >= 6 && paced.len() >= 6,
        "interactive frames: {fixed:?}, {paced:?}"
    );
    // Without a budget the orbit alone moves the count (the volume's depth along the view).
    let first = fixed[0] as f64;
    assert!(
        fixed.iter().all(|&n| (n as f64 - first).abs() <= 0.15 * first),
        "planes moved without a budget: {fixed:?}"
    );
    // No frame fits 1 µs: after the first frames (one to copy the textures, two to go by)
    // the planes are as far apart as they go, 6/16 of the count (the orbit's share aside).
    assert_eq!(paced[0], fixed[0], "both start 6 voxels apart");
    let last = *paced.last().unwrap() as f64;
    assert!(
        last <= 0.5 * first && last >= 0.25 * first,
        "planes with a budget no frame fits: {paced:?} (without one {fixed:?})"
    );
    assert_eq!(
        paced_full, fixed_full,
        "the full frame is the scene's own quality either way"
    );
}
