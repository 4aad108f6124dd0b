//! Lint findings of tilegraph's own passes that are the intended state of that pass
//! (`config/accepted_findings.toml`, compiled in): an alpha-tested depth pre-pass discards where
//! it writes depth because that is what a pre-pass for alpha-tested geometry is. The lint still
//! reports them — a tuner sees every state that costs the GPU family something — but counts them
//! apart, each with its reason; tests/e2e/profiles.rs fails on any other finding of a shipped
//! pass, and on a row no frame needs any more.

use serde::{Deserialize, Serialize};

use crate::error::ProfileError;
use crate::lint::Finding;
use crate::select::parse_toml;
use crate::PipelineState;

const FILE: &str = "config/accepted_findings.toml";
const TEXT: &str = include_str!("../../../config/accepted_findings.toml");

/// One accepted finding: a rule, the pipelines it is accepted on, under which profiles, why.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AcceptedFinding {
    /// The rule's state (`discard_with_depth_write`).
    pub rule: PipelineState,
    /// A prefix of the pipeline's name (its fragment shader's, `depth_alpha.frag`).
    pub pipeline: String,
    /// Profile names, or `all`.
    pub profiles: Vec<String>,
    pub reason: String,
}

impl AcceptedFinding {
    /// Whether this row accepts `f`.
    pub fn covers(&self, f: &Finding) -> bool {
        self.rule == f.rule
            && f.pipeline.starts_with(&self.pipeline)
            && self.profiles.iter().any(|p| p == "all" || *p == f.profile)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AcceptedFile {
    accepted: Vec<AcceptedFinding>,
}

/// The accepted findings compiled into the binary.
pub fn accepted_findings() -> Result<Vec<AcceptedFinding>, ProfileError> {
    Ok(parse_toml::<AcceptedFile>(TEXT, FILE)?.accepted)
}

/// The reason `f` is accepted, if a row of `accepted` covers it.
pub fn accepted_reason<'a>(accepted: &'a [AcceptedFinding], f: &Finding) -> Option<&'a str> {
    accepted
        .iter()
        .find(|a| a.covers(f))
        .map(|a| a.reason.as_str())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_compiled_table_parses_and_every_row_has_a_reason() {
        let rows = accepted_findings().unwrap();
        assert!(!rows.is_empty());
        for r in &rows {
            assert!(!r.reason.trim().is_empty(), "{r:?}");
            assert!(!r.profiles.is_empty(), "{r:?}");
        }
    }
}
