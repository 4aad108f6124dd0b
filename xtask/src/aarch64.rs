//! The phone's architecture, run for real: the pure crates' tests (the software rasterizer's
//! NEON path above all, compared with its scalar reference) built for
//! `aarch64-unknown-linux-gnu` and run under `qemu-aarch64` user-mode emulation.

use crate::{cargo, ensure_rust_target, run};

const TARGET: &str = "aarch64-unknown-linux-gnu";

/// Where Debian's `libc6-dev-arm64-cross` puts the target's C library (qemu's `-L` prefix).
pub const SYSROOT: &str = "/usr/aarch64-linux-gnu";

/// The crates whose tests run on aarch64: the ones with SIMD code and their dependencies.
const CRATES: [&str; 2] = ["tilegraph-types", "tilegraph-cull"];

/// Adds the Rust target when missing, then runs the crates' library and integration tests
/// (not their benchmarks) under qemu.
pub fn test() -> Result<(), String> {
    ensure_rust_target(TARGET)?;
    let mut c = cargo();
    c.args(["test", "--target", TARGET, "--lib", "--tests"]);
    for krate in CRATES {
        c.args(["-p", krate]);
    }
    c.env(
        "CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER",
        "aarch64-linux-gnu-gcc",
    )
    .env(
        "CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER",
        format!("qemu-aarch64 -L {SYSROOT}"),
    );
    run(
        &format!(
            "cargo test --target {TARGET} (under qemu-aarch64) -p {}",
            CRATES.join(" -p ")
        ),
        &mut c,
    )
}
