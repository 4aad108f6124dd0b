//! `cargo xtask <demo|test|shaders|bench|deps>`: the project's own commands.
//!
//! Both `demo` and `test` first make sure the system pieces are present — the Vulkan loader,
//! Mesa's lavapipe, the Khronos validation layer, glslc and spirv-tools — installing what is
//! missing with apt-get when running as root (or with password-less sudo), or stopping with the
//! exact command to run.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

mod aarch64;
mod structure;

/// A system piece, how to recognise it, and the Debian/Ubuntu package that provides it.
struct Requirement {
    what: &'static str,
    package: &'static str,
    present: fn() -> bool,
}

const REQUIREMENTS: &[Requirement] = &[
    Requirement {
        what: "Vulkan loader (libvulkan.so.1)",
        package: "libvulkan1",
        present: has_vulkan_loader,
    },
    Requirement {
        what: "Mesa lavapipe ICD",
        package: "mesa-vulkan-drivers",
        present: has_lavapipe,
    },
    Requirement {
        what: "Khronos validation layer",
        package: "vulkan-validationlayers",
        present: has_validation_layer,
    },
    Requirement {
        what: "Vulkan C headers (the C ABI's tests compile C programs against them)",
        package: "libvulkan-dev",
        present: || Path::new("/usr/include/vulkan/vulkan.h").exists(),
    },
    Requirement {
        what: "C compiler (cc)",
        package: "gcc",
        present: || on_path("cc"),
    },
    Requirement {
        what: "glslc",
        package: "glslc",
        present: || on_path("glslc"),
    },
    Requirement {
        what: "spirv-val",
        package: "spirv-tools",
        present: || on_path("spirv-val"),
    },
    Requirement {
        what: "Graphviz dot (a test renders the plan's DOT)",
        package: "graphviz",
        present: || on_path("dot"),
    },
    Requirement {
        what: "Chromium (a test opens the bench's plots and HTML report headless)",
        package: "chromium",
        present: || on_path("chromium"),
    },
    Requirement {
        what: "qemu-aarch64 (the pure crates' tests run for aarch64 under it)",
        package: "qemu-user",
        present: || on_path("qemu-aarch64"),
    },
    Requirement {
        what: "aarch64 cross linker (aarch64-linux-gnu-gcc)",
        package: "gcc-aarch64-linux-gnu",
        present: || on_path("aarch64-linux-gnu-gcc"),
    },
    Requirement {
        what: "aarch64 C library (the cross linker's and qemu's sysroot)",
        package: "libc6-dev-arm64-cross",
        present: || Path::new(aarch64::SYSROOT).join("lib/crt1.o").exists(),
    },
];

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (cmd, rest) = match args.split_first() {
        Some((c, r)) => (c.as_str(), r),
        None => ("help", &[][..]),
    };
    let result = match cmd {
        "demo" => ensure_system().and_then(|_| demo(rest)),
        "test" => ensure_system().and_then(|_| test(rest)),
        "shaders" => ensure_system().and_then(|_| {
            if rest.iter().any(|a| a == "--check") {
                check_shaders(&root())
            } else {
                compile_shaders(&root())
            }
        }),
        "bench" => ensure_system().and_then(|_| bench(rest)),
        "bless" => ensure_system().and_then(|_| {
            run(
                "regenerate golden images (tests/golden)",
                cargo()
                    .args(["test", "-p", "tilegraph-e2e", "--test", "passes", "golden"])
                    .env("TILEGRAPH_BLESS", "1"),
            )
        }),
        "deps" => ensure_system(),
        "structure" => check_structure(rest.first().map(PathBuf::from)),
        _ => {
            eprintln!(
                "usage: cargo xtask <command>\n\
                 \n  demo [ARGS]     render the demo frame (device, profile, PNG, per-pass GPU times)\
                 \n  test            fmt --check, clippy -D warnings, shader check, every test\
                 \n  shaders [--check]  compile shaders/*.{{vert,frag,comp}} to shaders/spv (or check them)\
                 \n  bench           criterion benchmarks\
                 \n  structure [DIR] file sizes, too_many_arguments allowances, import cycles\
                 \n  deps            install/check the system pieces (Vulkan, lavapipe, validation, glslc)"
            );
            return if cmd == "help" {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            };
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask {cmd}: {e}");
            ExitCode::FAILURE
        }
    }
}

