//! The C programs of `tests/capi/`, compiled with the system `cc` against `libtilegraph.a` and
//! the Vulkan headers, run on lavapipe with their own validation:
//!
//! - `sample.c` renders the city with two-phase HiZ on the C engine's own device, into its own
//!   image, through its own command buffers; its pixels equal the Rust path's, bit for bit;
//! - `moving.c` moves, spawns and removes instances every frame through the C ABI before
//!   recording; its pixels equal the same changes made through the Rust API, bit for bit;
//! - `materials.c` registers an engine material of its own shaders (through the shipped
//!   include), layout and bind callback; the city through `none` and `hiz-2phase` gives equal
//!   images, which differ from tilegraph's own shading, and with its cluster file attached
//!   `none` and `hiz-2phase-clusters` do too;
//! - `plan.c` compiles a deferred frame's graph for three profiles and walks every plan whole
//!   (steps, attachments, subpasses, barriers): its text equals the Rust plan's, line for line;
//! - `pvs.c` reads a visible set baked by the test from memory, as a game reads an asset, and
//!   draws the city's path with `TG_CULLING_PVS`: its pixels equal the Rust path's; the
//!   refusals (no set, another scene's, bytes that are none, a destroyed handle) name the cause;
//! - `errors.c` drives every error status and checks each message, faults included.
//!
//! `cargo xtask test` builds the static library first (`cargo build --profile test -p
//! tilegraph-capi`); a library older than the sources is an error naming that command.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::SystemTime;

use tilegraph_e2e::gpu_with;
use tilegraph_passes::cull::Culling;
use tilegraph_passes::shadow::{CasterCulling, ShadowOptions};
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_scene::CameraFrame;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `target/debug` (or wherever this test binary was built).
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    // target/<profile dir>/deps/c_programs-HASH
    exe.parent().and_then(Path::parent).unwrap().to_path_buf()
}

fn newest_source(dir: &Path, newest: &mut SystemTime) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            // Tests and benchmarks are not built into the library.
            if p.file_name()
                .is_some_and(|n| n == "tests" || n == "benches")
            {
                continue;
            }
            newest_source(&p, newest);
        } else if p
            .extension()
            .is_some_and(|x| x == "rs" || x == "spv" || x == "toml")
        {
            if let Ok(m) = e.metadata().and_then(|m| m.modified()) {
                *newest = (*newest).max(m);
            }
        }
    }
}

/// The static library, checked to be newer than every source it is built from.
fn library() -> PathBuf {
    let lib = target_dir().join("libtilegraph.a");
    let rebuild =
        "build it with `cargo build --profile test -p tilegraph-capi` (`cargo xtask test` does)";
    let built = std::fs::metadata(&lib)
        .and_then(|m| m.modified())
        .unwrap_or_else(|_| panic!("{} is missing: {rebuild}", lib.display()));
    let mut newest = SystemTime::UNIX_EPOCH;
    for dir in ["shaders/spv", "config"] {
        newest_source(&root().join(dir), &mut newest);
    }
    // Every crate but the two the library is not built from (the CLI, the Rust facade): a
    // change to the CLI alone leaves the library as it was, and cargo rightly does not relink it.
    let crates = std::fs::read_dir(root().join("crates"))
        .into_iter()
        .flatten();
    for c in crates.flatten() {
        if !(c.file_name() == "cli" || c.file_name() == "tilegraph") {
            newest_source(&c.path(), &mut newest);
        }
    }
    assert!(
        built >= newest,
        "{} is older than the sources: {rebuild}",
        lib.display()
    );
    lib
}

/// Compiles `tests/capi/<name>.c` into an executable.
fn compile(name: &str) -> PathBuf {
    let out = target_dir().join(format!("capi-{name}"));
    let status = Command::new("cc")
        .args(["-std=c11", "-O1", "-g", "-Wall", "-Wextra", "-Werror"])
        .arg("-I")
        .arg(root().join("crates/capi/include"))
        .arg("-I")
        .arg(root().join("tests/capi"))
        .arg(root().join(format!("tests/capi/{name}.c")))
        .arg(library())
        .args(["-lvulkan", "-lpthread", "-ldl", "-lm", "-o"])
        .arg(&out)
        .status()
        .expect("cc (install gcc: `cargo xtask deps`)");
    assert!(status.success(), "compiling tests/capi/{name}.c failed");
    out
}

