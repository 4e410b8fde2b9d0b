//! The page's files, embedded in the binary so that the studio needs nothing beyond it: the
//! page (`crates/cli/studio/`) and the vendored three.js with its licence
//! (`crates/cli/studio/vendor/`, made by `vendor.sh`). Served by name from a fixed table: no
//! request reaches the file system.

/// One embedded file.
pub(crate) struct Asset {
    /// The name under `/assets/` (`index.html` is served at `/`).
    pub name: &'static str,
    /// Its `Content-Type`.
    pub content_type: &'static str,
    /// Its bytes.
    pub bytes: &'static [u8],
}

macro_rules! asset {
    ($name:literal, $path:literal, $type:literal) => {
        Asset {
            name: $name,
            content_type: $type,
            bytes: include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/studio/", $path)),
        }
    };
}

/// Every file the page loads.
static ASSETS: &[Asset] = &[
    asset!("index.html", "index.html", "text/html; charset=utf-8"),
    asset!("studio.css", "studio.css", "text/css; charset=utf-8"),
    asset!("studio.js", "studio.js", "text/javascript; charset=utf-8"),
    asset!(
        "three.module.js",
        "vendor/three/three.module.js",
        "text/javascript; charset=utf-8"
    ),
    asset!(
        "three.core.js",
        "vendor/three/three.core.js",
        "text/javascript; charset=utf-8"
    ),
    asset!(
        "OrbitControls.js",
        "vendor/three/OrbitControls.js",
        "text/javascript; charset=utf-8"
    ),
    asset!(
        "LICENSE-three.txt",
        "vendor/three/LICENSE",
        "text/plain; charset=utf-8"
    ),
];

/// The embedded file called `name`, if any.
pub(crate) fn find(name: &str) -> Option<&'static Asset> {
    ASSETS.iter().find(|a| a.name == name)
}
