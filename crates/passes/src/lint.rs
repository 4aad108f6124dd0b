//! The state lint over a recorded frame: every pipeline bound while the frame recorded (traced
//! by [`Pipelines`](crate::pipelines::Pipelines)), grouped by the plan's render passes in
//! recording order, checked against the profile's state rules
//! ([`tilegraph_profile::lint`]). What is checked is what was recorded: the states come from
//! the pipelines' own descriptions and their shaders' SPIR-V.

use serde::Serialize;
use tilegraph_graph::Plan;
use tilegraph_profile::accepted::{accepted_findings, accepted_reason};
use tilegraph_profile::lint::{lint, Finding, LintDraw, LintRenderPass};
use tilegraph_profile::Profile;

use crate::pipelines::TracedBind;

/// A frame's draws by render pass, and what the profile's rules found in them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FrameLint {
    pub profile: String,
    pub render_passes: Vec<LintRenderPass>,
    pub findings: Vec<Finding>,
}

impl FrameLint {
    /// One line for a frame report: how many findings, and of which rules.
    pub fn summary(&self) -> String {
        let draws: usize = self.render_passes.iter().map(|r| r.draws.len()).sum();
        if self.findings.is_empty() {
            return format!(
                "lint ({}): clean, {draws} pipeline binds in {} render passes",
                self.profile,
                self.render_passes.len()
            );
        }
        let accepted = self.accepted_count();
        let open = self.findings.len() - accepted;
        if open == 0 {
            let s = if accepted == 1 { "" } else { "s" };
            return format!(
                "lint ({}): clean but {accepted} accepted finding{s} (the passes' intended state; `tilegraph lint` says why), {draws} pipeline binds",
                self.profile
            );
        }
        let mut rules: Vec<&str> = self
            .findings
            .iter()
            .filter(|f| f.accepted.is_none())
            .map(|f| f.rule.name())
            .collect();
        rules.sort_unstable();
        rules.dedup();
        format!(
            "lint ({}): {open} findings over {draws} pipeline binds ({}), {accepted} more accepted; `tilegraph lint` lists them",
            self.profile,
            rules.join(", ")
        )
    }

    /// Findings `config/accepted_findings.toml` accepts (the pass's intended state).
    pub fn accepted_count(&self) -> usize {
        self.findings
            .iter()
            .filter(|f| f.accepted.is_some())
            .count()
    }
}

/// Groups `trace` by the render pass of `plan` each bind recorded in (numbered as the plan
/// orders its render passes) and lints it under `profile`.
pub fn lint_frame(profile: &Profile, plan: &Plan, trace: &[TracedBind]) -> FrameLint {
    let mut render_passes: Vec<LintRenderPass> = plan
        .render_passes()
        .enumerate()
        .map(|(index, _)| LintRenderPass {
            index,
            draws: Vec::new(),
        })
        .collect();
    let owner = |pass| {
        plan.render_passes()
            .position(|(_, rp)| rp.subpasses.iter().any(|s| s.pass == pass))
    };
    for bind in trace {
        // Graphics pipelines bind inside render passes only (`render_pass_of`).
        if let Some(rp) = owner(bind.pass).and_then(|i| render_passes.get_mut(i)) {
            rp.draws.push(LintDraw {
                pass: bind.pass_name.clone(),
                state: (*bind.state).clone(),
            });
        }
    }
    render_passes.retain(|rp| !rp.draws.is_empty());
    let mut findings = lint(profile, &render_passes);
    // The compiled-in table parses (a unit test of tilegraph-profile holds it); were it not to,
    // every finding would simply show as one to act on.
    let accepted = accepted_findings().unwrap_or_default();
    for f in &mut findings {
        f.accepted = accepted_reason(&accepted, f).map(str::to_string);
    }
    FrameLint {
        profile: profile.name.clone(),
        render_passes,
        findings,
    }
}
