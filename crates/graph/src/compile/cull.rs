//! Phase 1, `cull_unused_passes`: keep what an export needs, drop the rest.
//!
//! The roots are the last writer of every exported resource and every pass declared with
//! `Retention::Always`; a pass is kept when a kept pass reads what it wrote (its producer).
//! Everything else is culled, with the reason. This is how tilegraph models only what a scene
//! requires: a pass whose output nobody reads costs nothing.

use crate::declare::{PassDecl, PassId, ResourceId, Retention};
use crate::plan::CullReason;

use super::validate::Analysis;

#[derive(Debug)]
pub(crate) struct Culling {
    /// Per declared pass.
    pub alive: Vec<bool>,
    /// Culled passes in declaration order.
    pub culled: Vec<(PassId, CullReason)>,
}

pub(crate) fn cull_unused_passes(
    analysis: &Analysis,
    passes: &[PassDecl],
    exports: &[ResourceId],
) -> Culling {
    let n = passes.len();
    let mut alive = vec![false; n];
    let mut stack: Vec<usize> = Vec::new();
    fn keep(p: usize, alive: &mut [bool], stack: &mut Vec<usize>) {
        if !alive[p] {
            alive[p] = true;
            stack.push(p);
        }
    }
    for (p, pass) in passes.iter().enumerate() {
        if pass.retention == Retention::Always {
            keep(p, &mut alive, &mut stack);
        }
    }
    for &e in exports {
        if let Some(Some(w)) = analysis.last_writer.get(e.index()) {
            keep(w.index(), &mut alive, &mut stack);
        }
    }
    while let Some(p) = stack.pop() {
        for w in analysis.producers_of(p) {
            keep(w.index(), &mut alive, &mut stack);
        }
    }

    let mut culled = Vec::new();
    if alive.iter().all(|&a| a) {
        return Culling { alive, culled };
    }
    // Consumers of culled passes are culled too (a kept consumer would have kept them).
    let mut consumers: Vec<Vec<PassId>> = vec![Vec::new(); n];
    for (q, _) in passes.iter().enumerate().filter(|(q, _)| !alive[*q]) {
        for w in analysis.producers_of(q) {
            let list = &mut consumers[w.index()];
            if list.last() != Some(&PassId(q as u32)) {
                list.push(PassId(q as u32));
            }
        }
    }
    for p in (0..n).filter(|&p| !alive[p]) {
        let writes = analysis.accesses_of(p).iter().any(|a| a.writes);
        let reason = if !writes {
            CullReason::NoOutputs
        } else if consumers[p].is_empty() {
            CullReason::OutputsUnused
        } else {
            CullReason::ConsumersCulled {
                consumers: std::mem::take(&mut consumers[p]),
            }
        };
        culled.push((PassId(p as u32), reason));
    }
    Culling { alive, culled }
}