fn run(exe: &Path, args: &[&str]) -> String {
    let output = Command::new(exe).args(args).output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "{} failed ({}):\n{stdout}\n{stderr}",
        exe.display(),
        output.status
    );
    stdout
}

/// The image a C program wrote at `path` equals the Rust path's `reference`, byte for byte
/// (`what`: which image, or the program's log).
fn assert_equals_rust_image(what: &str, path: &Path, reference: &[u8]) {
    let pixels = std::fs::read(path).unwrap();
    assert_eq!(pixels.len(), reference.len(), "{what}");
    let differing = pixels.iter().zip(reference).filter(|(a, b)| a != b).count();
    assert_eq!(
        differing, 0,
        "{differing} bytes differ from the Rust path's image: {what}"
    );
}

/// The Rust path: tilegraph's own device and submission, the same frames — the main camera's
/// image, and the second camera's rendered alone with the visibility buffer and with deferred
/// texturing (on a device with the same features).
fn rust_reference() -> (Vec<u8>, Vec<u8>, Vec<u8>) {
    let scene = tilegraph_scene::load("city:300").unwrap();
    let options = RenderOptions {
        technique: Technique::Prepass,
        culling: Culling::HizTwoPhase,
        width: 160,
        height: 90,
        shadows: ShadowOptions {
            cascades: 3,
            resolution: 512,
            culling: CasterCulling::ReceiversHiz,
            ..ShadowOptions::default()
        },
        ..Default::default()
    };
    let view = RenderOptions {
        technique: Technique::Visbuf,
        culling: Culling::Hiz,
        width: 96,
        height: 64,
        clear_color: [0.1, 0.2, 0.3, 1.0],
        shadows: ShadowOptions {
            cascades: 2,
            resolution: 256,
            culling: CasterCulling::Receivers,
            ..ShadowOptions::default()
        },
        ..Default::default()
    };
    let mut features = options.device_features();
    features.required.extend(view.device_features().required);
    features.optional.extend(view.device_features().optional);
    let g = gpu_with(Some("mali-valhall"), features).unwrap();
    let light = glam::Vec3::new(-0.8, 0.45, 0.35).normalize();
    let sun = glam::Vec3::new(0.9, 0.85, 0.75);
    let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
    r.set_light_direction(light);
    r.set_light_color(sun);
    for frame in scene.camera_path().frames(160.0 / 90.0).take(6) {
        r.render_frame(&g, &scene, &frame).unwrap();
    }
    let image = r.read_image(&g).unwrap();
    r.destroy(&g);
    // The second camera's frames, further along the path, rendered alone under `options`.
    let ahead = |options: RenderOptions| {
        let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
        r.set_light_direction(light);
        r.set_light_color(sun);
        let keys = scene.camera_path().keys();
        for i in 0..6 {
            let key = keys[20 + i];
            let previous = (i > 0 && !key.cut).then(|| keys[19 + i].camera);
            let frame = CameraFrame::new(i, key.camera, previous.as_ref(), 96.0 / 64.0);
            r.render_frame(&g, &scene, &frame).unwrap();
        }
        let image = r.read_image(&g).unwrap();
        r.destroy(&g);
        image
    };
    let view_image = ahead(view);
    let deferred_image = ahead(RenderOptions {
        technique: Technique::DeferredTexturing,
        culling: Culling::HizTwoPhase,
        width: 96,
        height: 64,
        clear_color: [0.1, 0.2, 0.3, 1.0],
        ..Default::default()
    });
    (image.pixels, view_image.pixels, deferred_image.pixels)
}

#[test]
fn the_c_sample_renders_the_rust_paths_image() {
    let exe = compile("sample");
    let out = target_dir().join("capi-sample.rgba");
    let log = run(&exe, &[out.to_str().unwrap(), "mali-valhall"]);
    assert!(log.contains("profile mali-valhall (forced"), "{log}");
    assert!(log.contains("GPU times of frame"), "{log}");
    // Timed per pass first, then (tg_renderer_set_gpu_timing) as a whole frame.
    assert!(log.contains("  depth-prepass"), "{log}");
    assert!(log.contains("  view1/visbuf"), "{log}");
    assert!(log.lines().any(|l| l.starts_with("  frame ")), "{log}");
    assert!(log.contains("  view2/gbuffer-resolve"), "{log}");
    let (reference, view_reference, deferred_reference) = rust_reference();
    let view_out = target_dir().join("capi-sample.rgba.view");
    let deferred_out = target_dir().join("capi-sample.rgba.deferred");
    for (what, path, reference) in [
        ("main camera", &out, &reference),
        ("second camera", &view_out, &view_reference),
        (
            "deferred-texturing view",
            &deferred_out,
            &deferred_reference,
        ),
    ] {
        assert_equals_rust_image(what, path, reference);
    }
}