fn root() -> PathBuf {
    // xtask/ is one level below the workspace root.
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

fn cargo() -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.current_dir(root());
    c
}

fn run(step: &str, cmd: &mut Command) -> Result<(), String> {
    println!("==> {step}");
    let status = cmd
        .status()
        .map_err(|e| format!("{step}: cannot start: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{step} failed ({status})"))
    }
}

/// Runs a `cargo test` that must run at least `at_least` tests: its output is echoed, and
/// the tests it ran are counted from libtest's summaries (a filter that matches nothing after a
/// rename would otherwise run zero tests and pass).
fn run_tests_counted(step: &str, cmd: &mut Command, at_least: usize) -> Result<(), String> {
    println!("==> {step}");
    let out = cmd
        .stderr(std::process::Stdio::inherit())
        .output()
        .map_err(|e| format!("{step}: cannot start: {e}"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    print!("{text}");
    if !out.status.success() {
        return Err(format!("{step} failed ({})", out.status));
    }
    let passed = tests_passed(&text);
    if passed < at_least {
        return Err(format!(
            "{step} ran {passed} tests, fewer than the {at_least} it exists for (a renamed test?)"
        ));
    }
    Ok(())
}

/// The tests libtest's summaries in `output` say passed.
fn tests_passed(output: &str) -> usize {
    output
        .lines()
        .filter_map(|l| l.strip_prefix("test result: ok. "))
        .filter_map(|l| l.split(' ').next()?.parse::<usize>().ok())
        .sum()
}

fn demo(rest: &[String]) -> Result<(), String> {
    let mut c = cargo();
    c.args([
        "run",
        "--release",
        "--quiet",
        "-p",
        "tilegraph-cli",
        "--",
        "demo",
    ])
    .args(rest);
    run("tilegraph demo", &mut c)
}

/// rustfmt and clippy, which `test` runs: added with rustup when the toolchain lacks them (a
/// minimal rustup profile has neither).
fn ensure_rust_components() -> Result<(), String> {
    for (component, subcommand) in [("rustfmt", "fmt"), ("clippy", "clippy")] {
        let present = cargo()
            .args([subcommand, "--version"])
            .output()
            .is_ok_and(|o| o.status.success());
        if present {
            continue;
        }
        if !on_path("rustup") {
            return Err(format!(
                "`cargo {subcommand}` is missing: install the {component} component of your Rust toolchain"
            ));
        }
        run(
            &format!("rustup component add {component}"),
            Command::new("rustup").args(["component", "add", component]),
        )?;
    }
    Ok(())
}

fn test(rest: &[String]) -> Result<(), String> {
    // A leaked TILEGRAPH_BLESS would rewrite the golden images and the header instead of
    // comparing them, and every test would pass.
    if std::env::var_os("TILEGRAPH_BLESS").is_some() {
        return Err(
            "TILEGRAPH_BLESS is set: `cargo xtask test` compares golden images and the C header, it never rewrites them (unset it; `cargo xtask bless` regenerates the goldens)"
                .into(),
        );
    }
    ensure_rust_components()?;
    run(
        "cargo fmt --all --check",
        cargo().args(["fmt", "--all", "--", "--check"]),
    )?;
    run(
        "cargo clippy --workspace --all-targets -- -D warnings",
        cargo().args([
            "clippy",
            "--workspace",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ]),
    )?;
    check_structure(None)?;
    android()?;
    // The C programs of tests/capi link the static library: built first, with the profile
    // the tests use (so it shares their compiled dependencies).
    run(
        "cargo build --profile test -p tilegraph-capi (libtilegraph.a for the C tests)",
        cargo().args(["build", "--profile", "test", "-p", "tilegraph-capi"]),
    )?;
    // Every skip of the run (test data absent) is appended here and listed at the end.
    let skips = root().join("target").join("test-skips.log");
    let _ = std::fs::remove_file(&skips);
    let require_data = require_data();
    // The shader check (staleness + spirv-val) is xtask's own unit test, run by cargo test below.
    // Every GPU test requires the validation layer (with synchronization validation).
    let tests = run(
        "cargo test --workspace",
        cargo()
            .args(["test", "--workspace"])
            .args(rest)
            .env("TILEGRAPH_VALIDATION", "required")
            .env("TILEGRAPH_SKIP_LOG", &skips)
            .env("TILEGRAPH_REQUIRE_DATA", require_data),
    )
    .and_then(|()| best_practices_per_vendor())
    .and_then(|()| aarch64::test());
    report_skips(&skips);
    tests
}

/// Whether the tests must find every third-party file they read (`TILEGRAPH_REQUIRE_DATA`):
/// as the caller set it, else "1" where the data directory is there — a file missing from it
/// (a scene renamed or dropped) then fails its test instead of skipping it — and "0" where the
/// whole directory is absent (a machine without `../shared`: the tests that need it skip, and
/// the run lists them at its end).
fn require_data() -> String {
    if let Ok(v) = std::env::var("TILEGRAPH_REQUIRE_DATA") {
        return v;
    }
    let dir = std::env::var_os("TILEGRAPH_TEST_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("..").join("shared").join("data"));
    let present = dir.is_dir();
    println!(
        "==> test data: {} {}",
        dir.display(),
        if present {
            "present: a file missing from it fails its test"
        } else {
            "absent: the tests that need it skip (listed at the end)"
        }
    );
    String::from(if present { "1" } else { "0" })
}

/// Appends a skip to `$TILEGRAPH_SKIP_LOG` (the format `tilegraph_scene::test_data::skipped`
/// writes), for the run's summary.
fn log_skip(what: &str, why: &str) {
    let line = format!("skipped {what}: {why}");
    eprintln!("{line}");
    if let Some(log) = std::env::var_os("TILEGRAPH_SKIP_LOG") {
        use std::io::Write as _;
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

/// Prints what the run did not run (`tilegraph_scene::test_data` records each skip), or that
/// nothing was skipped.
fn report_skips(log: &Path) {
    let text = std::fs::read_to_string(log).unwrap_or_default();
    let mut lines: Vec<&str> = text.lines().collect();
    lines.sort_unstable();
    lines.dedup();
    if lines.is_empty() {
        println!("==> skips: none (every test ran in full)");
    } else {
        println!(
            "==> skips: {} (set TILEGRAPH_TEST_DATA, or TILEGRAPH_REQUIRE_DATA=1 to fail on them)",
            lines.len()
        );
        for l in lines {
            println!("    {l}");
        }
    }
}

/// The vendor best-practices checks, each in a process of its own: on layer 1.3.239 they are
/// switched on for a whole process by a `vk_layer_settings.txt` (`VK_LAYER_SETTINGS_PATH`).
/// Every shipped technique is rendered under the vendor's profile (tests/e2e/profiles.rs); the
/// reviewed exceptions are docs/PROFILES.md's "Silenced best-practices messages".
fn best_practices_per_vendor() -> Result<(), String> {
    for (vendor, profile) in [
        ("ARM", "mali-valhall"),
        ("IMG", "powervr-b"),
        ("NVIDIA", "desktop-nvidia"),
    ] {
        let dir = root()
            .join("target")
            .join("best-practices")
            .join(vendor.to_ascii_lowercase());
        let settings = dir.join("vk_layer_settings.txt");
        std::fs::create_dir_all(&dir)
            .and_then(|()| {
                std::fs::write(
                    &settings,
                    format!(
                        "khronos_validation.enables = VK_VALIDATION_FEATURE_ENABLE_BEST_PRACTICES_EXT,\
                         VALIDATION_CHECK_ENABLE_VENDOR_SPECIFIC_{vendor},\
                         VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT\n"
                    ),
                )
            })
            .map_err(|e| format!("writing {}: {e}", settings.display()))?;
        run_tests_counted(
            &format!("best practices with the {vendor} checks, profile {profile}"),
            cargo()
                .args(["test", "-p", "tilegraph-e2e", "--test", "profiles"])
                .args(["--", "best_practices"])
                .env("VK_LAYER_SETTINGS_PATH", &settings)
                .env("TILEGRAPH_BEST_PRACTICES_PROFILE", profile)
                .env("TILEGRAPH_VALIDATION", "required"),
            2,
        )?;
    }
    Ok(())
}

/// The Android target: the sample checked (with clippy) and the C ABI built as a static
/// library for aarch64-linux-android. Neither links, so no NDK is needed (docs/ANDROID.md).
fn android() -> Result<(), String> {
    const TARGET: &str = "aarch64-linux-android";
    ensure_rust_target(TARGET)?;
    run(
        &format!("cargo clippy --target {TARGET} -p tilegraph-android"),
        cargo().args([
            "clippy",
            "--target",
            TARGET,
            "-p",
            "tilegraph-android",
            "--",
            "-D",
            "warnings",
        ]),
    )?;
    run(
        &format!("tilegraph-capi as a staticlib for {TARGET}"),
        cargo().args([
            "rustc",
            "--target",
            TARGET,
            "-p",
            "tilegraph-capi",
            "--crate-type",
            "staticlib",
        ]),
    )
}

/// Adds the Rust standard library for `target` with rustup when the toolchain lacks it.
fn ensure_rust_target(target: &str) -> Result<(), String> {
    let installed = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .map(|o| {
            String::from_utf8_lossy(&o.stdout)
                .lines()
                .any(|l| l.trim() == target)
        })
        .map_err(|e| format!("rustup (needed for the {target} target): {e}"))?;
    if installed {
        return Ok(());
    }
    run(
        &format!("rustup target add {target}"),
        Command::new("rustup").args(["target", "add", target]),
    )
}

/// The structure rules of `structure.rs`, over the whole workspace (or the one at `dir`).
fn check_structure(dir: Option<PathBuf>) -> Result<(), String> {
    println!("==> structure rules (file sizes, allowances, import cycles)");
    let problems = structure::check(&dir.unwrap_or_else(root))?;
    if problems.is_empty() {
        Ok(())
    } else {
        Err(problems.join("\n"))
    }
}

fn bench(rest: &[String]) -> Result<(), String> {
    run(
        "cargo bench --workspace",
        cargo().args(["bench", "--workspace"]).args(rest),
    )
}

// ---------------------------------------------------------------------------------------------
// System pieces

fn ensure_system() -> Result<(), String> {
    let missing: Vec<&Requirement> = REQUIREMENTS.iter().filter(|r| !(r.present)()).collect();
    if missing.is_empty() {
        return Ok(());
    }
    let packages: Vec<&str> = missing.iter().map(|r| r.package).collect();
    for r in &missing {
        println!("missing: {} (package {})", r.what, r.package);
    }
    let install = format!(
        "apt-get install -y --no-install-recommends {}",
        packages.join(" ")
    );
    // As root, apt-get directly; otherwise through sudo when it needs no password (a CI
    // runner's usual setup).
    let sudo = !is_root()
        && on_path("sudo")
        && Command::new("sudo")
            .args(["-n", "true"])
            .output()
            .is_ok_and(|o| o.status.success());
    if (is_root() || sudo) && on_path("apt-get") {
        println!("==> installing {} with apt-get", packages.join(" "));
        let apt = || {
            let mut c = if sudo {
                let mut c = Command::new("sudo");
                c.args(["-n", "env", "DEBIAN_FRONTEND=noninteractive", "apt-get"]);
                c
            } else {
                let mut c = Command::new("apt-get");
                c.env("DEBIAN_FRONTEND", "noninteractive");
                c
            };
            c.arg("-q");
            c
        };
        run("apt-get update", apt().arg("update"))?;
        run(
            &install,
            apt()
                .args(["install", "-y", "--no-install-recommends"])
                .args(&packages),
        )?;
        let still: Vec<&str> = REQUIREMENTS
            .iter()
            .filter(|r| !(r.present)())
            .map(|r| r.what)
            .collect();
        if still.is_empty() {
            Ok(())
        } else {
            Err(format!("still missing after apt-get: {}", still.join(", ")))
        }
    } else {
        Err(format!(
            "missing system packages; run:\n    sudo apt-get update && sudo {install}\n(then run the command again)"
        ))
    }
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false)
}

fn on_path(tool: &str) -> bool {
    std::env::var_os("PATH")
        .map(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()))
        .unwrap_or(false)
}

fn any_exists(paths: &[&str]) -> bool {
    paths.iter().any(|p| Path::new(p).exists())
}

fn dir_has(dirs: &[&str], pred: impl Fn(&str) -> bool) -> bool {
    dirs.iter().any(|d| {
        std::fs::read_dir(d)
            .map(|rd| {
                rd.filter_map(Result::ok)
                    .any(|e| pred(&e.file_name().to_string_lossy()))
            })
            .unwrap_or(false)
    })
}

fn has_vulkan_loader() -> bool {
    const LOADER: &str = "libvulkan.so.1";
    // Debian/Ubuntu multiarch directories (x86_64-linux-gnu, aarch64-linux-gnu, riscv64-...).
    let multiarch = std::fs::read_dir("/usr/lib")
        .map(|rd| {
            rd.filter_map(Result::ok).any(|e| {
                e.file_name().to_string_lossy().contains("-linux-")
                    && e.path().join(LOADER).exists()
            })
        })
        .unwrap_or(false);
    multiarch
        || any_exists(&[
            "/usr/lib64/libvulkan.so.1",
            "/usr/lib/libvulkan.so.1",
            "/usr/local/lib/libvulkan.so.1",
        ])
}

fn has_lavapipe() -> bool {
    dir_has(
        &[
            "/usr/share/vulkan/icd.d",
            "/etc/vulkan/icd.d",
            "/usr/local/share/vulkan/icd.d",
        ],
        |n| n.starts_with("lvp_icd"),
    )
}

fn has_validation_layer() -> bool {
    dir_has(
        &[
            "/usr/share/vulkan/explicit_layer.d",
            "/etc/vulkan/explicit_layer.d",
            "/usr/local/share/vulkan/explicit_layer.d",
        ],
        |n| n.eq_ignore_ascii_case("VkLayer_khronos_validation.json"),
    )
}

// ---------------------------------------------------------------------------------------------
// Shaders: GLSL in shaders/, SPIR-V committed in shaders/spv/.

const STAGES: &[&str] = &["vert", "frag", "comp", "geom", "tesc", "tese"];

/// Where `cargo xtask shaders` records the compiler that made the committed modules.
const GLSLC_VERSION_FILE: &str = "shaders/spv/GLSLC_VERSION";

/// `glslc --version` (shaderc, glslang and spirv-tools versions), or `None` without glslc.
fn glslc_version() -> Option<String> {
    let out = Command::new("glslc").arg("--version").output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// The one glslc command line of the project (also what the staleness check reproduces).
fn glslc(src: &Path, out: &Path, root: &Path) -> Command {
    let mut c = Command::new("glslc");
    c.arg("--target-env=vulkan1.2")
        .arg("-O")
        .arg("-I")
        .arg(root.join("shaders/common"))
        .arg(src)
        .arg("-o")
        .arg(out);
    c
}

fn shader_sources(root: &Path) -> Result<Vec<PathBuf>, String> {
    let dir = root.join("shaders");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| format!("reading {}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|x| x.to_str())
                .is_some_and(|x| STAGES.contains(&x))
        })
        .collect();
    v.sort();
    Ok(v)
}

fn spv_path(root: &Path, src: &Path) -> PathBuf {
    let name = src
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    root.join("shaders/spv").join(format!("{name}.spv"))
}

fn spirv_val(spv: &Path) -> Result<(), String> {
    let out = Command::new("spirv-val")
        .args(["--target-env", "vulkan1.2"])
        .arg(spv)
        .output()
        .map_err(|e| format!("spirv-val: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "spirv-val {}: {}",
            spv.display(),
            String::from_utf8_lossy(&out.stderr)
        ))
    }
}

fn compile_shaders(root: &Path) -> Result<(), String> {
    let version = glslc_version().ok_or("glslc --version failed")?;
    let record = root.join(GLSLC_VERSION_FILE);
    std::fs::write(&record, format!("{version}\n"))
        .map_err(|e| format!("{}: {e}", record.display()))?;
    for src in shader_sources(root)? {
        let out = spv_path(root, &src);
        run(
            &format!("glslc {}", src.display()),
            &mut glslc(&src, &out, root),
        )?;
        spirv_val(&out)?;
    }
    println!("shaders compiled and validated");
    Ok(())
}

/// Recompiles every shader to a temporary file and compares it with the committed module;
/// runs spirv-val on every committed module; flags modules without a source.
fn check_shaders(root: &Path) -> Result<(), String> {
    println!("==> shader check (staleness + spirv-val)");
    let tmp = std::env::temp_dir().join(format!("tilegraph-shader-check-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    let mut problems = Vec::new();
    let sources = shader_sources(root)?;
    // Byte-for-byte staleness only with the compiler that made the modules: another shaderc or
    // spirv-opt release may encode the same shader differently. With another one, every source
    // must still compile and every committed module must still validate.
    let recorded = std::fs::read_to_string(root.join(GLSLC_VERSION_FILE))
        .map(|v| v.trim().to_string())
        .unwrap_or_default();
    let current = glslc_version().unwrap_or_default();
    let exact = recorded == current;
    if !exact {
        println!(
            "note: committed modules were made by\n{recorded}\nthis machine has\n{current}\nstaleness is not compared byte for byte"
        );
        // Not silent: the run's summary lists it with the other skips.
        log_skip(
            "byte-for-byte shader staleness",
            &format!("this glslc is not the one that made the committed modules ({recorded})"),
        );
    }
    for src in &sources {
        let committed = spv_path(root, src);
        let fresh = tmp.join(committed.file_name().unwrap_or_default());
        let out = glslc(src, &fresh, root)
            .output()
            .map_err(|e| format!("glslc: {e}"))?;
        if !out.status.success() {
            problems.push(format!(
                "{} does not compile: {}",
                src.display(),
                String::from_utf8_lossy(&out.stderr)
            ));
            continue;
        }
        match (std::fs::read(&committed), std::fs::read(&fresh)) {
            (Ok(a), Ok(b)) if a == b || !exact => {}
            (Ok(_), Ok(_)) => problems.push(format!(
                "{} is stale against {} (run `cargo xtask shaders` and commit)",
                committed.display(),
                src.display()
            )),
            (Err(_), _) => problems.push(format!(
                "{} has no committed module {}",
                src.display(),
                committed.display()
            )),
            (_, Err(e)) => problems.push(format!("reading fresh module: {e}")),
        }
        if let Err(e) = spirv_val(&committed) {
            problems.push(e);
        }
    }
    let spv_dir = root.join("shaders/spv");
    if let Ok(rd) = std::fs::read_dir(&spv_dir) {
        for e in rd.filter_map(Result::ok) {
            let name = e.file_name().to_string_lossy().into_owned();
            if let Some(stem) = name.strip_suffix(".spv") {
                if !root.join("shaders").join(stem).exists() {
                    problems.push(format!("shaders/spv/{name} has no source shaders/{stem}"));
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
    if problems.is_empty() {
        println!("{} shader modules up to date and valid", sources.len());
        Ok(())
    } else {
        Err(problems.join("\n"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passed_tests_are_counted_from_libtests_summaries() {
        let out = "running 2 tests\ntest a ... ok\ntest b ... ok\n\ntest result: ok. 2 passed; 0 failed; 0 ignored; 0 measured; 3 filtered out; finished in 1.0s\n\nrunning 0 tests\n\ntest result: ok. 0 passed; 0 failed; 0 ignored; 0 measured; 0 filtered out; finished in 0.0s\n";
        assert_eq!(tests_passed(out), 2);
        assert_eq!(tests_passed("running 0 tests\n"), 0);
    }

    /// The committed SPIR-V matches its GLSL and passes spirv-val. Without the tools (which
    /// `cargo xtask test` installs) it fails, unless `TILEGRAPH_ALLOW_MISSING_TOOLS=1` says the
    /// machine is known to lack them (never set in CI).
    #[test]
    fn committed_shaders_are_fresh_and_valid() {
        if !on_path("glslc") || !on_path("spirv-val") {
            let allowed =
                std::env::var_os("TILEGRAPH_ALLOW_MISSING_TOOLS").is_some_and(|v| v == "1");
            assert!(
                allowed,
                "glslc/spirv-val not on PATH: `cargo xtask deps` installs them \
                 (TILEGRAPH_ALLOW_MISSING_TOOLS=1 skips this check on a machine without them)"
            );
            log_skip(
                "the shader check",
                "glslc/spirv-val not on PATH (TILEGRAPH_ALLOW_MISSING_TOOLS=1)",
            );
            return;
        }
        if let Err(e) = check_shaders(&root()) {
            panic!("{e}");
        }
    }
}
