//! Shared by the fuzz targets: the loaders read files, so each input is written to a file of
//! the given name in a directory private to this process, then loaded through the same
//! `caustica::volume::open` a user's file goes through.

use std::path::PathBuf;

pub fn input_file(name: &str, data: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("caustica-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("fuzz scratch dir");
    let path = dir.join(name);
    std::fs::write(&path, data).expect("write fuzz input");
    path
}

/// Loads `data` as a volume file named `name`; a successful load must satisfy the Volume
/// invariants (the loaders return errors, never panic, for anything else), and so must its
/// reorientation for display, which keeps every sample.
#[allow(dead_code)]
pub fn load(name: &str, data: &[u8]) {
    let path = input_file(name, data);
    if let Ok(loaded) = caustica::volume::open(&path) {
        check(&loaded);
        let before = loaded.volume.data.iter().map(|x| f64::from(*x)).sum::<f64>();
        let shown = loaded.into_display();
        check(&shown);
        let after = shown.volume.data.iter().map(|x| f64::from(*x)).sum::<f64>();
        // A permutation of the same samples: the same sum up to the order of additions.
        assert!((before - after).abs() <= 1e-6 * before.abs().max(1.0) * shown.volume.data.len() as f64);
        if let Some(frame) = &shown.meta.patient {
            // Reordered onto the display axes without mirroring: the residual is a rotation.
            let r = frame.display_from_world();
            assert!((r.determinant() - 1.0).abs() < 1e-3, "{r}");
        }
    }
}

fn check(loaded: &caustica::volume::Loaded) {
    let v = &loaded.volume;
    assert_eq!(v.data.len(), v.dims.iter().product::<usize>());
    assert!(v.data.iter().all(|x| x.is_finite()));
    assert!(v.spacing.iter().all(|s| s.is_finite() && *s > 0.0));
    let _ = loaded.default_window();
}
