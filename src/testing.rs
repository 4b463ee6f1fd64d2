//! What the tests share (unit tests, and integration tests through `#[path]`).
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A fresh directory under the system's temp dir for one test, `mufe_NAME_PID`, removed
/// when dropped (when the test fails too): test runs leave nothing behind. `name` must
/// differ between tests that run at once.
pub struct TestDir(PathBuf);

impl TestDir {
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("mufe_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        Self(dir)
    }
}

/// The directory's path: `dir.join(…)`, and `&dir` where a `&Path` is wanted.
impl std::ops::Deref for TestDir {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TestDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
