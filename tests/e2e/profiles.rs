//! Profiles checked against the frames they shape (lavapipe, validation on), for every profile
//! and every technique on the shipped scenes:
//!
//! - the state lint of the shipped passes: a finding is either fixed or listed, with its
//!   reason, in `config/accepted_findings.toml` (shown in docs/PROFILES.md's "Accepted lint
//!   findings") — and a listed finding that no frame produces any more is an error too, so the
//!   table stays true;
//! - the promises the profile makes about the compiled plan: occlusion queries in a render
//!   pass of their own, after a flush, where it says so (and no flush where it does not) —
//!   raster occlusion's boxes are of the same class and follow the same rule; passes in the
//!   profile's class order unless a dependency puts them otherwise (a pass feeding one of an
//!   earlier class takes that class's rank); the light's cascades one render pass, stored,
//!   before whatever samples them;
//!   next-frame queries after all drawing; attachments whose whole life is one render pass
//!   transient exactly where the profile keeps data on chip.

use std::collections::BTreeMap;

use tilegraph_e2e::gpu_with;
use tilegraph_graph::{FlushReason, LoadOp, PassClass, Plan, Residency, Step, StoreOp, UseKind};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::lint::FrameLint;
use tilegraph_passes::shadow::ShadowOptions;
use tilegraph_passes::{RenderOptions, SceneRenderer, Technique};
use tilegraph_profile::accepted::AcceptedFinding;
use tilegraph_profile::{Profile, ProfileSet};

/// The frames linted: every shading technique unculled, and every culling technique with the
/// shading it is most often paired with (raster occlusion at full and half resolution); the
/// last field is the light's shadow cascades.
const FRAMES: &[(Technique, Culling, u32, u32)] = &[
    (Technique::Forward, Culling::None, 1, 0),
    (Technique::Prepass, Culling::None, 1, 0),
    (Technique::Visbuf, Culling::None, 1, 0),
    (Technique::Forward, Culling::Frustum, 1, 0),
    (Technique::Forward, Culling::Hiz, 1, 0),
    (Technique::Prepass, Culling::HizTwoPhase, 1, 0),
    (Technique::Visbuf, Culling::HizTwoPhase, 1, 0),
    (Technique::DeferredTexturing, Culling::HizTwoPhase, 1, 0),
    // After the merged resolve read the depth as an input attachment, the pyramid reads it.
    (Technique::DeferredTexturing, Culling::Hiz, 1, 0),
    (Technique::Forward, Culling::Oq, 1, 0),
    (Technique::Forward, Culling::OqConditional, 1, 0),
    (Technique::Prepass, Culling::RasterOcclusion, 1, 0),
    (Technique::Prepass, Culling::RasterOcclusion, 2, 0),
    // The light's three cascades under each shading.
    (Technique::Forward, Culling::None, 1, 3),
    (Technique::Prepass, Culling::HizTwoPhase, 1, 3),
    (Technique::Visbuf, Culling::HizTwoPhase, 1, 3),
    (Technique::DeferredTexturing, Culling::HizTwoPhase, 1, 3),
];

/// The shipped procedural scenes: opaque, alpha-tested (forest, field, interior) and blended
/// (city, interior) materials.
const SCENES: &[&str] = &["interior:100", "city:100", "forest:100", "field:100"];

/// The device features every frame of [`FRAMES`] needs.
fn frame_features() -> tilegraph_vk::FeatureRequest {
    let mut features = tilegraph_vk::FeatureRequest::default();
    for &(technique, culling, _, cascades) in FRAMES {
        let f = RenderOptions {
            technique,
            culling,
            shadows: shadows(cascades),
            ..Default::default()
        }
        .device_features();
        features.required.extend(f.required);
        features.optional.extend(f.optional);
    }
    features
}