/// The Rust path of `tests/capi/moving.c`: the same changes before the same frames.
fn rust_moving_reference() -> Vec<u8> {
    use glam::Mat3;
    use tilegraph_scene::{InstanceFlags, InstanceId, MeshId, Transform};
    let mut scene = tilegraph_scene::load("city:300").unwrap();
    let options = RenderOptions {
        technique: Technique::Prepass,
        culling: Culling::HizTwoPhase,
        width: 160,
        height: 90,
        ..Default::default()
    };
    let g = gpu_with(Some("mali-valhall"), options.device_features()).unwrap();
    let movers: Vec<_> = (0..40)
        .map(|k| scene.instance_handle(InstanceId(3 * k)).unwrap())
        .collect();
    let base: Vec<Transform> = movers
        .iter()
        .map(|h| scene.instance(*h).unwrap().transform)
        .collect();
    let crate_mesh = scene.mesh_handle(MeshId(2)).unwrap();
    scene.prepare_mirroring(crate_mesh).unwrap();
    let path = scene.camera_path().clone();
    let mut spawned = Vec::new();
    let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
    for (i, frame) in path.frames(160.0 / 90.0).take(8).enumerate() {
        let moves: Vec<_> = movers
            .iter()
            .zip(&base)
            .enumerate()
            .map(|(k, (h, t))| {
                let mut t = *t;
                t.translation.x += ((i + k) % 4) as f64 * 0.5;
                (*h, t)
            })
            .collect();
        scene.set_transforms(&moves).unwrap();
        let camera = path.camera(i).unwrap();
        let added: Vec<_> = (0..4)
            .map(|k| {
                let mut at = camera.eye + (camera.target - camera.eye) * 0.25;
                at.x += f64::from(k) * 1.5;
                let mirror = if k == 3 { -1.0 } else { 1.0 };
                let t = Transform::new(Mat3::from_diagonal(glam::Vec3::new(mirror, 1.0, 1.0)), at);
                scene
                    .add_instance(crate_mesh, t, InstanceFlags::CASTS_SHADOWS)
                    .unwrap()
            })
            .collect();
        spawned.push(added);
        if i >= 2 {
            for h in &spawned[i - 2] {
                scene.remove_instance(*h).unwrap();
            }
        }
        r.render_frame(&g, &scene, &frame).unwrap();
    }
    let image = r.read_image(&g).unwrap();
    r.destroy(&g);
    image.pixels
}

#[test]
fn the_c_moving_scene_renders_the_rust_paths_image() {
    let exe = compile("moving");
    let out = target_dir().join("capi-moving.rgba");
    let log = run(&exe, &[out.to_str().unwrap()]);
    assert!(log.trim_end().ends_with("ok"), "{log}");
    assert_equals_rust_image(&log, &out, &rust_moving_reference());
}

/// A visible set of city:300 baked over its path (as `tilegraph pvs` bakes), written where
/// `tests/capi/pvs.c` reads it; and the Rust path's image of the frames `pvs.c` draws with it.
fn rust_pvs_reference(file: &Path) -> Vec<u8> {
    use std::sync::Arc;
    let scene = tilegraph_scene::load("city:300").unwrap();
    let (baker, _, pvs) = tilegraph_e2e::bake_path_pvs(&scene, 32);
    drop(baker);
    std::fs::write(file, pvs.to_json().unwrap()).unwrap();
    let options = RenderOptions {
        technique: Technique::Forward,
        culling: Culling::Pvs,
        width: 160,
        height: 90,
        pvs: Some(Arc::new(pvs)),
        pvs_dilation: 1,
        ..Default::default()
    };
    let g = gpu_with(Some("mali-valhall"), options.device_features()).unwrap();
    let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
    for frame in scene.camera_path().frames(160.0 / 90.0).take(6) {
        r.render_frame(&g, &scene, &frame).unwrap();
    }
    let image = r.read_image(&g).unwrap();
    r.destroy(&g);
    image.pixels
}

