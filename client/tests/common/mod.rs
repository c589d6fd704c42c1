//! Helpers the CLI's integration tests share.

use std::path::{Path, PathBuf};

/// The repository root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// An empty temporary directory named after the test file (`kind`), the test and this process.
pub fn scratch(kind: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tessera-{kind}-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Every layer of an EXR, as bits (NaN-safe, -0 distinct from 0).
pub fn pixels(path: &Path) -> Vec<(String, Vec<u32>)> {
    let image = tessera::output::read_exr(path).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
    image.layers.into_iter().map(|(name, (_, data))| (name, data.into_iter().map(f32::to_bits).collect())).collect()
}
