//! The scratch folder of a fuzz target's process, for the inputs that loaders read from disk: in memory where
//! `/dev/shm` exists, else in the temporary folder. Shared by the targets through `#[path]`.

use std::path::PathBuf;
use std::sync::OnceLock;

/// This process's own folder, made on first use.
pub fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let shm = std::path::Path::new("/dev/shm");
        let base = if shm.is_dir() {
            shm.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("nimbus_fuzz_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}
