//! The third-party scenes tests and tools read (`$TILEGRAPH_TEST_DATA`, by default
//! `../shared/data` beside the repository; never copied into it), and what a test does when
//! they are absent: it skips, and says so where it will be seen. Each skip is printed to stderr
//! and, when `$TILEGRAPH_SKIP_LOG` names a file, appended to it — `cargo xtask test` sets it and
//! prints every skip of the run at the end. With `TILEGRAPH_REQUIRE_DATA=1` a missing file fails
//! the test instead (a machine that must have the data).

use std::io::Write;
use std::path::PathBuf;

/// The data directory.
pub fn dir() -> PathBuf {
    std::env::var_os("TILEGRAPH_TEST_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data"))
        })
}

/// `relative` (a file or a directory) under the data directory, if it is there; otherwise the
/// skip of `what` is recorded ([`skipped`]) and `None` returned.
///
/// # Panics
/// With `TILEGRAPH_REQUIRE_DATA=1`, when it is missing: the run asked for the data.
pub fn find(relative: &str, what: &str) -> Option<PathBuf> {
    let p = dir().join(relative);
    if p.exists() {
        return Some(p);
    }
    let reason = format!("{} not found", p.display());
    if std::env::var_os("TILEGRAPH_REQUIRE_DATA").is_some_and(|v| v == "1") {
        panic!("{what}: {reason}, and TILEGRAPH_REQUIRE_DATA=1");
    }
    skipped(what, &reason);
    None
}

/// Records that `what` did not run, and why: on stderr, and in `$TILEGRAPH_SKIP_LOG` if set.
pub fn skipped(what: &str, why: &str) {
    let line = format!("skipped {what}: {why}");
    eprintln!("{line}");
    if let Some(log) = std::env::var_os("TILEGRAPH_SKIP_LOG") {
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .and_then(|mut f| writeln!(f, "{line}"));
        if let Err(e) = written {
            eprintln!("(could not append to TILEGRAPH_SKIP_LOG: {e})");
        }
    }
}
