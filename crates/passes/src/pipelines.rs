//! Graphics pipelines cached per render pass and subpass.
//!
//! A pipeline is created against one render pass and stays valid with any compatible one. The
//! executor destroys its render passes when the plan changes, and a driver may give the same
//! handle value to a new, incompatible render pass: the cache is keyed on the render pass's
//! serial ([`RenderPassRef::serial`]), which is never reused, and [`PipelineCache::prune`] drops
//! what was created for render passes that no longer exist.

use std::collections::HashMap;
use std::hash::Hash;

use tilegraph_vk::ash::vk;
use tilegraph_vk::executor::{PassContext, RenderPassRef};
use tilegraph_vk::{Context, VkError};

/// Pipelines by (render pass serial, subpass, `K`): `K` holds what else the pipeline bakes in.
pub(crate) struct PipelineCache<K> {
    pipelines: HashMap<(u64, u32, K), vk::Pipeline>,
}

impl<K> Default for PipelineCache<K> {
    fn default() -> Self {
        PipelineCache {
            pipelines: HashMap::new(),
        }
    }
}

/// The render pass `pc` records into; `what` names the recording in the error when there is
/// none (a compute or transfer pass).
pub(crate) fn render_pass_of(pc: &PassContext<'_>, what: &str) -> Result<RenderPassRef, VkError> {
    pc.render_pass.ok_or_else(|| VkError::Invalid {
        what: pc.pass_name.into(),
        reason: format!("{what} record inside a render pass"),
    })
}

impl<K: Copy + Eq + Hash> PipelineCache<K> {
    pub fn get(&self, rp: RenderPassRef, key: K) -> Option<vk::Pipeline> {
        self.pipelines.get(&(rp.serial, rp.subpass, key)).copied()
    }

    pub fn insert(&mut self, rp: RenderPassRef, key: K, pipeline: vk::Pipeline) {
        self.pipelines
            .insert((rp.serial, rp.subpass, key), pipeline);
    }

    /// Destroys the pipelines made for render passes older than `floor`
    /// ([`Executor::render_pass_serial_floor`](tilegraph_vk::executor::Executor::render_pass_serial_floor)):
    /// those render passes are gone and no frame in flight uses their pipelines.
    pub fn prune(&mut self, ctx: &Context, floor: u64) {
        self.pipelines.retain(|&(serial, _, _), p| {
            let keep = serial >= floor;
            if !keep {
                // SAFETY: no frame in flight uses it (the executor waited before rebuilding).
                unsafe { ctx.device.destroy_pipeline(*p, None) };
            }
            keep
        });
    }

    pub fn len(&self) -> usize {
        self.pipelines.len()
    }

    /// Destroys every pipeline; the GPU must be idle.
    pub fn destroy(self, ctx: &Context) {
        for (_, p) in self.pipelines {
            // SAFETY: the GPU is idle (caller's guarantee).
            unsafe { ctx.device.destroy_pipeline(p, None) };
        }
    }
}