/// The rows of the table under `## {section}` in docs/PROFILES.md that start with a name in
/// backticks.
fn table_rows(section: &str) -> Vec<String> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/PROFILES.md");
    let doc = std::fs::read_to_string(path).unwrap();
    let body = doc
        .split(&format!("## {section}"))
        .nth(1)
        .unwrap_or_else(|| panic!("docs/PROFILES.md has a {section:?} section"));
    let body = body.split("\n## ").next().unwrap_or(body);
    body.lines()
        .filter(|l| l.starts_with("| `"))
        .map(str::to_string)
        .collect()
}

/// The accepted findings: `config/accepted_findings.toml`, compiled into tilegraph-profile
/// (docs/PROFILES.md's "Accepted lint findings" shows the same rows; a test of that crate keeps
/// them equal).
fn accepted() -> Vec<AcceptedFinding> {
    tilegraph_profile::accepted::accepted_findings().unwrap()
}

/// What shapes a frame's passes and render passes: profiles that agree on it record the same
/// draws in the same render passes, so each shape is recorded once and linted under each of
/// its profiles.
fn shape(p: &Profile) -> String {
    format!(
        "{:?} {:?} {:?}",
        p.passes, p.render_pass, p.gpu.architecture
    )
}

#[test]
fn every_profile_keeps_its_plan_promises_and_lints_clean_but_the_accepted() {
    let accepted = accepted();
    assert!(!accepted.is_empty());
    let scenes: Vec<_> = SCENES
        .iter()
        .map(|name| {
            let scene = tilegraph_scene::load(name).unwrap();
            let camera = scene.camera_path().camera(0).unwrap();
            (*name, scene, camera)
        })
        .collect();
    let set = ProfileSet::embedded().unwrap();
    let mut shapes: BTreeMap<String, Vec<&Profile>> = BTreeMap::new();
    for p in set.profiles() {
        shapes.entry(shape(p)).or_default().push(p);
    }
    let mut used = vec![false; accepted.len()];
    let mut unaccepted: Vec<String> = Vec::new();
    let mut linted = 0;
    for profiles in shapes.values() {
        let recording = profiles[0];
        let g = gpu_with(Some(&recording.name), frame_features()).unwrap();
        for ((name, scene, camera), &(technique, culling, scale, cascades)) in scenes
            .iter()
            .flat_map(|s| FRAMES.iter().map(move |f| (s, f)))
        {
            let options = RenderOptions {
                technique,
                culling,
                raster_occlusion_scale: scale,
                width: 64,
                height: 36,
                shadows: shadows(cascades),
                ..Default::default()
            };
            let mut r = SceneRenderer::new(&g, scene, options).unwrap();
            r.lint_next_frame();
            let report = r.render(&g, scene, camera).unwrap();
            r.finish(&g).unwrap();
            r.destroy(&g);
            let frame = format!(
                "{name} {} / {} / {} / {cascades} cascades",
                technique.name(),
                culling.name(),
                scale
            );
            for p in profiles {
                check_promises(p, &report.plan, culling, &frame);
                check_shadow_promises(p, &report.plan, cascades, &frame);
            }
            let recorded: &FrameLint = report.lint.as_deref().expect("the frame was linted");
            assert!(!recorded.render_passes.is_empty());
            for p in profiles {
                let findings = tilegraph_profile::lint::lint(p, &recorded.render_passes);
                linted += 1;
                for f in findings {
                    match accepted.iter().position(|a| a.covers(&f)) {
                        Some(i) => used[i] = true,
                        None => unaccepted.push(format!("{frame}: {f}")),
                    }
                }
            }
        }
    }
    assert!(
        linted >= 18 * FRAMES.len() * SCENES.len(),
        "{linted} frames linted"
    );
    unaccepted.sort();
    unaccepted.dedup();
    assert!(
        unaccepted.is_empty(),
        "findings neither fixed nor accepted in docs/PROFILES.md:\n{}",
        unaccepted.join("\n")
    );
    let stale: Vec<&AcceptedFinding> = accepted
        .iter()
        .zip(&used)
        .filter(|(_, u)| !**u)
        .map(|(a, _)| a)
        .collect();
    assert!(
        stale.is_empty(),
        "accepted findings no frame produces any more: {stale:#?}"
    );
}

