//! `compile`: declarations in, [`Plan`] out, as a sequence of named phases, each a function
//! from one plain data stage to the next, except that load/store inference feeds the barrier
//! planner one step at a time (`=>`), and merging hands each access to the use summary as it
//! forms the groups (`+`):
//!
//! ```text
//! validate_declarations -> cull_unused_passes -> order_passes -> merge_render_passes + UseSweep
//!   -> residencies -> assign_aliases -> infer_load_store => BarrierPlanner -> estimate_traffic
//! ```
//!
//! Merging comes before load/store inference because "never leaves the render pass" (DONT_CARE
//! store, transient) is a property of the merged render pass; aliasing comes before barriers
//! because memory handed from one resource to another needs a barrier of its own. Load/store
//! inference and barrier planning run step by step together: each render pass is built in place
//! in the plan's steps, and the barriers it needs are written into a slot reserved before it.

pub(crate) mod access;
pub(crate) mod barriers;
mod cull;
mod load_store;
mod merge;
mod order;
mod validate;

use tilegraph_profile::{Architecture, Profile};

use crate::alias::{
    assign_aliases, AliasLifetime, MemoryClass, MemoryNeed, MemoryRequirements,
    ESTIMATED_ALIGNMENT_BYTES,
};
use crate::declare::{
    GraphBuilder, Origin, PassId, ResourceDecl, ResourceDesc, ResourceId, UseKind,
};
use crate::error::GraphError;
use crate::plan::{
    CulledPass, Plan, PlanResource, PlannedPass, Residency, Step, StepIndex, StepRange,
    SubpassIndex, Usage,
};
use crate::traffic::{estimate_traffic, AccessTraffic, Sizes, TrafficModel};
use crate::types::{BufferUsage, ImageUsage};

use access::{push_pass_accesses, role, Access};
use barriers::{step_lifetimes, BarrierPlan, BarrierPlanner, PassAccesses, ResourceSync};
use load_store::{infer_load_store, residencies, LoadStoreInput, StepSink, UseSweep};
use merge::GroupKind;

