//! What the CLI's integration tests share.

use std::process::Command;

/// Runs `tilegraph ARGS` with the validation layers required and no profile forced by the
/// environment: (succeeded, stdout, stderr).
pub fn tilegraph<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tilegraph"))
        .args(args)
        .env_remove("TILEGRAPH_PROFILE")
        .env("TILEGRAPH_VALIDATION", "required")
        .output()
        .expect("run tilegraph");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}
