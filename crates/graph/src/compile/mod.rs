//! `compile`: declarations in, [`Plan`] out, as a list of named phases, each a function from
//! plain data to plain data in the file of its name:
//!
//! ```text
//! validate_declarations -> trace_dataflow -> prune_unused_passes -> order_passes (and
//!   assign_queues) -> merge_render_passes -> resource_lifetimes -> residencies
//!   -> assign_aliases -> infer_load_store -> plan_barriers -> plan_submissions
//!   -> (the plan) -> estimate_traffic
//! ```
//!
//! Merging comes before load/store inference because "never leaves the render pass" (DONT_CARE
//! store, transient) is a property of the merged render pass; aliasing comes before barriers
//! because memory handed from one resource to another needs a barrier of its own. The plan's
//! types sit below every phase (`crate::plan`); a phase reads what earlier phases returned and
//! nothing else, so each can be read, and tested, on its own.

mod access;
mod alias;
mod barriers;
mod dataflow;
mod lifetimes;
mod load_store;
mod merge;
mod order;
mod prune;
mod queues;
mod reassign;
mod traffic;
mod validate;

pub use alias::assign_aliases;

use tilegraph_profile::{Architecture, Profile};

use crate::declare::{GraphBuilder, PassId, ResourceDecl, ResourceDesc, ResourceId};
use crate::error::GraphError;
use crate::plan::{
    AliasLifetime, MemoryClass, MemoryNeed, MemoryRequirements, Plan, PlanResource, PlannedPass,
    PrunedPass, Queue, Residency, Step, StepIndex, StepRange, SubpassIndex, TrafficModel,
    ESTIMATED_ALIGNMENT_BYTES,
};

use barriers::{plan_barriers, step_lifetimes, BarrierPlan, ResourceSync};
use lifetimes::{content_kept_at_end, infer_usage, residencies, resource_lifetimes, ResourceUses};
use load_store::{infer_load_store, LoadStoreInput};
use prune::Pruning;
use queues::{plan_submissions, SubmissionInput};

/// A compiled frame: the plan, and the payloads of the surviving passes.
#[derive(Debug, Clone)]
pub struct CompiledGraph<P> {
    pub plan: Plan,
    /// Indexed by `PassId`; `None` for pruned passes (their payloads are dropped) and for
    /// payloads already taken.
    payloads: Vec<Option<P>>,
}

impl<P> CompiledGraph<P> {
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    pub fn payload(&self, pass: PassId) -> Option<&P> {
        self.payloads.get(pass.index()).and_then(Option::as_ref)
    }

    pub fn payload_mut(&mut self, pass: PassId) -> Option<&mut P> {
        self.payloads.get_mut(pass.index()).and_then(Option::as_mut)
    }

    /// Moves a payload out (e.g. an `FnOnce` recording callback).
    pub fn take_payload(&mut self, pass: PassId) -> Option<P> {
        self.payloads.get_mut(pass.index()).and_then(Option::take)
    }

    /// The plan and the payloads indexed by `PassId` (`None`: pruned, or taken).
    pub fn into_plan_and_payloads(self) -> (Plan, Vec<Option<P>>) {
        (self.plan, self.payloads)
    }

    /// The plan and the payloads in execution order (`plan.passes[i]` owns `payloads[i]`).
    pub fn into_parts(self) -> (Plan, Vec<(PassId, P)>) {
        let mut payloads = self.payloads;
        let ordered = self
            .plan
            .passes
            .iter()
            .filter_map(|p| {
                payloads
                    .get_mut(p.id.index())
                    .and_then(Option::take)
                    .map(|payload| (p.id, payload))
            })
            .collect();
        (self.plan, ordered)
    }
}

impl<P> GraphBuilder<P> {
    /// Compiles the declared frame for `profile`. Deterministic: the same declarations and
    /// profile give an identical plan.
    pub fn compile(self, profile: &Profile) -> Result<CompiledGraph<P>, GraphError> {
        compile(self, profile)
    }
}

/// The graph's memory estimate for a resource (see `compile/alias.rs`): its size, aligned to
/// [`ESTIMATED_ALIGNMENT_BYTES`].
pub fn estimated_requirements(desc: &ResourceDesc) -> MemoryRequirements {
    MemoryRequirements {
        size_bytes: desc.size_bytes(),
        alignment_bytes: ESTIMATED_ALIGNMENT_BYTES,
    }
}