/// A compiled frame: the plan, and the payloads of the surviving passes.
#[derive(Debug, Clone)]
pub struct CompiledGraph<P> {
    pub plan: Plan,
    /// Indexed by `PassId`; `None` for culled passes (their payloads are dropped) and for
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

/// The graph's memory estimate for a resource (see [`crate::alias`]).
pub fn estimated_requirements(desc: &ResourceDesc) -> MemoryRequirements {
    estimate_of_size(desc.size_bytes())
}

/// The estimate for a resource of `size_bytes` ([`ResourceDesc::size_bytes`]).
fn estimate_of_size(size_bytes: u64) -> MemoryRequirements {
    MemoryRequirements {
        size_bytes,
        alignment_bytes: ESTIMATED_ALIGNMENT_BYTES,
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

fn memory_need(residency: Residency) -> MemoryNeed {
    match residency {
        Residency::Imported | Residency::Unused => MemoryNeed::External,
        Residency::Exported => MemoryNeed::Dedicated(MemoryClass::DeviceLocal),
        Residency::Transient => MemoryNeed::Dedicated(MemoryClass::LazilyAllocated),
        Residency::FrameLocal => MemoryNeed::Shared(MemoryClass::DeviceLocal),
    }
}

fn resource_sync(desc: &ResourceDesc, origin: &Origin) -> ResourceSync {
    ResourceSync {
        is_image: desc.image().is_some(),
        is_depth: desc.image().is_some_and(|d| d.format.is_depth_stencil()),
        import: match origin {
            Origin::Imported(import) => Some(*import),
            Origin::Created => None,
        },
    }
}

/// Per resource: its content must outlive the frame. Exports, and imported content that no
/// surviving pass writes: the frame only read it, and a read must not cost the caller what it
/// imported (a static depth buffer tested by decals would otherwise end with a DONT_CARE store).
fn content_kept_at_end(
    resources: &[ResourceDecl],
    exported: &[bool],
    analysis: &validate::Analysis,
    alive: &[bool],
) -> Vec<bool> {
    let mut kept = exported.to_vec();
    let mut ambiguous = false;
    for (r, decl) in resources.iter().enumerate() {
        // Store ops exist for attachments only, hence images only.
        if kept[r] || decl.desc.image().is_none() || !validate::has_initial_content(decl) {
            continue;
        }
        // The last declared writer tells, unless it was culled (an earlier one may survive).
        match analysis.last_writer[r] {
            None => kept[r] = true,
            Some(w) if alive.get(w.index()).copied().unwrap_or(false) => {}
            Some(_) => {
                kept[r] = true;
                ambiguous = true;
            }
        }
    }
    if ambiguous {
        for (p, _) in alive.iter().enumerate().filter(|(_, &a)| a) {
            for a in analysis.accesses_of(p) {
                if a.writes() && !exported[a.resource.index()] {
                    kept[a.resource.index()] = false;
                }
            }
        }
    }
    kept
}

/// Usage flags from the roles of every surviving access.
fn infer_usage(desc: &ResourceDesc, roles: u16, residency: Residency) -> Usage {
    let has = |kind: UseKind| roles & role(kind) != 0;
    match desc {
        ResourceDesc::Image(_) => {
            let mut u = ImageUsage::NONE;
            if has(UseKind::ColorAttachment { clear: None })
                || has(UseKind::ResolveTarget {
                    source: ResourceId(0),
                })
            {
                u |= ImageUsage::COLOR_ATTACHMENT;
            }
            if has(UseKind::DepthStencilAttachment { clear: None })
                || has(UseKind::DepthStencilReadOnly)
            {
                u |= ImageUsage::DEPTH_STENCIL_ATTACHMENT;
            }
            if has(UseKind::InputAttachment) {
                u |= ImageUsage::INPUT_ATTACHMENT;
            }
            if has(UseKind::Sampled) {
                u |= ImageUsage::SAMPLED;
            }
            if has(UseKind::StorageRead)
                || has(UseKind::StorageWrite)
                || has(UseKind::StorageReadWrite)
            {
                u |= ImageUsage::STORAGE;
            }
            if has(UseKind::TransferSrc) {
                u |= ImageUsage::TRANSFER_SRC;
            }
            if has(UseKind::TransferDst) {
                u |= ImageUsage::TRANSFER_DST;
            }
            if residency == Residency::Transient {
                u |= ImageUsage::TRANSIENT_ATTACHMENT;
            }
            Usage::Image(u)
        }
        ResourceDesc::Buffer(_) => {
            let mut u = BufferUsage::NONE;
            if has(UseKind::Uniform) {
                u |= BufferUsage::UNIFORM_BUFFER;
            }
            if has(UseKind::StorageRead)
                || has(UseKind::StorageWrite)
                || has(UseKind::StorageReadWrite)
            {
                u |= BufferUsage::STORAGE_BUFFER;
            }
            if has(UseKind::Vertex) {
                u |= BufferUsage::VERTEX_BUFFER;
            }
            if has(UseKind::Index) {
                u |= BufferUsage::INDEX_BUFFER;
            }
            if has(UseKind::Indirect) {
                u |= BufferUsage::INDIRECT_BUFFER;
            }
            if has(UseKind::ConditionalPredicate) {
                u |= BufferUsage::CONDITIONAL_RENDERING;
            }
            if has(UseKind::TransferSrc) {
                u |= BufferUsage::TRANSFER_SRC;
            }
            if has(UseKind::TransferDst) {
                u |= BufferUsage::TRANSFER_DST;
            }
            Usage::Buffer(u)
        }
    }
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

fn compile<P>(graph: GraphBuilder<P>, profile: &Profile) -> Result<CompiledGraph<P>, GraphError> {
    let GraphBuilder {
        resources,
        passes,
        payloads,
        exports,
        dependencies,
    } = graph;
    let n_resources = resources.len();

    let analysis =
        validate::validate_declarations(&resources, &passes, &exports, &dependencies, profile)?;
    let culling = cull::cull_unused_passes(&analysis, &passes, &exports);
    let order = order::order_passes(
        &analysis,
        &passes,
        n_resources,
        &culling.alive,
        &dependencies,
        profile,
    )?;
    let sizes = Sizes::of(resources.iter().map(|r| &r.desc));
    let mut access_traffic = AccessTraffic::new(&sizes);
    let mut sweep = UseSweep::new(n_resources, analysis.accesses.len(), &mut access_traffic);
    let groups =
        merge::merge_render_passes(&order, &analysis, &passes, n_resources, profile, &mut sweep);
    let mut exported = vec![false; n_resources];
    for e in &exports {
        exported[e.index()] = true;
    }
    let uses = sweep.finish(&content_kept_at_end(
        &resources,
        &exported,
        &analysis,
        &culling.alive,
    ));
    let residency = residencies(&uses, &groups, &resources, &exported, profile);
    // Aliasing runs on group numbers: steps are numbered later, and the assignment depends only
    // on the order of lifetimes.
    // `estimated_requirements`, from the sizes the traffic tally already holds.
    let requirements: Vec<MemoryRequirements> =
        sizes.whole().iter().map(|&s| estimate_of_size(s)).collect();
    let alias_input: Vec<AliasLifetime> = uses
        .resources
        .iter()
        .zip(&residency)
        .map(|(u, &res)| AliasLifetime {
            lifetime: u.lifetime().map(|(first, last)| StepRange {
                first: StepIndex(first),
                last: StepIndex(last),
            }),
            memory: memory_need(res),
        })
        .collect();
    let aliasing = assign_aliases(&alias_input, &requirements)?;

    let sync: Vec<ResourceSync> = resources
        .iter()
        .map(|r| resource_sync(&r.desc, &r.origin))
        .collect();
    let pass_accesses = PassAccesses {
        accesses: &analysis.accesses,
        ranges: &analysis.pass_ranges,
    };
    // Load/store inference hands each work step to the barrier planner as it is built.
    let flushes = groups.iter().filter(|g| g.flush_before).count();
    let mut planner = BarrierPlanner::new(&pass_accesses, &sync, &aliasing, groups.len() + flushes);
    infer_load_store(
        &LoadStoreInput {
            groups: &groups,
            order: &order,
            analysis: &analysis,
            passes: &passes,
            resources: &resources,
            residency: &residency,
            uses: &uses,
            store_op_none: profile.render_pass.store_op_none,
        },
        &mut planner,
        &mut access_traffic,
    );
    let BarrierPlan {
        steps,
        work_steps,
        final_states: finals,
    } = planner.finish();
    // Groups and work steps correspond one to one, in order.
    let step_of = |group: u32| {
        work_steps
            .get(group as usize)
            .copied()
            .unwrap_or(StepIndex(0))
    };
    let lifetimes: Vec<Option<StepRange>> = uses
        .resources
        .iter()
        .map(|u| {
            u.lifetime().map(|(first, last)| StepRange {
                first: step_of(first),
                last: step_of(last),
            })
        })
        .collect();

    let mut payload_slots: Vec<Option<P>> = payloads.into_iter().map(Some).collect();
    // Names and uses move from the declarations into the plan; nothing is copied.
    let mut passes = passes;
    // Each group is one work step; a render group's passes are its subpasses, in order.
    let mut planned: Vec<PlannedPass> = Vec::with_capacity(order.len());
    for (g, group) in groups.iter().enumerate() {
        let step = step_of(g as u32);
        for (k, &id) in order[group.start..group.end].iter().enumerate() {
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
                step,
                subpass: (group.kind == GroupKind::Render).then_some(SubpassIndex(k as u32)),
            });
        }
    }
    let mut culled = Vec::with_capacity(culling.culled.len());
    for (id, reason) in culling.culled {
        if let Some(slot) = payload_slots.get_mut(id.index()) {
            *slot = None;
        }
        let Some(d) = passes.get_mut(id.index()) else {
            continue;
        };
        culled.push(CulledPass {
            id,
            name: std::mem::take(&mut d.name),
            kind: d.kind,
            class: d.class,
            coverage: d.coverage,
            uses: std::mem::take(&mut d.uses),
            reason,
        });
    }

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
            final_state: finals[i],
        })
        .collect();

