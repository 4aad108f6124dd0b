//! The resident geometry: meshes added at run time staged per slot and copied at the start of
//! the frame ([`GeometryUpload`]), buffers grown on the GPU, replaced ones destroyed once the
//! frames that read them are done.

use ash::vk;
use tilegraph_profile::MemoryUse;
use tilegraph_scene::{Change, Scene};
use tilegraph_vk::ash;
use tilegraph_vk::{Buffer, Context, VkError};

use super::{buffer, no_slot, GpuScene};

/// One pending copy into the resident geometry.
#[derive(Debug, Clone, Copy)]
pub(super) struct Copy {
    src: vk::Buffer,
    dst: vk::Buffer,
    region: vk::BufferCopy,
    /// A growth's copy of the old buffer (queued before the staged ranges that land on it).
    growth: bool,
}

/// Uploads `bytes` into a new buffer of `usage` in the static-geometry memory type, through a
/// staging copy where that memory is not host-visible (waits for the copy: for data made
/// once, before any frame).
pub(crate) fn upload(
    ctx: &Context,
    name: &str,
    bytes: &[u8],
    usage: vk::BufferUsageFlags,
) -> Result<Buffer, VkError> {
    upload_sized(ctx, name, bytes, bytes.len() as u64, usage)
}

/// [`upload`] into a buffer of `size` bytes (at least the data).
pub(super) fn upload_sized(
    ctx: &Context,
    name: &str,
    bytes: &[u8],
    size: u64,
    usage: vk::BufferUsageFlags,
) -> Result<Buffer, VkError> {
    let size = size.max(bytes.len() as u64).max(4);
    let mut buffer = ctx.create_buffer(
        name,
        size,
        usage | vk::BufferUsageFlags::TRANSFER_DST | vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryUse::StaticGeometry,
    )?;
    if bytes.is_empty() {
        return Ok(buffer);
    }
    if buffer.mapped().is_some() {
        return match ctx.write_mapped(&mut buffer, 0, bytes) {
            Ok(()) => Ok(buffer),
            Err(e) => {
                ctx.destroy_buffer(buffer);
                Err(e)
            }
        };
    }
    let mut staging = match ctx.create_buffer(
        &format!("{name} staging"),
        bytes.len() as u64,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryUse::Staging,
    ) {
        Ok(s) => s,
        Err(e) => {
            ctx.destroy_buffer(buffer);
            return Err(e);
        }
    };
    let copied = match ctx.write_mapped(&mut staging, 0, bytes) {
        Ok(()) => ctx.submit_and_wait(|cb| {
            let region = vk::BufferCopy {
                src_offset: 0,
                dst_offset: 0,
                size: bytes.len() as u64,
            };
            // SAFETY: both buffers are live and at least `region.size` bytes.
            unsafe {
                ctx.device
                    .cmd_copy_buffer(cb, staging.raw, buffer.raw, &[region])
            };
            Ok(())
        }),
        Err(e) => Err(e),
    };
    ctx.destroy_buffer(staging);
    match copied {
        Ok(()) => Ok(buffer),
        Err(e) => {
            ctx.destroy_buffer(buffer);
            Err(e)
        }
    }
}

pub(super) const GEOMETRY_USAGE: vk::BufferUsageFlags =
    vk::BufferUsageFlags::from_raw(vk::BufferUsageFlags::STORAGE_BUFFER.as_raw());

/// Room for `n` elements of a growing array: at least `n`, and a quarter more than that.
pub(super) fn grown(n: u64) -> u64 {
    (n + n / 4).max(64)
}