/// `cascades` cascades of 256 texels (none for 0).
fn shadows(cascades: u32) -> ShadowOptions {
    ShadowOptions {
        cascades,
        resolution: 256,
        ..ShadowOptions::default()
    }
}

/// A frame with shadows: the cascades are one render pass of their own (the atlas its one
/// attachment, cleared and stored — what a tiler writes out once), before every pass that
/// samples the atlas; the atlas is never transient. A frame without has no shadow pass.
fn check_shadow_promises(p: &Profile, plan: &Plan, cascades: u32, frame: &str) {
    let at = format!("{} {frame}\n{plan}", p.name);
    let shadow = plan.passes.iter().find(|q| q.class == PassClass::Shadow);
    let Some(shadow) = shadow else {
        assert_eq!(cascades, 0, "no shadow pass: {at}");
        return;
    };
    assert!(cascades > 0, "a shadow pass without shadows: {at}");
    let atlas = plan.resources.iter().find(|r| r.name == "shadow-atlas");
    let Some(atlas) = atlas else {
        panic!("no atlas: {at}");
    };
    assert_ne!(atlas.residency, Residency::Transient, "{at}");
    let Some(Step::RenderPass(rp)) = plan.steps.get(shadow.step.0 as usize) else {
        panic!("the shadow pass is in no render pass: {at}");
    };
    assert_eq!(
        rp.subpasses.len(),
        1,
        "the cascades share a render pass: {at}"
    );
    assert_eq!(rp.attachments.len(), 1, "{at}");
    let a = &rp.attachments[0];
    assert_eq!(a.resource, atlas.id, "{at}");
    assert_eq!(
        (a.load_op, a.store_op),
        (LoadOp::Clear, StoreOp::Store),
        "{at}"
    );
    let samplers: Vec<_> = plan
        .passes
        .iter()
        .filter(|q| {
            q.uses
                .iter()
                .any(|u| u.resource == atlas.id && u.kind == UseKind::Sampled)
        })
        .collect();
    assert!(!samplers.is_empty(), "nothing samples the atlas: {at}");
    for q in samplers {
        assert!(
            q.step.0 > shadow.step.0,
            "{} before the cascades: {at}",
            q.name
        );
    }
}

