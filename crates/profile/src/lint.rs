//! The state lint: a profile's [`StateRule`]s applied to the draws a frame records.
//!
//! Tilers and deferred GPUs remove hidden fragments before shading — Adreno's LRZ, Mali's
//! Forward Pixel Kill, PowerVR's hidden-surface removal — but a handful of pipeline states
//! switch that off for one draw or, on Adreno, for the rest of the render pass. Which states
//! matter is vendor guidance, kept as data in each profile (`[[state_rules]]`, every rule with
//! its source). This module is the check: each render pass of a frame is a list of
//! [`DrawState`]s in recording order (what `tilegraph-vk` derives from the pipelines it creates,
//! or what an engine describes for its own draws), and [`lint`] reports every rule that fires,
//! where, and how far the damage reaches.

use std::fmt;

use serde::Serialize;

use crate::{PipelineState, Profile, StateEffect, StateRule, StateScope};

/// A depth compare, as `VkCompareOp` spells it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthCompare {
    Never,
    Less,
    Equal,
    LessOrEqual,
    Greater,
    NotEqual,
    GreaterOrEqual,
    Always,
}

/// Which way a depth compare lets fragments through: what a low-resolution depth structure
/// (Adreno's LRZ) is built for. EQUAL, NOT_EQUAL, ALWAYS and NEVER have no direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CompareDirection {
    /// LESS / LESS_OR_EQUAL: nearer is smaller (standard depth).
    Smaller,
    /// GREATER / GREATER_OR_EQUAL: nearer is larger (reverse-Z).
    Larger,
}

impl DepthCompare {
    pub fn direction(self) -> Option<CompareDirection> {
        match self {
            DepthCompare::Less | DepthCompare::LessOrEqual => Some(CompareDirection::Smaller),
            DepthCompare::Greater | DepthCompare::GreaterOrEqual => Some(CompareDirection::Larger),
            _ => None,
        }
    }
}

/// Which colour channels a draw writes, over all its colour attachments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ColorWrites {
    /// No colour attachment or an empty mask everywhere (depth-only, side-effect-only).
    None,
    All,
    /// A mask that is neither all channels nor none on some attachment.
    Partial,
}

/// How a draw uses stencil.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StencilUse {
    Off,
    /// Stencil tested or written with results that do not depend on the depth test.
    Independent,
    /// A depth-fail operation other than KEEP: the stencil result depends on the depth test.
    DependsOnDepth,
}

/// What the lint knows of one draw (or run of draws under one pipeline): the pipeline state
/// and the facts of its fragment shader.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize)]
pub struct DrawState {
    /// The pipeline, named by its shaders, for the findings.
    pub pipeline: String,
    pub depth_test: bool,
    pub depth_write: bool,
    pub depth_compare: DepthCompare,
    pub blend: bool,
    pub color_writes: ColorWrites,
    /// Colour attachments with differing write masks or blend states.
    pub attachments_differ: bool,
    /// The fragment shader can discard (`OpKill`, `OpTerminateInvocation`, demote) under the
    /// pipeline's specialization.
    pub discard: bool,
    pub alpha_to_coverage: bool,
    /// The fragment shader writes `gl_FragDepth`.
    pub shader_depth_write: bool,
    /// The fragment shader writes storage buffers or images, or does atomics on them.
    pub storage_writes: bool,
    /// The fragment shader declares `early_fragment_tests`.
    pub early_fragment_tests: bool,
    pub stencil: StencilUse,
    /// Recorded in a secondary command buffer.
    pub secondary_command_buffer: bool,
}

impl DrawState {
    /// An opaque draw: depth tested nearer-passes (`compare`) and written, every colour channel
    /// written, no blending, a fragment shader without discard, depth writes or side effects.
    pub fn opaque(pipeline: impl Into<String>, compare: DepthCompare) -> Self {
        DrawState {
            pipeline: pipeline.into(),
            depth_test: true,
            depth_write: true,
            depth_compare: compare,
            blend: false,
            color_writes: ColorWrites::All,
            attachments_differ: false,
            discard: false,
            alpha_to_coverage: false,
            shader_depth_write: false,
            storage_writes: false,
            early_fragment_tests: false,
            stencil: StencilUse::Off,
            secondary_command_buffer: false,
        }
    }

    /// Whether the draw occludes what is behind it in the hidden-surface structure: it writes
    /// depth, and neither blending nor a discard makes its coverage uncertain.
    pub fn occluder(&self) -> bool {
        self.depth_write && !self.blend && !self.discard && !self.alpha_to_coverage
    }