impl GpuScene {
    /// Stages the geometry the scene added since the last frame, growing the resident buffers
    /// (on the GPU) when it outgrew them.
    pub(super) fn sync_geometry(
        &mut self,
        ctx: &Context,
        slot: usize,
        scene: &Scene,
    ) -> Result<(), VkError> {
        // Copies staged for a frame that was never recorded (prepared twice) may have held a
        // growth's copy of the old content: stage everything again.
        if !self.copies.is_empty() {
            self.geometry_cursor = None;
        }
        self.copies.clear();
        self.staged.clear();
        let vertex_bytes = std::mem::size_of_val(scene.vertices()) as u64;
        let index_bytes = std::mem::size_of_val(scene.indices()) as u64;
        let changes = self.geometry_cursor.and_then(|c| scene.changes_since(c));
        self.geometry_cursor = Some(scene.cursor());
        let grow_vertices = vertex_bytes > self.vertices.size;
        let tail_bytes = self.index_tails.iter().sum::<u64>() * 4;
        let grow_indices = index_bytes + tail_bytes > self.indices.size;
        let everything = changes.is_none_or(|l| l.contains(&Change::Everything));
        if grow_vertices {
            self.grow(ctx, true, grown(vertex_bytes / 32) * 32)?;
        }
        if grow_indices {
            self.grow(ctx, false, grown(index_bytes / 4) * 4 + tail_bytes)?;
        }
        let vertices: &[u8] = bytemuck::cast_slice(scene.vertices());
        let indices: &[u8] = bytemuck::cast_slice(scene.indices());
        let (vb, ib) = (self.vertices.raw, self.indices.raw);
        if everything {
            self.stage(vb, 0, vertices);
            self.stage(ib, 0, indices);
        } else if let Some(list) = changes {
            // Each range once, from what the arrays hold now: copies whose destinations
            // overlap (a range written twice, or freed and taken again, within a frame) would
            // race in the transfer.
            let (mut v, mut i) = (Vec::new(), Vec::new());
            for &c in list {
                match c {
                    Change::Vertices { start, len } => v.push((start, start + len)),
                    Change::Indices { start, len } => i.push((start, start + len)),
                    _ => {}
                }
            }
            for (start, end) in merged(v) {
                let (s, e) = (start as usize * 32, end as usize * 32);
                if let Some(bytes) = vertices.get(s..e) {
                    self.stage(vb, s as u64, bytes);
                }
            }
            for (start, end) in merged(i) {
                let (s, e) = (start as usize * 4, end as usize * 4);
                if let Some(bytes) = indices.get(s..e) {
                    self.stage(ib, s as u64, bytes);
                }
            }
        }
        if self.staged.is_empty() {
            return Ok(());
        }
        let f = self.frames.get_mut(slot).ok_or_else(|| no_slot(slot))?;
        let needed = self.staged.len() as u64;
        if f.staging.as_ref().is_none_or(|s| s.size < needed) {
            let new = buffer(
                ctx,
                &format!("geometry staging[{slot}]"),
                grown(needed),
                vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryUse::Streaming,
            )?;
            // The slot's previous frame (the only one that read it) is complete.
            if let Some(old) = f.staging.replace(new) {
                ctx.destroy_buffer(old);
            }
        }
        let Some(staging) = f.staging.as_mut() else {
            return Err(no_slot(slot));
        };
        ctx.write_mapped(staging, 0, &self.staged)?;
        let src = staging.raw;
        for c in &mut self.copies {
            if c.src == vk::Buffer::null() {
                c.src = src;
            }
        }
        Ok(())
    }

    /// Queues a copy of `bytes` (through the slot's staging buffer) to `dst` at `offset`.
    fn stage(&mut self, dst: vk::Buffer, offset: u64, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        let src_offset = self.staged.len() as u64;
        self.staged.extend_from_slice(bytes);
        // Copy offsets into a buffer need no alignment but 4 for 4-byte elements (as here).
        self.copies.push(Copy {
            src: vk::Buffer::null(),
            dst,
            region: vk::BufferCopy {
                src_offset,
                dst_offset: offset,
                size: bytes.len() as u64,
            },
            growth: false,
        });
    }

    /// Replaces the vertex (`vertices`) or index buffer by one of `size` bytes; the old content
    /// is copied on the GPU before this frame's other copies, and the old buffer goes once the
    /// frames in flight are done with it.
    fn grow(&mut self, ctx: &Context, vertices: bool, size: u64) -> Result<(), VkError> {
        let (name, usage) = if vertices {
            ("scene vertices", vk::BufferUsageFlags::VERTEX_BUFFER)
        } else {
            ("scene indices", vk::BufferUsageFlags::INDEX_BUFFER)
        };
        let new = upload_sized(ctx, name, &[], size, usage | GEOMETRY_USAGE)?;
        let old = if vertices {
            std::mem::replace(&mut self.vertices, new)
        } else {
            std::mem::replace(&mut self.indices, new)
        };
        let dst = if vertices {
            self.vertices.raw
        } else {
            self.indices.raw
        };
        self.copies.push(Copy {
            src: old.raw,
            dst,
            region: vk::BufferCopy {
                src_offset: 0,
                dst_offset: 0,
                size: old.size,
            },
            growth: true,
        });
        self.retired
            .push((old, self.frames_written + self.frames.len() as u64));
        self.geometry_serial += 1;
        log::info!("scene {name} grown to {size} bytes");
        Ok(())
    }

    /// Keeps `indices` free at the end of the index buffer for the current view from the next
    /// frame on (grown then if needed), where its per-triangle culling packs the triangles it
    /// keeps. Each view has a region of its own: their packings never overwrite each other.
    pub fn reserve_index_tail(&mut self, indices: u64) {
        let view = self.view;
        if self.index_tails.len() <= view {
            self.index_tails.resize(view + 1, 0);
        }
        if let Some(t) = self.index_tails.get_mut(view) {
            *t = indices;
        }
    }

    /// View `view`'s region of the index buffer's tail: its first index and its length in
    /// indices (`(0, 0)` without one).
    pub fn index_tail(&self, view: usize) -> (u32, u32) {
        let len = self.index_tails.get(view).copied().unwrap_or(0);
        if len == 0 {
            return (0, 0);
        }
        let total = self.indices.size / 4;
        let before: u64 = self.index_tails.iter().take(view).sum();
        let all: u64 = self.index_tails.iter().sum();
        let first = total.saturating_sub(all) + before;
        match (u32::try_from(first), u32::try_from(len)) {
            (Ok(first), Ok(len)) if first as u64 + len as u64 <= total => (first, len),
            _ => (0, 0), // past what an index can address: no tail
        }
    }

