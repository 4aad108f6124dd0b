//! `Plan::reassign_aliases`: the executor's second placement of memory, with the driver's real
//! `VkMemoryRequirements` instead of compile's estimates. Aliasing and barrier planning run
//! again on the finished plan (the same phases as in compile); the render passes and the
//! traffic estimate stay as compiled.

use crate::declare::{PassId, UseKind};
use crate::error::GraphError;
use crate::plan::{MemoryRequirements, Plan, Queue, Residency, Step};

use super::access::{push_pass_accesses, PassAccesses};
use super::alias::assign_aliases;
use super::barriers::{plan_barriers, step_lifetimes, BarrierPlan, ResourceSync};
use super::locate_passes;
use super::queues::{plan_submissions, SubmissionInput};

/// Re-derives every planned pass's accesses (indexed by `PassId`) from its declared uses.
fn plan_accesses(plan: &Plan) -> PassAccesses {
    let max_id = plan
        .passes
        .iter()
        .map(|p| p.id.index() + 1)
        .max()
        .unwrap_or(0);
    let mut ranges = vec![(0u32, 0u32); max_id];
    let mut accesses = Vec::new();
    for p in &plan.passes {
        let start = accesses.len() as u32;
        // Validated at compile time: a conflict cannot occur here; if it did, the pass would
        // simply keep the accesses summarized so far.
        let _ = push_pass_accesses(
            p.kind,
            p.coverage,
            &p.uses,
            |id| plan.resources.get(id.index()).map(|r| &r.desc),
            &mut accesses,
        );
        ranges[p.id.index()] = (start, accesses.len() as u32);
    }
    PassAccesses { accesses, ranges }
}

impl Plan {
    /// Re-runs aliasing with the real `VkMemoryRequirements` (one per resource, index =
    /// `ResourceId`; the executor must fold `bufferImageGranularity` into the alignments) and
    /// rebuilds the barriers the new placement needs. Memory slots, lifetimes' step numbers and
    /// each pass's step are updated; passes, render passes and traffic are unchanged.
    pub fn reassign_aliases(
        &mut self,
        requirements: &[MemoryRequirements],
    ) -> Result<(), GraphError> {
        self.check_consistency()?;
        let aliasing = assign_aliases(&self.alias_lifetimes(), requirements)?;
        let accesses = plan_accesses(self);
        let sync: Vec<ResourceSync> = self
            .resources
            .iter()
            .map(|r| ResourceSync::of(&r.desc, &r.origin))
            .collect();
        let work = std::mem::take(&mut self.steps);
        let BarrierPlan { steps, .. } = plan_barriers(work, &accesses, &sync, &aliasing);
        let mut queue_of = vec![Queue::Graphics; self.passes.len() + self.pruned.len()];
        for p in &self.passes {
            if let Some(q) = queue_of.get_mut(p.id.index()) {
                *q = p.queue;
            }
        }
        let kept_at_end: Vec<bool> = self
            .resources
            .iter()
            .map(|r| matches!(r.residency, Residency::Exported | Residency::Imported))
            .collect();
        let (steps, submissions) = plan_submissions(
            steps,
            &SubmissionInput {
                queue_of: &queue_of,
                accesses: &accesses,
                resources: &sync,
                kept_at_end: &kept_at_end,
                sharing: self.queue_sharing,
            },
        );
        self.submissions = submissions;
        let lifetimes = step_lifetimes(&steps, &accesses, self.resources.len());
        for (i, r) in self.resources.iter_mut().enumerate() {
            r.lifetime = lifetimes[i];
            r.memory = aliasing.slots[i];
        }
        locate_passes(&steps, &mut self.passes);
        self.steps = steps;
        self.aliasing = aliasing;
        Ok(())
    }