fn compile<P>(graph: GraphBuilder<P>, profile: &Profile) -> Result<CompiledGraph<P>, GraphError> {
    let GraphBuilder {
        resources,
        passes,
        payloads,
        exports,
        dependencies,
    } = graph;
    let n_resources = resources.len();
    let mut exported = vec![false; n_resources];
    for e in &exports {
        if let Some(x) = exported.get_mut(e.index()) {
            *x = true;
        }
    }

    let validated =
        validate::validate_declarations(&resources, &passes, &exports, &dependencies, profile)?;
    let accesses = &validated.accesses;
    let dataflow = dataflow::trace_dataflow(&resources, &passes, accesses, &exports)?;
    let pruning = prune::prune_unused_passes(&dataflow, accesses, &passes, &exports);
    let order::Ordered { order, queue_of } = order::order_passes(
        accesses,
        &dataflow,
        &passes,
        n_resources,
        &pruning.alive,
        &dependencies,
        profile,
    )?;
    let async_queue = resources_on(
        Queue::AsyncCompute,
        &queue_of,
        &order,
        accesses,
        n_resources,
    );
    let (groups, merges) =
        merge::merge_render_passes(&order, &validated, &passes, n_resources, profile);
    let kept_at_end =
        content_kept_at_end(&resources, &exported, &dataflow, &pruning.alive, accesses);
    let uses = resource_lifetimes(&groups, &order, accesses, n_resources, &kept_at_end);
    let residency = residencies(&uses, &groups, &resources, &exported, profile);
    let requirements: Vec<MemoryRequirements> = resources
        .iter()
        .map(|r| estimated_requirements(&r.desc))
        .collect();
    // Aliasing runs on group numbers: steps are numbered later, and the assignment depends only
    // on the order of lifetimes.
    let aliasing = assign_aliases(
        &alias_lifetimes(&uses, &residency, &async_queue),
        &requirements,
    )?;
    let work = infer_load_store(&LoadStoreInput {
        groups: &groups,
        order: &order,
        accesses,
        passes: &passes,
        resources: &resources,
        residency: &residency,
        uses: &uses,
        store_op_none: profile.render_pass.store_op_none,
    });
    let sync: Vec<ResourceSync> = resources
        .iter()
        .map(|r| ResourceSync::of(&r.desc, &r.origin))
        .collect();
    let BarrierPlan {
        steps,
        final_states,
    } = plan_barriers(work, accesses, &sync, &aliasing);
    let (steps, submissions) = plan_submissions(
        steps,
        &SubmissionInput {
            queue_of: &queue_of,
            accesses,
            resources: &sync,
            kept_at_end: &kept_at_end,
            sharing: profile.queues.sharing,
        },
    );

    let lifetimes = step_lifetimes(&steps, accesses, n_resources);
    let (planned, pruned, payloads) =
        planned_passes(&steps, &order, (passes, &queue_of), payloads, pruning);
    let plan_resources: Vec<PlanResource> = resources
        .into_iter()
        .enumerate()
        .map(|(i, ResourceDecl { name, desc, origin })| PlanResource {
            id: ResourceId(i as u32),
            name,
            desc,
            origin,
            residency: residency[i],
            usage: infer_usage(&desc, uses.resources[i].roles, residency[i]),
            lifetime: lifetimes[i],
            memory: aliasing.slots[i],
            estimated_size_bytes: requirements[i].size_bytes,
            estimated_alignment_bytes: requirements[i].alignment_bytes,
            final_state: final_states[i],
            async_queue: async_queue[i],
        })
        .collect();
    let model = match profile.gpu.architecture {
        Architecture::Tiler => TrafficModel::Tiler,
        Architecture::Immediate => TrafficModel::Immediate,
    };
    let traffic = traffic::estimate_traffic(model, &steps, &planned, &plan_resources, accesses);

    Ok(CompiledGraph {
        plan: Plan {
            profile: profile.name.clone(),
            tile_budget_bytes_per_px: tile_budget_bytes_per_px(profile),
            passes: planned,
            pruned,
            resources: plan_resources,
            steps,
            aliasing,
            traffic,
            merges,
            submissions,
            queue_sharing: profile.queues.sharing,
            async_compute: profile.queues.async_compute,
        },
        payloads,
    })
}

/// Per resource: whether a surviving pass on `queue` uses it.
fn resources_on(
    queue: Queue,
    queue_of: &[Queue],
    order: &[PassId],
    accesses: &access::PassAccesses,
    n_resources: usize,
) -> Vec<bool> {
    let mut on = vec![false; n_resources];
    for &p in order {
        if queue_of.get(p.index()) == Some(&queue) {
            for a in accesses.of(p) {
                if let Some(x) = on.get_mut(a.resource.index()) {
                    *x = true;
                }
            }
        }
    }
    on
}

