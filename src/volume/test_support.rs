//! Scratch directories for the volume readers' tests, removed when dropped.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

pub struct ScratchDir {
    root: PathBuf,
}

impl ScratchDir {
    pub fn new(tag: &str) -> ScratchDir {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let unique = NEXT.fetch_add(1, Ordering::Relaxed);
        let root = std::env::temp_dir().join(format!("caustica-{tag}-{}-{unique}", std::process::id()));
        std::fs::create_dir_all(&root).expect("create scratch directory");
        ScratchDir { root }
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.root.join(name)
    }

    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.path(name);
        std::fs::write(&path, bytes).expect("write scratch file");
        path
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        // Leftover files in the temp directory are harmless, so a failed cleanup is ignored.
        let _ = std::fs::remove_dir_all(&self.root);
    }
}