    /// Whether `state` holds of this draw, given the draws recorded before it in the same
    /// render pass.
    pub fn has(&self, state: PipelineState, earlier: &[&DrawState]) -> bool {
        match state {
            PipelineState::DiscardWithDepthWrite => {
                (self.discard || self.alpha_to_coverage) && self.depth_write
            }
            PipelineState::ShaderDepthWrite => self.shader_depth_write,
            PipelineState::BlendWithDepthWrite => self.blend && self.depth_write,
            PipelineState::PartialColorMask => {
                self.color_writes == ColorWrites::Partial && self.depth_write
            }
            PipelineState::DepthCompareDirectionChange => {
                let (true, Some(dir)) = (self.depth_write, self.direction()) else {
                    return false;
                };
                // Only depth-writing draws set the direction (turnip's `prev_direction`).
                earlier
                    .iter()
                    .filter(|d| d.depth_write)
                    .filter_map(|d| d.direction())
                    .any(|d| d != dir)
            }
            PipelineState::StencilDependsOnDepth => self.stencil == StencilUse::DependsOnDepth,
            PipelineState::FragmentSideEffects => self.storage_writes && !self.early_fragment_tests,
            PipelineState::MrtStateMismatch => self.attachments_differ && self.depth_write,
            PipelineState::OccluderAfterBlend => {
                self.occluder()
                    && earlier
                        .iter()
                        .any(|d| d.blend && d.color_writes != ColorWrites::None)
            }
            PipelineState::OccluderAfterDiscard => {
                self.occluder() && earlier.iter().any(|d| d.discard || d.alpha_to_coverage)
            }
            PipelineState::AlphaToCoverage => self.alpha_to_coverage,
            PipelineState::SecondaryCommandBuffer => self.secondary_command_buffer,
        }
    }

    /// The compare direction of a depth-tested draw.
    fn direction(&self) -> Option<CompareDirection> {
        self.depth_test
            .then(|| self.depth_compare.direction())
            .flatten()
    }
}

/// One draw of a render pass: the graph pass that recorded it and its state.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct LintDraw {
    pub pass: String,
    pub state: DrawState,
}

/// One render pass of a frame, its draws in recording order (across its subpasses).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct LintRenderPass {
    /// Its index in the compiled plan's render passes.
    pub index: usize,
    pub draws: Vec<LintDraw>,
}

/// A rule that fired.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Finding {
    pub profile: String,
    pub rule: PipelineState,
    pub effect: StateEffect,
    pub scope: StateScope,
    /// The render pass (plan index) and the draw within it.
    pub render_pass: usize,
    pub draw: usize,
    pub pass: String,
    pub pipeline: String,
    /// Draws after this one in the render pass that lose the optimisation too
    /// ([`StateScope::RestOfRenderPass`]); 0 otherwise.
    pub later_draws: usize,
    pub note: String,
    /// Where the rule comes from (a key of docs/PROFILES.md's sources, or `unsourced`).
    pub source: String,
    /// Why the state is intended, where `config/accepted_findings.toml` accepts it for this
    /// pipeline and profile ([`crate::accepted`]); `None`: a finding to act on.
    pub accepted: Option<String>,
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "render pass {} draw {} ({}, {}): {} -> {}",
            self.render_pass,
            self.draw,
            self.pass,
            self.pipeline,
            self.rule.name(),
            self.effect.name()
        )?;
        if self.later_draws > 0 {
            write!(f, " for it and the {} draws after it", self.later_draws)?;
        }
        write!(f, " — {} [{}]", self.note, self.source)
    }
}

/// Applies `profile`'s state rules to a frame's render passes. A rule whose damage lasts for
/// the rest of the render pass is reported once per render pass, at the draw that triggers
/// it, with the count of later draws it reaches; a per-draw rule at every draw it fires on.
///
/// Each render pass is linted on its own. On Adreno, turnip keeps LRZ invalid until the depth
/// is cleared, so damage done in a render pass whose depth a later one loads (two-phase
/// culling's second depth pass) reaches further than reported; the shipped frames clear depth
/// in their first render pass and trigger no such rule.
pub fn lint(profile: &Profile, render_passes: &[LintRenderPass]) -> Vec<Finding> {
    let mut findings = Vec::new();
    let mut earlier: Vec<&DrawState> = Vec::new();
    for rp in render_passes {
        earlier.clear();
        let mut reported: Vec<(PipelineState, StateEffect)> = Vec::new();
        for (i, draw) in rp.draws.iter().enumerate() {
            for rule in &profile.state_rules {
                if !draw.state.has(rule.state, &earlier) {
                    continue;
                }
                let later_draws = match rule.scope {
                    StateScope::Draw => 0,
                    StateScope::RestOfRenderPass
                        if reported.contains(&(rule.state, rule.effect)) =>
                    {
                        continue
                    }
                    StateScope::RestOfRenderPass => {
                        reported.push((rule.state, rule.effect));
                        rp.draws.len() - i - 1
                    }
                };
                findings.push(finding(profile, rule, rp.index, i, draw, later_draws));
            }
            earlier.push(&draw.state);
        }
    }
    findings
}

fn finding(
    profile: &Profile,
    rule: &StateRule,
    render_pass: usize,
    draw: usize,
    at: &LintDraw,
    later_draws: usize,
) -> Finding {
    Finding {
        profile: profile.name.clone(),
        rule: rule.state,
        effect: rule.effect,
        scope: rule.scope,
        render_pass,
        draw,
        pass: at.pass.clone(),
        pipeline: at.state.pipeline.clone(),
        later_draws,
        note: rule.note.clone(),
        source: rule.source.clone(),
        accepted: None,
    }
}