/// The profile's promises on one compiled frame (see the module doc).
fn check_promises(p: &Profile, plan: &Plan, culling: Culling, frame: &str) {
    let at = format!("{} {frame}\n{plan}", p.name);
    let class_of = |pass| plan.pass(pass).map(|q| q.class);
    let policy = p.passes.occlusion_queries;
    let mut query_steps = Vec::new();
    for (i, step) in plan.steps.iter().enumerate() {
        let Step::RenderPass(rp) = step else { continue };
        let queries = rp
            .subpasses
            .iter()
            .filter(|s| class_of(s.pass) == Some(PassClass::OcclusionQuery))
            .count();
        if queries == 0 {
            continue;
        }
        query_steps.push(i);
        if policy.own_render_pass {
            assert_eq!(
                queries,
                rp.subpasses.len(),
                "queries share a render pass: {at}"
            );
        }
        let before = plan.steps[..i]
            .iter()
            .rev()
            .find(|s| !matches!(s, Step::Barriers(_)));
        let flushed = matches!(
            before,
            Some(Step::Flush(FlushReason::BeforeOcclusionQueries))
        );
        assert_eq!(
            flushed, policy.flush_before,
            "flush before the queries: {at}"
        );
    }
    assert_eq!(
        !query_steps.is_empty(),
        matches!(
            culling,
            Culling::Oq | Culling::OqConditional | Culling::RasterOcclusion
        ),
        "occlusion-query class passes (queries, raster occlusion boxes): {at}"
    );
    if !policy.flush_before {
        assert!(
            !plan.steps.iter().any(|s| matches!(s, Step::Flush(_))),
            "a flush the profile does not ask for: {at}"
        );
    }
    // Next-frame queries test this frame's finished depth: after every drawing pass.
    if culling == Culling::Oq {
        let last_query = query_steps.iter().max().copied().unwrap_or(0);
        for q in &plan.passes {
            if matches!(
                q.class,
                PassClass::Opaque | PassClass::AlphaTested | PassClass::Transparent
            ) {
                assert!(
                    q.step.0 as usize <= last_query,
                    "{} after the queries: {at}",
                    q.name
                );
            }
        }
    }
    // Passes in the profile's class order: a pass of a later class runs before one of an
    // earlier class only when the earlier-class pass depends on it (through a resource, as a
    // same-frame query's results feed the colour passes).
    let touches = |a: &tilegraph_graph::PlannedPass, b: &tilegraph_graph::PlannedPass| {
        let shared = b.uses.iter().any(|ub| {
            a.uses
                .iter()
                .any(|ua| ua.resource == ub.resource && (ua.kind.writes() || ub.kind.writes()))
        });
        // Same-frame query results reach the copy through the query pool, an explicit
        // `after` edge the plan does not keep: what is predicated on them depends on the
        // queries.
        let predicated = a.class == PassClass::OcclusionQuery
            && b.uses
                .iter()
                .any(|u| u.kind == UseKind::ConditionalPredicate);
        shared || predicated
    };
    // depends[j][k]: pass j (transitively) depends on the earlier pass k.
    let mut depends: Vec<Vec<bool>> = Vec::with_capacity(plan.passes.len());
    for (j, b) in plan.passes.iter().enumerate() {
        let mut row = vec![false; plan.passes.len()];
        for (k, a) in plan.passes[..j].iter().enumerate() {
            if touches(a, b) {
                row[k] = true;
                for (m, d) in depends[k].iter().enumerate() {
                    row[m] |= *d;
                }
            }
        }
        depends.push(row);
    }
    // A pass takes the rank of the most urgent pass that waits on it (the scheduler's
    // effective rank): the early depth of two-phase culling feeds the pyramid's compute, so it
    // may run before a shadow pass.
    let effective: Vec<usize> = (0..plan.passes.len())
        .map(|k| {
            let own = p.passes.class_rank(plan.passes[k].class);
            depends
                .iter()
                .enumerate()
                .filter(|(_, row)| row[k])
                .map(|(j, _)| p.passes.class_rank(plan.passes[j].class))
                .fold(own, usize::min)
        })
        .collect();
    for (b, row) in plan.passes.iter().zip(&depends) {
        for ((a, depends_on_a), &urgency) in plan.passes.iter().zip(row).zip(&effective) {
            let out_of_order = urgency > p.passes.class_rank(b.class);
            if a.step.0 < b.step.0 || (a.step == b.step && a.subpass < b.subpass) {
                assert!(
                    !out_of_order || *depends_on_a,
                    "{} ({}) runs before {} ({}) without feeding it: {at}",
                    a.name,
                    a.class.name(),
                    b.name,
                    b.class.name()
                );
            }
        }
    }
    // Attachments that live and die in one render pass stay on chip where the profile keeps
    // data there, and nowhere else.
    let on_chip = p.is_tiler() && p.render_pass.transient_attachments;
    for r in &plan.resources {
        if r.residency == Residency::Transient {
            assert!(on_chip, "{} transient: {at}", r.name);
        }
    }
    if on_chip && culling == Culling::None {
        let depth = plan.resources.iter().find(|r| r.name == "depth");
        assert_eq!(
            depth.map(|r| r.residency),
            Some(Residency::Transient),
            "the depth of an unculled frame never leaves the tile: {at}"
        );
    }
}