/// What aliasing places: each resource's first and last group, and the memory it needs (its
/// own where the async queue uses it).
fn alias_lifetimes(
    uses: &ResourceUses,
    residency: &[Residency],
    async_queue: &[bool],
) -> Vec<AliasLifetime> {
    uses.resources
        .iter()
        .zip(residency)
        .zip(async_queue)
        .map(|((u, &res), &on_async)| AliasLifetime {
            lifetime: u.lifetime().map(|(first, last)| StepRange {
                first: StepIndex(first),
                last: StepIndex(last),
            }),
            memory: match res {
                Residency::Imported | Residency::Unused => MemoryNeed::External,
                Residency::Exported => MemoryNeed::Dedicated(MemoryClass::DeviceLocal),
                Residency::Transient => MemoryNeed::Dedicated(MemoryClass::LazilyAllocated),
                Residency::FrameLocal if on_async => {
                    MemoryNeed::Dedicated(MemoryClass::DeviceLocal)
                }
                Residency::FrameLocal => MemoryNeed::Shared(MemoryClass::DeviceLocal),
            },
        })
        .collect()
}

/// The surviving passes in execution order, each at its step and subpass; the pruned ones
/// with their reasons; and the payloads of the survivors (names and uses move from the
/// declarations into the plan: nothing is copied).
fn planned_passes<P>(
    steps: &[Step],
    order: &[PassId],
    (mut passes, queue_of): (Vec<crate::declare::PassDecl>, &[Queue]),
    payloads: Vec<P>,
    pruning: Pruning,
) -> (Vec<PlannedPass>, Vec<PrunedPass>, Vec<Option<P>>) {
    let mut planned: Vec<PlannedPass> = Vec::with_capacity(order.len());
    for &id in order {
        let Some(d) = passes.get_mut(id.index()) else {
            continue;
        };
        planned.push(PlannedPass {
            id,
            name: std::mem::take(&mut d.name),
            kind: d.kind,
            class: d.class,
            coverage: d.coverage,
            retention: d.retention,
            uses: std::mem::take(&mut d.uses),
            step: StepIndex(0),
            subpass: None,
            queue: queue_of.get(id.index()).copied().unwrap_or(Queue::Graphics),
            async_capable: d.async_capable,
        });
    }
    locate_passes(steps, &mut planned);
    let mut payloads: Vec<Option<P>> = payloads.into_iter().map(Some).collect();
    let mut pruned = Vec::with_capacity(pruning.pruned.len());
    for (id, reason) in pruning.pruned {
        if let Some(slot) = payloads.get_mut(id.index()) {
            *slot = None;
        }
        let Some(d) = passes.get_mut(id.index()) else {
            continue;
        };
        pruned.push(PrunedPass {
            id,
            name: std::mem::take(&mut d.name),
            kind: d.kind,
            class: d.class,
            coverage: d.coverage,
            uses: std::mem::take(&mut d.uses),
            reason,
        });
    }
    (planned, pruned, payloads)
}

/// Sets each planned pass's step and subpass from the steps.
fn locate_passes(steps: &[Step], passes: &mut [PlannedPass]) {
    let max_id = passes.iter().map(|p| p.id.index() + 1).max().unwrap_or(0);
    let mut slot = vec![usize::MAX; max_id];
    for (i, p) in passes.iter().enumerate() {
        slot[p.id.index()] = i;
    }
    let mut set = |id: PassId, step: usize, subpass: Option<SubpassIndex>| {
        if let Some(&i) = slot.get(id.index()) {
            if let Some(p) = passes.get_mut(i) {
                p.step = StepIndex(step as u32);
                p.subpass = subpass;
            }
        }
    };
    for (i, step) in steps.iter().enumerate() {
        match step {
            Step::RenderPass(rp) => {
                for (s, sub) in rp.subpasses.iter().enumerate() {
                    set(sub.pass, i, Some(SubpassIndex(s as u32)));
                }
            }
            Step::Compute { pass } | Step::Transfer { pass } => set(*pass, i, None),
            Step::Barriers(_) | Step::Flush(_) => {}
        }
    }
}

/// Bytes of tile memory per pixel, from the profile's tile model (tilers only).
fn tile_budget_bytes_per_px(profile: &Profile) -> Option<u32> {
    let gpu = &profile.gpu;
    let pixels = u64::from(gpu.tile_width_px) * u64::from(gpu.tile_height_px);
    if !profile.is_tiler() || pixels == 0 {
        return None;
    }
    Some(u32::try_from(gpu.tile_memory_bytes / pixels).unwrap_or(u32::MAX))
}
