//! Missing drivers and unknown devices give clear errors and exit code 3, not a panic.

use std::process::Command;

fn caustica(args: &[&str], env: &[(&str, &str)]) -> (i32, String) {
    let out_dir = std::env::temp_dir().join(format!("caustica-devices-{}", std::process::id()));
    std::fs::create_dir_all(&out_dir).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_caustica"));
    cmd.args(args).current_dir(&out_dir);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "{stderr}");
    (out.status.code().unwrap_or(-1), stderr)
}

/// A tiny render of a built-in scene, with `extra` arguments.
fn render_args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "render",
        "--scene",
        "ball-lens",
        "--resolution",
        "16",
        "--size",
        "8x8",
        "-o",
        "x.png",
    ];
    args.extend_from_slice(extra);
    args
}

#[test]
fn no_driver_is_a_clear_error() {
    let args = render_args(&[]);
    // Point the loader at a driver list with nothing in it.
    let env = [
        ("VK_ICD_FILENAMES", "/nonexistent/icd.json"),
        ("VK_DRIVER_FILES", "/nonexistent/icd.json"),
    ];
    let (code, stderr) = caustica(&args, &env);
    assert_eq!(code, 3, "{stderr}");
    assert!(
        stderr.contains("Vulkan") && stderr.contains("mesa-vulkan-drivers"),
        "{stderr}"
    );
}

#[test]
fn unknown_device_lists_the_available_ones() {
    let args = render_args(&["--device", "no-such-gpu"]);
    let (code, stderr) = caustica(&args, &[]);
    assert_eq!(code, 3, "{stderr}");
    assert!(
        stderr.contains("no-such-gpu") && stderr.contains("available"),
        "{stderr}"
    );
}