/// Best practices with the vendor checks of a profile's family. The instance always enables the
/// generic checks; the vendor checks (Arm, IMG, NVIDIA) are switched on for a whole process by
/// a `vk_layer_settings.txt`, so `cargo xtask test` runs this test once per vendor with
/// `VK_LAYER_SETTINGS_PATH` and `TILEGRAPH_BEST_PRACTICES_PROFILE` naming the matching profile
/// (`mali-valhall` with Arm, `powervr-b` with IMG, `desktop-nvidia` with NVIDIA). A plain run
/// renders under lavapipe with the generic checks. Three frames per technique, each read back
/// as a presented image would be, so the checks that look across frames (a store nobody reads
/// before the next clear) see steady frames.
#[test]
fn every_technique_passes_best_practices_under_the_vendors_profile() {
    let profile = std::env::var("TILEGRAPH_BEST_PRACTICES_PROFILE")
        .unwrap_or_else(|_| "lavapipe".to_string());
    let scene = tilegraph_scene::load("interior:100").unwrap();
    let path = scene.camera_path();
    let g = gpu_with(Some(&profile), frame_features()).unwrap();
    for &(technique, culling, scale, cascades) in FRAMES {
        let options = RenderOptions {
            technique,
            culling,
            raster_occlusion_scale: scale,
            width: 64,
            height: 36,
            shadows: shadows(cascades),
            ..Default::default()
        };
        let mut r = SceneRenderer::new(&g, &scene, options).unwrap();
        for i in 0..3 {
            let camera = path.camera(i).unwrap();
            r.render(&g, &scene, &camera).unwrap();
            r.read_image(&g).unwrap();
        }
        r.finish(&g).unwrap();
        r.destroy(&g);
        let messages = g.take_validation_messages();
        assert!(
            messages.is_empty(),
            "{profile}, {} / {} / {scale}: {messages:#?}",
            technique.name(),
            culling.name()
        );
    }
    // The vendor's checks ran: one of its reviewed (silenced) messages was reported.
    let vendor_only = match profile.as_str() {
        "mali-valhall" => Some("vkCmdDrawIndexed-sparse-index-buffer"),
        "powervr-b" => Some("vkCmdBeginRenderPass-attachment-needs-readback"),
        "desktop-nvidia" => Some("CreateImage-Depth32Format"),
        _ => None,
    };
    if let (Some(id), Ok(_)) = (vendor_only, std::env::var("VK_LAYER_SETTINGS_PATH")) {
        let seen = g.silenced_validation_ids();
        assert!(
            seen.iter().any(|s| s.ends_with(id)),
            "{profile}: the vendor checks did not run (no {id}; silenced seen: {seen:?})"
        );
    }
}

/// A best-practices warning fails a test like any validation message: a command pool whose
/// command buffers are reset one by one (best practices ask to reset the pool).
#[test]
fn a_best_practices_warning_fails_the_test() {
    tilegraph_e2e::init_logging();
    let ctx = tilegraph_e2e::context(tilegraph_e2e::options(None, Default::default())).unwrap();
    let info = tilegraph_vk::ash::vk::CommandPoolCreateInfo::default()
        .queue_family_index(ctx.queue_family)
        .flags(tilegraph_vk::ash::vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
    // SAFETY: valid device and queue family; the pool is destroyed unused.
    unsafe {
        let pool = ctx.device.create_command_pool(&info, None).unwrap();
        ctx.device.destroy_command_pool(pool, None);
    }
    let e = tilegraph_e2e::lifecycle(|| ctx.destroy_checked())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("BestPractices-vkCreateCommandPool-command-buffer-reset"),
        "{e}"
    );
}

/// docs/PROFILES.md's "Silenced best-practices messages" table is `tilegraph_vk::SILENCED`,
/// row for row, reasons included.
#[test]
fn the_silenced_messages_are_the_documented_ones() {
    let rows: Vec<(String, String, String)> = table_rows("Silenced best-practices messages")
        .iter()
        .map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split(" | ").collect();
            assert_eq!(cells.len(), 3, "row {l:?}");
            let contains = match cells[1].trim() {
                "(every message)" => String::new(),
                c => c.trim_matches('`').to_string(),
            };
            (
                cells[0].trim().trim_matches('`').to_string(),
                contains,
                cells[2].trim().to_string(),
            )
        })
        .collect();
    let code: Vec<(String, String, String)> = tilegraph_vk::SILENCED
        .iter()
        .map(|s| (s.id.into(), s.contains.into(), s.reason.into()))
        .collect();
    assert_eq!(rows, code);
}
