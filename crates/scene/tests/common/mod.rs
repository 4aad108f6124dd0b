//! Helpers shared by the integration tests.

#![allow(dead_code)]

use std::path::PathBuf;

/// `$TILEGRAPH_TEST_DATA`, or `<repo>/../shared/data`. `None` (with a message naming the path)
/// when it does not exist, so a fresh clone without the data stays green.
pub fn test_data(sub: &str) -> Option<PathBuf> {
    let base = std::env::var_os("TILEGRAPH_TEST_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data"))
        });
    let dir = base.join(sub);
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "SKIPPED: test data directory {} not found (set TILEGRAPH_TEST_DATA)",
            dir.display()
        );
        None
    }
}

/// Runs `f`, turning a panic into an `Err` with its message, so a test can report which input
/// panicked instead of stopping at the first.
pub fn no_panic<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|e| {
        e.downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "non-string panic".into())
    })
}
