//! [`PlanCache`]: a frame declared again with the same declarations reuses the plan compiled
//! for them. An engine declares its graph every frame (the passes' payloads capture that frame's
//! state), but the declarations — resources, passes, uses, exports, dependencies — change only
//! when the frame's structure does; comparing them with the last frame's costs a walk over the
//! declarations, compiling them the whole of `compile`.

use std::sync::Arc;

use tilegraph_profile::Profile;

use crate::declare::{GraphBuilder, PassDecl, PassId, ResourceDecl, ResourceId};
use crate::error::GraphError;
use crate::plan::Plan;

/// What a frame's graph declared, without its payloads.
#[derive(Debug, Clone, PartialEq)]
struct Declarations {
    resources: Vec<ResourceDecl>,
    passes: Vec<PassDecl>,
    exports: Vec<ResourceId>,
    dependencies: Vec<(PassId, PassId)>,
}

/// A compiled frame: the plan (shared with the frames that reuse it) and the payloads indexed
/// by [`PassId`] (`None` for pruned passes).
#[derive(Debug)]
pub struct CachedFrame<P> {
    pub plan: Arc<Plan>,
    pub payloads: Vec<Option<P>>,
    /// The plan is the last frame's: nothing was compiled.
    pub reused: bool,
}

/// Compiles frames, reusing the last plan while the declarations and the profile stay the same.
#[derive(Debug, Default)]
pub struct PlanCache {
    last: Option<(Declarations, Profile, Arc<Plan>)>,
}

impl PlanCache {
    pub fn new() -> Self {
        PlanCache::default()
    }

    /// The plan of `graph` for `profile`: the last one when the declarations equal the last
    /// frame's, else compiled now (and kept for the next frame).
    pub fn compile<P>(
        &mut self,
        graph: GraphBuilder<P>,
        profile: &Profile,
    ) -> Result<CachedFrame<P>, GraphError> {
        let GraphBuilder {
            resources,
            passes,
            payloads,
            exports,
            dependencies,
        } = graph;
        if let Some((d, p, plan)) = &self.last {
            let same = d.resources == resources
                && d.passes == passes
                && d.exports == exports
                && d.dependencies == dependencies
                && p == profile;
            if same {
                let mut payloads: Vec<Option<P>> = payloads.into_iter().map(Some).collect();
                for pruned in &plan.pruned {
                    if let Some(slot) = payloads.get_mut(pruned.id.index()) {
                        *slot = None;
                    }
                }
                return Ok(CachedFrame {
                    plan: Arc::clone(plan),
                    payloads,
                    reused: true,
                });
            }
        }
        let declarations = Declarations {
            resources: resources.clone(),
            passes: passes.clone(),
            exports: exports.clone(),
            dependencies: dependencies.clone(),
        };
        // A failed compile forgets the last plan: the next frame compiles again.
        self.last = None;
        let compiled = GraphBuilder {
            resources,
            passes,
            payloads,
            exports,
            dependencies,
        }
        .compile(profile)?;
        let (plan, payloads) = compiled.into_plan_and_payloads();
        let plan = Arc::new(plan);
        self.last = Some((declarations, profile.clone(), Arc::clone(&plan)));
        Ok(CachedFrame {
            plan,
            payloads,
            reused: false,
        })
    }

    /// Forgets the last plan (the next frame compiles).
    pub fn clear(&mut self) {
        self.last = None;
    }
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    /// Payloads `base + 1`, `base + 2` (and `base + 3` for the debug pass).
    fn frame(with_debug: bool, base: u32) -> GraphBuilder<u32> {
        let mut g = GraphBuilder::new();
        let out = swapchain(&mut g);
        let tmp = rgba8(&mut g, "tmp");
        g.raster_pass("draw", PassClass::Opaque, base + 1)
            .color_clear(tmp, ClearColor::BLACK);
        g.raster_pass("post", PassClass::Post, base + 2)
            .sampled(tmp)
            .color(out)
            .coverage(Coverage::Full);
        if with_debug {
            // Nobody reads it: pruned, its payload dropped.
            let dbg = rgba8(&mut g, "debug");
            g.raster_pass("debug", PassClass::Other, base + 3)
                .sampled(tmp)
                .color(dbg)
                .coverage(Coverage::Full);
        }
        g
    }

    #[test]
    fn the_same_declarations_reuse_the_plan_and_take_the_new_payloads() {
        let profile = tiler();
        let mut cache = PlanCache::new();
        let first = cache.compile(frame(true, 0), &profile).unwrap();
        assert!(!first.reused);
        assert_eq!(first.payloads, [Some(1), Some(2), None]);
        let second = cache.compile(frame(true, 10), &profile).unwrap();
        assert!(second.reused);
        assert!(std::sync::Arc::ptr_eq(&first.plan, &second.plan));
        assert_eq!(second.payloads, [Some(11), Some(12), None]);
        assert_eq!(*second.plan, frame(true, 0).compile(&profile).unwrap().plan);
    }

    #[test]
    fn other_declarations_or_another_profile_compile_again() {
        let mut cache = PlanCache::new();
        let a = cache.compile(frame(true, 0), &tiler()).unwrap();
        let b = cache.compile(frame(false, 0), &tiler()).unwrap();
        assert!(!b.reused);
        assert_ne!(*a.plan, *b.plan);
        assert_eq!(*b.plan, frame(false, 0).compile(&tiler()).unwrap().plan);
        let c = cache.compile(frame(false, 0), &desktop()).unwrap();
        assert!(!c.reused);
        assert_eq!(c.plan.profile, desktop().name);
        // A frame that fails to compile forgets the plan.
        let mut bad = frame(false, 0);
        let ghost = rgba8(&mut bad, "ghost");
        let out = rgba8(&mut bad, "out");
        bad.raster_pass("reads-what-nobody-wrote", PassClass::Post, 9)
            .sampled(ghost)
            .color(out);
        bad.export(out);
        assert!(cache.compile(bad, &desktop()).is_err());
        assert!(!cache.compile(frame(false, 0), &desktop()).unwrap().reused);
    }
}
