//! The state lint: every rule of every embedded profile fires on a pass built to break it, and
//! stays quiet on a clean pass; scopes and ordering behave as documented.

use tilegraph_profile::lint::{
    lint, ColorWrites, DepthCompare, DrawState, Finding, LintDraw, LintRenderPass, StencilUse,
};
use tilegraph_profile::{PipelineState, Profile, ProfileSet, StateScope};

fn profile(name: &str) -> Profile {
    ProfileSet::embedded().unwrap().get(name).unwrap().clone()
}

fn opaque(name: &str) -> DrawState {
    DrawState::opaque(name, DepthCompare::Greater)
}

fn pass(draws: Vec<DrawState>) -> LintRenderPass {
    LintRenderPass {
        index: 0,
        draws: draws
            .into_iter()
            .map(|state| LintDraw {
                pass: "bad".into(),
                state,
            })
            .collect(),
    }
}

/// A render pass whose draws break `state`, and the index of the draw that breaks it.
fn bad_pass(state: PipelineState) -> (LintRenderPass, usize) {
    let mut bad = opaque("bad.frag");
    let draws = match state {
        PipelineState::DiscardWithDepthWrite => {
            bad.discard = true;
            vec![opaque("first"), bad]
        }
        PipelineState::ShaderDepthWrite => {
            bad.shader_depth_write = true;
            vec![bad]
        }
        PipelineState::BlendWithDepthWrite => {
            bad.blend = true;
            vec![bad]
        }
        PipelineState::PartialColorMask => {
            bad.color_writes = ColorWrites::Partial;
            vec![opaque("first"), bad, opaque("after")]
        }
        PipelineState::DepthCompareDirectionChange => {
            bad.depth_compare = DepthCompare::Less;
            vec![opaque("reverse-z"), bad, opaque("after")]
        }
        PipelineState::StencilDependsOnDepth => {
            bad.stencil = StencilUse::DependsOnDepth;
            vec![bad]
        }
        PipelineState::FragmentSideEffects => {
            bad.storage_writes = true;
            vec![bad]
        }
        PipelineState::MrtStateMismatch => {
            bad.attachments_differ = true;
            vec![bad]
        }
        PipelineState::OccluderAfterBlend => {
            let mut blended = opaque("blended");
            blended.blend = true;
            blended.depth_write = false;
            vec![blended, bad]
        }
        PipelineState::OccluderAfterDiscard => {
            let mut alpha = opaque("alpha");
            alpha.discard = true;
            vec![alpha, bad]
        }
        PipelineState::AlphaToCoverage => {
            bad.alpha_to_coverage = true;
            bad.depth_write = false;
            vec![bad]
        }
        PipelineState::SecondaryCommandBuffer => {
            bad.secondary_command_buffer = true;
            vec![bad]
        }
    };
    let at = draws.iter().position(|d| d.pipeline == "bad.frag").unwrap();
    (pass(draws), at)
}

#[test]
fn every_rule_of_every_profile_fires_on_its_bad_pass() {
    let set = ProfileSet::embedded().unwrap();
    let mut fired = 0;
    for p in set.profiles() {
        for rule in &p.state_rules {
            let (rp, at) = bad_pass(rule.state);
            let findings = lint(p, std::slice::from_ref(&rp));
            let hit = findings
                .iter()
                .find(|f| f.rule == rule.state && f.draw == at)
                .unwrap_or_else(|| {
                    panic!(
                        "{}: rule {} did not fire at draw {at}: {findings:#?}",
                        p.name,
                        rule.state.name()
                    )
                });
            assert_eq!(hit.effect, rule.effect);
            assert_eq!(hit.source, rule.source);
            assert_eq!(hit.pipeline, "bad.frag");
            assert_eq!(hit.profile, p.name);
            if rule.scope == StateScope::RestOfRenderPass {
                assert_eq!(hit.later_draws, rp.draws.len() - at - 1);
            }
            fired += 1;
        }
    }
    assert!(fired > 40, "only {fired} rules");
}