    let model = match profile.gpu.architecture {
        Architecture::Tiler => TrafficModel::Tiler,
        Architecture::Immediate => TrafficModel::Immediate,
    };
    let traffic = estimate_traffic(
        model,
        &planned,
        &plan_resources,
        &pass_accesses,
        access_traffic,
    );

    Ok(CompiledGraph {
        plan: Plan {
            profile: profile.name.clone(),
            tile_budget_bytes_per_px: tile_budget_bytes_per_px(profile),
            passes: planned,
            culled,
            resources: plan_resources,
            steps,
            aliasing,
            traffic,
        },
        payloads: payload_slots,
    })
}

/// Re-derives every planned pass's accesses (indexed by `PassId`) from its declared uses.
fn plan_accesses(plan: &Plan) -> (Vec<Access>, Vec<(u32, u32)>) {
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
    (accesses, ranges)
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
        let (accesses, ranges) = plan_accesses(self);
        let pass_accesses = PassAccesses {
            accesses: &accesses,
            ranges: &ranges,
        };
        let sync: Vec<ResourceSync> = self
            .resources
            .iter()
            .map(|r| resource_sync(&r.desc, &r.origin))
            .collect();
        let mut planner = BarrierPlanner::new(&pass_accesses, &sync, &aliasing, self.passes.len());
        for step in std::mem::take(&mut self.steps) {
            planner.push(step);
        }
        let BarrierPlan { steps, .. } = planner.finish();
        let lifetimes = step_lifetimes(&steps, &pass_accesses, self.resources.len());
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
        // Every declared pass is planned or culled, so ids stay below their total.
        let declared = self.passes.len() + self.culled.len();
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