    pub(super) fn destroy_retired(&mut self, ctx: &Context) {
        let now = self.frames_written;
        let mut i = 0;
        while i < self.retired.len() {
            if self.retired[i].1 <= now {
                let (b, _) = self.retired.swap_remove(i);
                ctx.destroy_buffer(b);
            } else {
                i += 1;
            }
        }
    }

    /// This frame's geometry copies, to record before the frame's passes
    /// ([`GeometryUpload::record`]); give them back with [`Self::end_upload`] (the list keeps
    /// its capacity: no allocation per frame).
    pub fn take_upload(&mut self) -> GeometryUpload {
        GeometryUpload {
            copies: std::mem::take(&mut self.copies),
        }
    }

    /// `recorded`: whether the frame holding the copies was recorded whole; if not, the next
    /// frame uploads all the geometry again.
    pub fn end_upload(&mut self, mut upload: GeometryUpload, recorded: bool) {
        upload.copies.clear();
        self.copies = upload.copies;
        if !recorded {
            self.geometry_cursor = None;
        }
    }
}

/// A frame's copies into the resident geometry ([`GpuScene::take_upload`]).
pub struct GeometryUpload {
    copies: Vec<Copy>,
}

impl GeometryUpload {
    /// Records the copies (nothing when the geometry did not change), with the barriers around
    /// them: after every earlier read and write of the geometry, before every later read.
    /// Outside any render pass, before the frame's passes.
    pub fn record(&self, ctx: &Context, cb: vk::CommandBuffer) -> Result<(), VkError> {
        let readers = vk::PipelineStageFlags2::VERTEX_ATTRIBUTE_INPUT
            | vk::PipelineStageFlags2::INDEX_INPUT
            | vk::PipelineStageFlags2::VERTEX_SHADER
            | vk::PipelineStageFlags2::FRAGMENT_SHADER
            | vk::PipelineStageFlags2::COMPUTE_SHADER;
        let reads = vk::AccessFlags2::VERTEX_ATTRIBUTE_READ
            | vk::AccessFlags2::INDEX_READ
            | vk::AccessFlags2::SHADER_STORAGE_READ;
        let copy = vk::PipelineStageFlags2::COPY;
        let write = vk::AccessFlags2::TRANSFER_WRITE;
        if self.copies.is_empty() {
            return Ok(());
        }
        // Per-triangle culling writes the index buffer's tail from compute shaders: a growth
        // copy reads it after them.
        let before = [vk::MemoryBarrier2::default()
            .src_stage_mask(readers | copy)
            .src_access_mask(write | vk::AccessFlags2::SHADER_STORAGE_WRITE)
            .dst_stage_mask(copy)
            .dst_access_mask(write | vk::AccessFlags2::TRANSFER_READ)];
        let after = [vk::MemoryBarrier2::default()
            .src_stage_mask(copy)
            .src_access_mask(write)
            .dst_stage_mask(readers | copy)
            .dst_access_mask(reads | write | vk::AccessFlags2::TRANSFER_READ)];
        ctx.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&before))?;
        // Growth copies first (they were queued first), then a barrier, so that the new
        // ranges land on top of the old content: copies without one between them may run in
        // any order.
        let growths = self.copies.iter().take_while(|c| c.growth).count();
        for (k, c) in self.copies.iter().enumerate() {
            if k == growths && k > 0 {
                let between = [vk::MemoryBarrier2::default()
                    .src_stage_mask(copy)
                    .src_access_mask(write)
                    .dst_stage_mask(copy)
                    .dst_access_mask(write)];
                let d = vk::DependencyInfo::default().memory_barriers(&between);
                ctx.cmd_pipeline_barrier2(cb, &d)?;
            }
            // SAFETY: outside a render pass; both buffers are live (a replaced one until the
            // frames that use it are done) and the region lies inside both.
            unsafe {
                ctx.device
                    .cmd_copy_buffer(cb, c.src, c.dst, std::slice::from_ref(&c.region))
            };
        }
        ctx.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&after))
    }
}

/// `ranges` (start, end) sorted, those that overlap or touch joined.
fn merged(mut ranges: Vec<(u32, u32)>) -> Vec<(u32, u32)> {
    ranges.sort_unstable();
    let mut out: Vec<(u32, u32)> = Vec::with_capacity(ranges.len());
    for (start, end) in ranges {
        match out.last_mut() {
            Some(last) if start <= last.1 => last.1 = last.1.max(end),
            _ => out.push((start, end)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn ranges_written_twice_are_copied_once() {
        let ranges = vec![(10, 20), (0, 5), (12, 30), (5, 6), (40, 41), (10, 20)];
        assert_eq!(super::merged(ranges), [(0, 6), (10, 30), (40, 41)]);
        assert!(super::merged(Vec::new()).is_empty());
    }
}