#[test]
fn the_c_game_draws_its_shipped_visible_set_as_the_rust_path() {
    let exe = compile("pvs");
    let set = target_dir().join("capi-pvs.json");
    let out = target_dir().join("capi-pvs.rgba");
    let reference = rust_pvs_reference(&set);
    let log = run(&exe, &[set.to_str().unwrap(), out.to_str().unwrap()]);
    assert!(log.trim_end().ends_with("ok"), "{log}");
    assert_equals_rust_image(&log, &out, &reference);
}

#[test]
fn the_c_error_test_drives_every_status() {
    let exe = compile("errors");
    let log = run(&exe, &[]);
    assert!(log.trim_end().ends_with("ok"), "{log}");
}

/// The C engine's frames in `mode` (`none`, `hiz-2phase`, `hiz-2phase-clusters`,
/// `tilegraph`), as RGBA8 images; with `clusters`, that cluster file attached.
fn c_material_frames(exe: &Path, mode: &str, clusters: Option<&Path>) -> Vec<Vec<u8>> {
    let spv = root().join("shaders/spv");
    let name = format!(
        "{mode}{}",
        if clusters.is_some() { "-clustered" } else { "" }
    );
    let prefix = target_dir().join(format!("capi-materials-{name}"));
    let mut args = vec![
        spv.join("test_engine.vert.spv").display().to_string(),
        spv.join("test_engine.frag.spv").display().to_string(),
        mode.to_string(),
        prefix.display().to_string(),
    ];
    args.extend(clusters.map(|p| p.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let log = run(exe, &args);
    assert!(log.starts_with("ok"), "{log}");
    (0..5)
        .map(|k| std::fs::read(format!("{}-{k}.rgba", prefix.display())).unwrap())
        .collect()
}

#[test]
fn the_c_engine_material_draws_the_culled_city_as_the_unculled_one() {
    let exe = compile("materials");
    let none = c_material_frames(&exe, "none", None);
    let two_phase = c_material_frames(&exe, "hiz-2phase", None);
    let tilegraph = c_material_frames(&exe, "tilegraph", None);
    for (k, (a, b)) in none.iter().zip(&two_phase).enumerate() {
        assert!(
            a.len() == 160 * 90 * 4 && a == b,
            "frame {k}: hiz-2phase differs from none"
        );
    }
    // Cluster culling draws the engine's groups too: with the city's cluster file attached
    // (its index order) in both runs, the culled frames are the unculled ones.
    let scene = tilegraph_scene::load("city:400").unwrap();
    let (data, _) = tilegraph_scene::clusters::build(&scene).unwrap();
    let file = target_dir().join("capi-materials-city400.clusters");
    data.write(&file).unwrap();
    let clustered = c_material_frames(&exe, "none", Some(&file));
    let clusters = c_material_frames(&exe, "hiz-2phase-clusters", Some(&file));
    for (k, (a, b)) in clustered.iter().zip(&clusters).enumerate() {
        assert!(
            a.len() == 160 * 90 * 4 && a == b,
            "frame {k}: hiz-2phase-clusters differs from none"
        );
    }
    let changed: usize = none
        .iter()
        .zip(&tilegraph)
        .map(|(a, b)| {
            a.chunks_exact(4)
                .zip(b.chunks_exact(4))
                .filter(|(p, q)| p != q)
                .count()
        })
        .sum();
    assert!(
        changed > 5 * 160 * 90 / 4,
        "the engine's shading is not what was drawn ({changed} pixels differ from tilegraph's)"
    );
}

/// `tests/capi/plan.c`'s graph through the Rust API, each plan written as the C walk writes it.
fn rust_plan_walk() -> String {
    use std::fmt::Write;
    use tilegraph_graph::{
        ClearColor, ClearDepthStencil, Extent2d, Format, GraphBuilder, ImageDesc, PassClass,
        Residency, Step,
    };
    let (w, h) = (320, 180);
    let desc = |format| ImageDesc::new(Extent2d::new(w, h), format);
    let mut g: GraphBuilder<()> = GraphBuilder::new();
    let albedo = g.create_image("albedo", desc(Format::R8G8B8A8_UNORM));
    let normal = g.create_image("normal", desc(Format::R16G16B16A16_SFLOAT));
    let depth = g.create_image("depth", desc(Format::D32_SFLOAT));
    let ao = g.create_buffer("ao", u64::from(w * h * 4));
    let hdr = g.create_image("hdr", desc(Format::R16G16B16A16_SFLOAT));
    // Found UNDEFINED, left in TRANSFER_SRC: as plan.c imports it.
    let target = g.import_image(
        "target",
        desc(Format::R8G8B8A8_UNORM),
        tilegraph_e2e::frames::target_import(),
    );
    let scratch = g.create_image("scratch", desc(Format::R8G8B8A8_UNORM));
    let black = ClearColor::Float([0.0, 0.0, 0.0, 1.0]);
    g.compute_pass("occlusion", PassClass::Compute, ())
        .storage_write(ao)
        .async_compute();
    g.raster_pass("gbuffer", PassClass::Opaque, ())
        .color_clear(albedo, black)
        .color_clear(normal, black)
        .depth_stencil_clear(
            depth,
            ClearDepthStencil {
                depth: 1.0,
                stencil: 0,
            },
        );
    g.raster_pass("lighting", PassClass::Opaque, ())
        .input(albedo)
        .input(normal)
        .storage_read(ao)
        .color(hdr);
    g.raster_pass("post", PassClass::Post, ())
        .sampled(hdr)
        .color(target);
    g.raster_pass("debug", PassClass::Post, ())
        .sampled(hdr)
        .color_clear(scratch, black);
    g.export(target);

    let profiles = tilegraph_profile::ProfileSet::embedded().unwrap();
    let mut out = String::new();
    for name in ["mali-valhall", "adreno-7xx", "desktop-nvidia"] {
        let profile = profiles.get(name).unwrap();
        let plan = g
            .clone()
            .compile(profile)
            .unwrap()
            .into_plan_and_payloads()
            .0;
        let pass_name = |id: tilegraph_graph::PassId| {
            plan.passes
                .iter()
                .find(|p| p.id == id)
                .map_or(String::new(), |p| p.name.clone())
        };
        let bytes = |b: &tilegraph_graph::TrafficBreakdown| {
            b.attachment_read_bytes + b.attachment_write_bytes + b.resolve_write_bytes
        };
        writeln!(
            out,
            "profile {name}: {} steps, {} render passes, {} barriers, {} passes, {} pruned, {} transient, traffic {} of {}",
            plan.steps.len(),
            plan.render_passes().count(),
            plan.barrier_count(),
            plan.passes.len(),
            plan.pruned.len(),
            plan.resources
                .iter()
                .filter(|r| r.residency == Residency::Transient)
                .count(),
            bytes(&plan.traffic.planned),
            bytes(&plan.traffic.naive)
        )
        .unwrap();
        for (i, step) in plan.steps.iter().enumerate() {
            let (kind, pass, barriers, rp) = match step {
                Step::Barriers(b) => (0, String::new(), b.len(), None),
                Step::RenderPass(rp) => (1, pass_name(rp.subpasses[0].pass), 0, Some(rp)),
                Step::Compute { pass } => (2, pass_name(*pass), 0, None),
                Step::Transfer { pass } => (3, pass_name(*pass), 0, None),
                Step::Flush(_) => (4, String::new(), 0, None),
            };
            let (subpasses, attachments, area) = rp.map_or((0, 0, (0, 0)), |rp| {
                (
                    rp.subpasses.len(),
                    rp.attachments.len(),
                    (rp.render_area_px.width_px, rp.render_area_px.height_px),
                )
            });
            writeln!(
                out,
                "step {i} kind {kind} pass {pass} barriers {barriers} subpasses {subpasses} attachments {attachments} area {}x{}",
                area.0, area.1
            )
            .unwrap();
            if let Some(rp) = rp {
                for (a, at) in rp.attachments.iter().enumerate() {
                    let residency = match at.residency {
                        Residency::Imported => 0,
                        Residency::Exported => 1,
                        Residency::FrameLocal => 2,
                        Residency::Transient => 3,
                        Residency::Unused => 4,
                    };
                    writeln!(
                        out,
                        "  attachment {a} resource {} format {} ops {}/{} stencil {}/{} layouts {}->{} residency {residency}",
                        at.resource.0,
                        at.format.vk_raw(),
                        at.load_op.vk_raw(),
                        at.store_op.vk_raw(),
                        at.stencil_load_op.vk_raw(),
                        at.stencil_store_op.vk_raw(),
                        at.initial_layout.vk_raw(),
                        at.final_layout.vk_raw()
                    )
                    .unwrap();
                }
                for (p, sp) in rp.subpasses.iter().enumerate() {
                    writeln!(
                        out,
                        "  subpass {p} pass {} colors {} inputs {} depth {}",
                        pass_name(sp.pass),
                        sp.colors.len(),
                        sp.inputs.len(),
                        sp.depth_stencil.map_or(-1, |d| d.attachment.0 as i32)
                    )
                    .unwrap();
                }
            }
            if let Step::Barriers(b) = step {
                for (k, x) in barrier_rows(b).into_iter().enumerate() {
                    writeln!(
                        out,
                        "  barrier {k} resource {} image {} src {:#x}/{:#x} dst {:#x}/{:#x} layouts {}->{} transfer {}",
                        x.resource, x.image, x.src.0, x.src.1, x.dst.0, x.dst.1, x.layouts.0, x.layouts.1, x.transfer
                    )
                    .unwrap();
                }
            }
        }
        for (k, sub) in plan.submissions.iter().enumerate() {
            let queue = match sub.queue {
                tilegraph_graph::Queue::Graphics => 0,
                tilegraph_graph::Queue::AsyncCompute => 1,
            };
            writeln!(
                out,
                "submission {k} queue {queue} steps {}..{} waits {} releases {}",
                sub.first.0,
                sub.end.0,
                sub.waits.len(),
                sub.releases.len()
            )
            .unwrap();
            for w in &sub.waits {
                writeln!(
                    out,
                    "  wait on {} at 0x{:x}",
                    w.submission.0,
                    w.dst_stages.bits()
                )
                .unwrap();
            }
            for (r, x) in barrier_rows(&sub.releases).into_iter().enumerate() {
                writeln!(
                    out,
                    "  release {r} resource {} image {} src 0x{:x} layouts {}->{} transfer {}",
                    x.resource, x.image, x.src.0, x.layouts.0, x.layouts.1, x.transfer
                )
                .unwrap();
            }
        }
    }
    out
}

/// One barrier as the C walk prints it.
struct BarrierRow {
    resource: u32,
    image: u32,
    src: (u64, u64),
    dst: (u64, u64),
    layouts: (i32, i32),
    transfer: u32,
}

/// A batch's barriers, images first (as `tg_plan_barrier` numbers them).
fn barrier_rows(b: &tilegraph_graph::BarrierBatch) -> Vec<BarrierRow> {
    use tilegraph_graph::{Queue, QueueTransfer};
    let transfer = |t: Option<QueueTransfer>| match t {
        None => 0,
        Some(QueueTransfer {
            to: Queue::AsyncCompute,
            ..
        }) => 1,
        Some(QueueTransfer {
            to: Queue::Graphics,
            ..
        }) => 2,
    };
    let images = b.images.iter().map(|x| BarrierRow {
        resource: x.resource.0,
        image: 1,
        src: (x.src_stages.bits(), x.src_access.bits()),
        dst: (x.dst_stages.bits(), x.dst_access.bits()),
        layouts: (x.old_layout.vk_raw(), x.new_layout.vk_raw()),
        transfer: transfer(x.queue_transfer),
    });
    let buffers = b.buffers.iter().map(|x| BarrierRow {
        resource: x.resource.0,
        image: 0,
        src: (x.src_stages.bits(), x.src_access.bits()),
        dst: (x.dst_stages.bits(), x.dst_access.bits()),
        layouts: (0, 0),
        transfer: transfer(x.queue_transfer),
    });
    images.chain(buffers).collect()
}

#[test]
fn the_c_plan_walk_sees_the_rust_plan() {
    let exe = compile("plan");
    let out = target_dir().join("capi-plan.txt");
    let log = run(&exe, &[out.to_str().unwrap()]);
    assert!(log.trim_end().ends_with("ok"), "{log}");
    let c = std::fs::read_to_string(&out).unwrap();
    let rust = rust_plan_walk();
    // The walk saw what a plan holds: merged subpasses on the tilers, transient attachments,
    // barriers, the pruned debug pass.
    for needle in [
        "subpass 1 pass lighting",
        "residency 3",
        "barrier 0",
        "1 pruned",
        // The occlusion pass on the async queue (mali-valhall, desktop-nvidia), and the
        // graphics queue's wait for it.
        "queue 1 steps",
        "  wait on ",
    ] {
        assert!(c.contains(needle), "{needle:?} not in the C walk:\n{c}");
    }
    for (i, (a, b)) in c.lines().zip(rust.lines()).enumerate() {
        assert_eq!(a, b, "line {i} of the walk: C against Rust");
    }
    assert_eq!(
        c.lines().count(),
        rust.lines().count(),
        "C:\n{c}\nRust:\n{rust}"
    );
}
