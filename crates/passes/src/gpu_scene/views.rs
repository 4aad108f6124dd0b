//! A view's part of the scene's sets: per frame slot its camera uniforms, its fragment
//! counters and its sets 0 (plain, and culled once its GPU culling exists); its shadow atlas;
//! its region of the entry buffer for its CPU list.

use ash::vk;
use tilegraph_vk::ash;
use tilegraph_vk::pipeline::allocate_set;
use tilegraph_vk::{Buffer, Context, VkError};

use super::shadow_atlas::ShadowAtlas;
use super::{buffer, no_slot, view_specs, FrameUniforms, GpuScene};

/// A view's buffers and sets in one frame slot.
pub(super) struct ViewBuffers {
    pub(super) uniforms: Buffer,
    /// `Counters` of `forward_count.frag`: fragments shaded per material class.
    pub(super) counters: Buffer,
    pub(super) set: vk::DescriptorSet,
    /// Set 0 for GPU-culled draws (binding 2 = the culling shader's draw list).
    pub(super) culled_set: Option<vk::DescriptorSet>,
}

impl ViewBuffers {
    pub(super) fn destroy(self, ctx: &Context) {
        ctx.destroy_buffer(self.uniforms);
        ctx.destroy_buffer(self.counters);
    }
}

fn no_view(view: usize) -> VkError {
    VkError::Invalid {
        what: "scene view".into(),
        reason: format!("{view} out of range"),
    }
}

impl GpuScene {
    /// View `view`'s buffers and plain set in slot `i` (the set written with the slot's).
    pub(super) fn view_buffers(
        &self,
        ctx: &Context,
        i: u32,
        view: usize,
    ) -> Result<ViewBuffers, VkError> {
        let [(un, us, uu, um), (cn, cs, cu, cm)] = view_specs();
        let uniforms = buffer(ctx, &format!("{un}[{view}][{i}]"), us, uu, um)?;
        let counters = match buffer(ctx, &format!("{cn}[{view}][{i}]"), cs, cu, cm) {
            Ok(b) => b,
            Err(e) => {
                ctx.destroy_buffer(uniforms);
                return Err(e);
            }
        };
        let mut v = ViewBuffers {
            uniforms,
            counters,
            set: vk::DescriptorSet::null(),
            culled_set: None,
        };
        match allocate_set(ctx, self.pool, self.set_layout) {
            Ok(set) => v.set = set,
            Err(e) => {
                v.destroy(ctx);
                return Err(e);
            }
        }
        Ok(v)
    }

    /// Views the sets are made for.
    pub fn views(&self) -> usize {
        self.atlases.len()
    }

    /// Makes `view` the one whose sets [`Self::set`] and [`Self::culled_set`] give (the
    /// renderer does, before a pass of that view records).
    pub fn enter_view(&mut self, view: usize) {
        debug_assert!(view < self.atlases.len());
        self.view = view;
    }

    /// The current view.
    pub fn current_view(&self) -> usize {
        self.view
    }

    /// View `view`'s shadow atlas.
    pub fn atlas(&self, view: usize) -> Option<&ShadowAtlas> {
        self.atlases.get(view)
    }

    /// Creates, per frame slot, the set that the current view's GPU-culled draws bind: the
    /// same as its plain one but with the draw list its culling shader writes (`draw_ids`)
    /// and, with cluster culling, its runs' first triangles (`runs`).
    pub fn add_culled_sets(
        &mut self,
        ctx: &Context,
        draw_ids: vk::Buffer,
        runs: Option<vk::Buffer>,
    ) -> Result<(), VkError> {
        let view = self.view;
        let entry = self
            .culled_draw_ids
            .get_mut(view)
            .ok_or_else(|| no_view(view))?;
        *entry = Some((draw_ids, runs));
        for i in 0..self.frames.len() {
            let set = allocate_set(ctx, self.pool, self.set_layout)?;
            if let Some(v) = self.frames[i].views.get_mut(view) {
                v.culled_set = Some(set);
            }
            self.write_sets(ctx, &self.frames[i]);
        }
        Ok(())
    }

    /// The current view's culled-draw set of a frame slot (after [`Self::add_culled_sets`]).
    pub fn culled_set(&self, slot: usize) -> Option<vk::DescriptorSet> {
        self.frames
            .get(slot)
            .and_then(|f| f.views.get(self.view))
            .and_then(|v| v.culled_set)
    }

    /// The current view's descriptor set (set 0) of a frame slot.
    pub fn set(&self, slot: usize) -> Option<vk::DescriptorSet> {
        self.frames
            .get(slot)
            .and_then(|f| f.views.get(self.view))
            .map(|v| v.set)
    }

    /// Writes view `view`'s uniforms and CPU list (`cpu_entries`: instance ids from
    /// [`super::Capacity::cpu_base_of`] the view) into `slot`, and zeroes its counters.
    pub fn write_view(
        &mut self,
        ctx: &Context,
        slot: usize,
        view: usize,
        uniforms: &FrameUniforms,
        cpu_entries: &[u32],
    ) -> Result<(), VkError> {
        if cpu_entries.len() as u64 > u64::from(self.capacity.instances) {
            return Err(VkError::Invalid {
                what: "scene buffers".into(),
                reason: format!(
                    "a CPU list of {} entries past the {} instance slots",
                    cpu_entries.len(),
                    self.capacity.instances
                ),
            });
        }
        let base = self.capacity.cpu_base_of(view) as usize * 4;
        let f = self.frames.get_mut(slot).ok_or_else(|| no_slot(slot))?;
        ctx.write_mapped(&mut f.entries, base, bytemuck::cast_slice(cpu_entries))?;
        let v = f.views.get_mut(view).ok_or_else(|| no_view(view))?;
        ctx.write_mapped(&mut v.uniforms, 0, bytemuck::bytes_of(uniforms))?;
        ctx.write_mapped(&mut v.counters, 0, &[0u8; 16])?;
        Ok(())
    }

    /// Fragments shaded per material class (opaque, alpha-tested, blended) by view `view` in
    /// the frame last recorded into `slot`, when it counted them (`forward_count.frag`). Call
    /// after the frame completed.
    pub fn fragment_counts(
        &self,
        ctx: &Context,
        slot: usize,
        view: usize,
    ) -> Result<[u32; 3], VkError> {
        let f = self.frames.get(slot).ok_or_else(|| no_slot(slot))?;
        let v = f.views.get(view).ok_or_else(|| no_view(view))?;
        ctx.invalidate_mapped(&v.counters)?;
        let m = v.counters.mapped().ok_or_else(|| VkError::Invalid {
            what: "fragment counters".into(),
            reason: "not host-visible".into(),
        })?;
        let word =
            |i: usize| u32::from_le_bytes([m[4 * i], m[4 * i + 1], m[4 * i + 2], m[4 * i + 3]]);
        Ok([word(0), word(1), word(2)])
    }
}
