//! Where the real scans are: `$ZEROSET_DATA` if set, else the repository's `data/` folder
//! (see its README for provenance and terms), so the examples run on a fresh clone.

use std::path::{Path, PathBuf};

/// The data folder.
pub fn data_dir() -> PathBuf {
    std::env::var_os("ZEROSET_DATA").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("data"),
        PathBuf::from,
    )
}
