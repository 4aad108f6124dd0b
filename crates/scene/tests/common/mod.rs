//! Helpers shared by the integration tests.

#![allow(dead_code)]

use std::path::PathBuf;

/// `sub` under the test data (`tilegraph_scene::test_data`): `None`, recorded as a skip, when it
/// is absent, so a fresh clone without the data stays green and says what it did not run.
pub fn test_data(sub: &str) -> Option<PathBuf> {
    tilegraph_scene::test_data::find(sub, &format!("the tests of {sub}"))
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