    /// The plan's fields are public: before rebuilding from them, make sure every index points
    /// at something (a hand-edited plan gets an error, not a panic).
    fn check_consistency(&self) -> Result<(), GraphError> {
        let invalid = |reason| Err(GraphError::InvalidPlan { reason });
        let n = self.resources.len();
        if self
            .resources
            .iter()
            .enumerate()
            .any(|(i, r)| r.id.index() != i)
        {
            return invalid("resource ids are not their indices");
        }
        // Every declared pass is planned or pruned, so ids stay below their total.
        let declared = self.passes.len() + self.pruned.len();
        if self.passes.iter().any(|p| p.id.index() >= declared) {
            return invalid("a pass id is larger than the number of passes");
        }
        let mut known = vec![false; declared];
        for p in &self.passes {
            known[p.id.index()] = true;
            let unknown = p.uses.iter().any(|u| {
                u.resource.index() >= n
                    || matches!(u.kind, UseKind::ResolveTarget { source } if source.index() >= n)
            });
            if unknown {
                return invalid("a pass uses an unknown resource");
            }
        }
        let is_known = |id: PassId| known.get(id.index()).copied().unwrap_or(false);
        // Per resource: the last step that attaches it.
        let mut attached_in = vec![usize::MAX; n];
        for (i, step) in self.steps.iter().enumerate() {
            match step {
                Step::RenderPass(rp) => {
                    for a in &rp.attachments {
                        let Some(seen) = attached_in.get_mut(a.resource.index()) else {
                            return invalid("a render pass attaches an unknown resource");
                        };
                        // The barrier planner keeps one state per resource and attachment.
                        if *seen == i {
                            return invalid("a render pass attaches a resource twice");
                        }
                        *seen = i;
                    }
                    if rp.subpasses.iter().any(|s| !is_known(s.pass)) {
                        return invalid("a subpass records an unknown pass");
                    }
                }
                Step::Compute { pass } | Step::Transfer { pass } if !is_known(*pass) => {
                    return invalid("a step records an unknown pass");
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The memory estimates compile used (index = `ResourceId`).
    pub fn estimated_requirements(&self) -> Vec<MemoryRequirements> {
        self.resources
            .iter()
            .map(|r| MemoryRequirements {
                size_bytes: r.estimated_size_bytes,
                alignment_bytes: r.estimated_alignment_bytes,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    /// Two independent chains, one after the other, each with a frame-local image.
    fn two_chains() -> GraphBuilder<()> {
        let mut g = GraphBuilder::new();
        let out = swapchain(&mut g);
        let mut prev = None;
        for i in 0..3 {
            let tmp = rgba8(&mut g, &format!("tmp{i}"));
            g.raster_pass(format!("draw{i}"), PassClass::Post, ())
                .color_clear(tmp, ClearColor::BLACK);
            let mut use_pass = g.raster_pass(format!("use{i}"), PassClass::Post, ());
            use_pass.sampled(tmp).color(out);
            if prev.is_none() {
                use_pass.coverage(Coverage::Full);
            }
            prev = Some(tmp);
        }
        g
    }

    #[test]
    fn the_plan_alias_assignment_is_what_assign_aliases_gives_for_its_lifetimes() {
        let plan = compile(two_chains(), &desktop());
        assert_eq!(plan.aliasing.blocks.len(), 1, "{plan}");
        assert_eq!(plan.aliasing.saved_bytes(), 2 * PIXELS * 4);
        let again = assign_aliases(&plan.alias_lifetimes(), &plan.estimated_requirements());
        assert_eq!(again.as_ref(), Ok(&plan.aliasing));
    }

    #[test]
    fn reassigning_with_real_requirements_rebuilds_slots_and_barriers() {
        let mut plan = compile(two_chains(), &desktop());
        let before = plan.clone();
        // Same numbers: nothing changes.
        plan.reassign_aliases(&plan.estimated_requirements())
            .unwrap();
        assert_eq!(plan, before);

        // Real requirements that forbid sharing (tmp1 needs more than the block holds and a
        // large alignment): still valid, new placement.
        let mut real = plan.estimated_requirements();
        let tmp1 = plan.resource_by_name("tmp1").map(|r| r.id.index()).unwrap();
        real[tmp1] = MemoryRequirements {
            size_bytes: 3 * PIXELS * 4,
            alignment_bytes: 4096,
        };
        plan.reassign_aliases(&real).unwrap();
        assert_eq!(
            plan.resources[tmp1].memory.map(|m| m.size_bytes),
            Some(3 * PIXELS * 4)
        );
        for a in &plan.resources {
            for b in &plan.resources {
                if let (Some(sa), Some(sb), Some(la), Some(lb)) =
                    (a.memory, b.memory, a.lifetime, b.lifetime)
                {
                    if a.id != b.id && la.overlaps(lb) {
                        assert!(!sa.overlaps(&sb), "{} and {} overlap", a.name, b.name);
                    }
                }
            }
        }
        assert!(plan
            .passes
            .iter()
            .all(|p| plan.steps[p.step.index()].is_work()));
        assert_eq!(
            plan.reassign_aliases(&real[1..]),
            Err(GraphError::AliasInputMismatch {
                lifetimes: plan.resources.len(),
                requirements: plan.resources.len() - 1
            })
        );
    }

    #[test]
    fn a_hand_edited_plan_gets_an_error_not_a_panic() {
        let mut plan = compile(two_chains(), &desktop());
        let requirements = plan.estimated_requirements();
        plan.passes[0].uses[0].resource = ResourceId(999);
        assert_eq!(
            plan.reassign_aliases(&requirements),
            Err(GraphError::InvalidPlan {
                reason: "a pass uses an unknown resource"
            })
        );
        let mut plan = compile(two_chains(), &desktop());
        plan.passes.pop();
        assert_eq!(
            plan.reassign_aliases(&requirements),
            Err(GraphError::InvalidPlan {
                reason: "a subpass records an unknown pass"
            })
        );
        let mut plan = compile(two_chains(), &desktop());
        let twice = plan.render_passes().next().map(|(step, _)| step.index());
        if let Some(Step::RenderPass(rp)) = twice.and_then(|i| plan.steps.get_mut(i)) {
            let first = rp.attachments[0].clone();
            rp.attachments.push(first);
        }
        assert_eq!(
            plan.reassign_aliases(&requirements),
            Err(GraphError::InvalidPlan {
                reason: "a render pass attaches a resource twice"
            })
        );
        // A huge id is rejected before anything is sized by it.
        let mut plan = compile(two_chains(), &desktop());
        plan.passes[0].id = PassId(u32::MAX);
        assert_eq!(
            plan.reassign_aliases(&requirements),
            Err(GraphError::InvalidPlan {
                reason: "a pass id is larger than the number of passes"
            })
        );
    }

    #[test]
    fn exported_resources_get_memory_of_their_own() {
        let mut g = GraphBuilder::new();
        let history = rgba8(&mut g, "next_history");
        let tmp = rgba8(&mut g, "tmp");
        g.export(history);
        g.raster_pass("draw", PassClass::Post, ())
            .color_clear(tmp, ClearColor::BLACK);
        g.raster_pass("resolve", PassClass::Post, ())
            .sampled(tmp)
            .color(history)
            .coverage(Coverage::Full);
        let plan = compile(g, &desktop());
        let slot = |name| plan.resource_by_name(name).and_then(|r| r.memory);
        let (Some(h), Some(t)) = (slot("next_history"), slot("tmp")) else {
            panic!("no memory:\n{plan}")
        };
        assert_ne!(h.block, t.block);
        assert_eq!(
            plan.aliasing
                .blocks
                .iter()
                .filter(|b| b.class == MemoryClass::DeviceLocal)
                .count(),
            2
        );
    }

    #[test]
    fn compiling_twice_gives_the_same_plan() {
        assert_eq!(
            compile(two_chains(), &tiler()),
            compile(two_chains(), &tiler())
        );
    }
}