#[test]
fn a_clean_frame_has_no_findings_under_any_profile() {
    // Depth pre-pass (no colour), opaque colour testing EQUAL, blended last without depth
    // writes: the order and states every profile asks for.
    let mut prepass = opaque("depth.vert");
    prepass.color_writes = ColorWrites::None;
    let mut colour = opaque("forward_early.frag");
    colour.depth_write = false;
    colour.depth_compare = DepthCompare::Equal;
    colour.early_fragment_tests = true;
    let mut blended = opaque("forward_early.frag blended");
    blended.blend = true;
    blended.depth_write = false;
    let rp = pass(vec![prepass, colour, blended]);
    for p in ProfileSet::embedded().unwrap().profiles() {
        let findings = lint(p, std::slice::from_ref(&rp));
        assert!(findings.is_empty(), "{}: {findings:#?}", p.name);
    }
}

#[test]
fn lrz_off_for_the_rest_of_the_pass_is_reported_once_with_the_draws_it_reaches() {
    // adreno-6xx: a compare direction change mid-pass turns LRZ off until the pass ends.
    let p = profile("adreno-6xx");
    let mut less = opaque("less");
    less.depth_compare = DepthCompare::Less;
    let rp = pass(vec![
        opaque("a"),
        less.clone(),
        opaque("b"),
        less,
        opaque("c"),
    ]);
    let findings = lint(&p, std::slice::from_ref(&rp));
    let dir: Vec<&Finding> = findings
        .iter()
        .filter(|f| f.rule == PipelineState::DepthCompareDirectionChange)
        .collect();
    assert_eq!(dir.len(), 1, "{dir:#?}");
    assert_eq!((dir[0].draw, dir[0].later_draws), (1, 3));
    let text = dir[0].to_string();
    assert!(
        text.contains("depth_compare_direction_change")
            && text.contains("disables_lrz")
            && text.contains("3 draws after it"),
        "{text}"
    );
    // A direction change without depth writes does not count (turnip: that draw only).
    let mut untouched = rp.clone();
    for d in &mut untouched.draws[1..] {
        d.state.depth_write = false;
    }
    assert!(lint(&p, &[untouched])
        .iter()
        .all(|f| f.rule != PipelineState::DepthCompareDirectionChange));
}

#[test]
fn only_depth_writing_draws_set_the_direction() {
    // A depth-tested box that writes nothing (an occlusion query) in the other direction:
    // turnip keeps the direction of the draws that write depth.
    let p = profile("adreno-6xx");
    let mut query = opaque("oq_box");
    query.depth_compare = DepthCompare::LessOrEqual;
    query.depth_write = false;
    query.color_writes = ColorWrites::None;
    assert!(lint(&p, &[pass(vec![query, opaque("a")])]).is_empty());
}

#[test]
fn the_rule_is_per_render_pass() {
    let p = profile("adreno-6xx");
    let mut less = opaque("less");
    less.depth_compare = DepthCompare::Less;
    let mut first = pass(vec![opaque("a")]);
    first.index = 0;
    let mut second = pass(vec![less]);
    second.index = 1;
    assert!(lint(&p, &[first, second]).is_empty());
}

#[test]
fn directionless_compares_do_not_count_as_a_change() {
    let p = profile("adreno-6xx");
    let mut equal = opaque("equal");
    equal.depth_compare = DepthCompare::Equal;
    equal.depth_write = false;
    let mut untested = opaque("untested");
    untested.depth_test = false;
    untested.depth_compare = DepthCompare::Less;
    assert!(lint(&p, &[pass(vec![opaque("a"), equal, untested])]).is_empty());
}

#[test]
fn side_effects_with_early_fragment_tests_are_fine() {
    let mut flags = opaque("raster_occlusion.frag");
    flags.storage_writes = true;
    flags.early_fragment_tests = true;
    flags.depth_write = false;
    flags.color_writes = ColorWrites::None;
    for p in ProfileSet::embedded().unwrap().profiles() {
        let findings = lint(p, &[pass(vec![flags.clone()])]);
        assert!(findings.is_empty(), "{}: {findings:#?}", p.name);
    }
}

#[test]
fn every_rule_names_its_source() {
    for p in ProfileSet::embedded().unwrap().profiles() {
        for r in &p.state_rules {
            assert!(!r.source.trim().is_empty(), "{}: {:?}", p.name, r.state);
        }
    }
}
