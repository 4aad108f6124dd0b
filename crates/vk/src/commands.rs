//! Commands recorded through the context: object names and debug labels, synchronization2
//! barriers and timestamps, dynamic rendering and conditional rendering (core or extension,
//! whichever the device has), and one-off submissions that wait.

use ash::vk;

use crate::context::{missing_feature, Context, DynRendering, Sync2};
use crate::error::{VkError, VkResultExt};
use crate::features::Feature;

impl Context {
    /// Names an object for validation messages and capture tools (no-op without debug utils).
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(du) = &self.debug_utils {
            let Ok(c) = std::ffi::CString::new(name.replace('\0', "")) else {
                return;
            };
            let info = vk::DebugUtilsObjectNameInfoEXT::default()
                .object_handle(handle)
                .object_name(&c);
            // SAFETY: handle belongs to this device; name is NUL-terminated.
            if let Err(e) = unsafe { du.set_debug_utils_object_name(&info) } {
                log::debug!("naming {name}: {e}");
            }
        }
    }

    /// Opens a debug label region named after a pass (no-op without debug utils).
    pub fn begin_label(&self, cb: vk::CommandBuffer, name: &str) {
        let Some(du) = &self.debug_utils else {
            return;
        };
        let Ok(mut buf) = self.label_scratch.try_borrow_mut() else {
            return;
        };
        buf.clear();
        buf.extend(name.bytes().filter(|b| *b != 0));
        buf.push(0);
        let Ok(c) = std::ffi::CStr::from_bytes_with_nul(&buf) else {
            return;
        };
        let label = vk::DebugUtilsLabelEXT::default().label_name(c);
        // SAFETY: cb is recording; the name is NUL-terminated and outlives the call.
        unsafe { du.cmd_begin_debug_utils_label(cb, &label) };
    }

    pub fn end_label(&self, cb: vk::CommandBuffer) {
        if let Some(du) = &self.debug_utils {
            // SAFETY: matches a begin_label on the same command buffer.
            unsafe { du.cmd_end_debug_utils_label(cb) };
        }
    }

    pub fn has_debug_labels(&self) -> bool {
        self.debug_utils.is_some()
    }

    /// `vkCmdPipelineBarrier2` through core 1.3 or VK_KHR_synchronization2.
    pub fn cmd_pipeline_barrier2(
        &self,
        cb: vk::CommandBuffer,
        info: &vk::DependencyInfo<'_>,
    ) -> Result<(), VkError> {
        match &self.sync2 {
            // SAFETY: synchronization2 was enabled at device creation.
            Sync2::Core => unsafe { self.device.cmd_pipeline_barrier2(cb, info) },
            // SAFETY: as above, through the extension.
            Sync2::Khr(k) => unsafe { k.cmd_pipeline_barrier2(cb, info) },
            Sync2::Missing => return Err(missing_feature(Feature::Synchronization2)),
        }
        Ok(())
    }

    /// `vkQueueSubmit2` through core 1.3 or VK_KHR_synchronization2.
    pub fn queue_submit2(
        &self,
        queue: vk::Queue,
        submits: &[vk::SubmitInfo2<'_>],
        fence: vk::Fence,
    ) -> Result<(), VkError> {
        let r = match &self.sync2 {
            // SAFETY: synchronization2 was enabled at device creation; the caller's command
            // buffers are executable and its semaphores live.
            Sync2::Core => unsafe { self.device.queue_submit2(queue, submits, fence) },
            // SAFETY: as above, through the extension.
            Sync2::Khr(k) => unsafe { k.queue_submit2(queue, submits, fence) },
            Sync2::Missing => return Err(missing_feature(Feature::Synchronization2)),
        };
        r.map_err(|e| VkError::call("vkQueueSubmit2", e))
    }

    /// `vkCmdWriteTimestamp2` through core 1.3 or VK_KHR_synchronization2.
    pub fn cmd_write_timestamp2(
        &self,
        cb: vk::CommandBuffer,
        stage: vk::PipelineStageFlags2,
        pool: vk::QueryPool,
        query: u32,
    ) -> Result<(), VkError> {
        match &self.sync2 {
            // SAFETY: synchronization2 was enabled at device creation; the query was reset.
            Sync2::Core => unsafe { self.device.cmd_write_timestamp2(cb, stage, pool, query) },
            // SAFETY: as above, through the extension.
            Sync2::Khr(k) => unsafe { k.cmd_write_timestamp2(cb, stage, pool, query) },
            Sync2::Missing => return Err(missing_feature(Feature::Synchronization2)),
        }
        Ok(())
    }

    pub fn cmd_begin_rendering(
        &self,
        cb: vk::CommandBuffer,
        info: &vk::RenderingInfo<'_>,
    ) -> Result<(), VkError> {
        match &self.dynrend {
            // SAFETY: dynamic rendering was enabled at device creation.
            DynRendering::Core => unsafe { self.device.cmd_begin_rendering(cb, info) },
            // SAFETY: as above, through the extension.
            DynRendering::Khr(k) => unsafe { k.cmd_begin_rendering(cb, info) },
            DynRendering::Missing => return Err(missing_feature(Feature::DynamicRendering)),
        }
        Ok(())
    }

    pub fn cmd_end_rendering(&self, cb: vk::CommandBuffer) -> Result<(), VkError> {
        match &self.dynrend {
            // SAFETY: matches cmd_begin_rendering.
            DynRendering::Core => unsafe { self.device.cmd_end_rendering(cb) },
            // SAFETY: as above.
            DynRendering::Khr(k) => unsafe { k.cmd_end_rendering(cb) },
            DynRendering::Missing => return Err(missing_feature(Feature::DynamicRendering)),
        }
        Ok(())
    }

    /// VK_EXT_conditional_rendering entry points, when that feature was enabled.
    pub fn conditional_rendering(&self) -> Option<&ash::ext::conditional_rendering::Device> {
        self.conditional.as_ref()
    }

    /// Records `record` into a one-time command buffer, submits it and waits. For uploads,
    /// readbacks and tests — never on a per-frame path.
    pub fn submit_and_wait<R>(
        &self,
        record: impl FnOnce(vk::CommandBuffer) -> Result<R, VkError>,
    ) -> Result<R, VkError> {
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.upload_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool belongs to this device; Context is not Sync, so one thread at a time
        // records into it.
        let cbs = unsafe { self.device.allocate_command_buffers(&alloc) }
            .vk("vkAllocateCommandBuffers")?;
        let cb = cbs[0];
        let result = (|| {
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: freshly allocated command buffer.
            unsafe { self.device.begin_command_buffer(cb, &begin) }.vk("vkBeginCommandBuffer")?;
            let r = record(cb)?;
            // SAFETY: recording.
            unsafe { self.device.end_command_buffer(cb) }.vk("vkEndCommandBuffer")?;
            // SAFETY: valid device.
            let fence = unsafe {
                self.device
                    .create_fence(&vk::FenceCreateInfo::default(), None)
            }
            .vk("vkCreateFence")?;
            let cbs = [cb];
            let submit = vk::SubmitInfo::default().command_buffers(&cbs);
            // SAFETY: the command buffer is executable; the fence is unsignalled.
            let submitted = unsafe { self.device.queue_submit(self.queue, &[submit], fence) }
                .vk("vkQueueSubmit");
            let waited = submitted.and_then(|_| {
                // SAFETY: the fence was just submitted with the command buffer.
                let waited = unsafe { self.device.wait_for_fences(&[fence], true, u64::MAX) }
                    .vk("vkWaitForFences");
                if waited.is_err() {
                    // Submitted but not known to be done (device lost, say): wait for the whole
                    // device before the fence and the command buffer go.
                    // SAFETY: plain wait.
                    if let Err(e) = unsafe { self.device.device_wait_idle() } {
                        log::error!("vkDeviceWaitIdle after a failed fence wait: {e}");
                    }
                }
                waited
            });
            // SAFETY: the submit failed, or the fence signalled, or the device was waited for
            // (or lost): either way unused now.
            unsafe { self.device.destroy_fence(fence, None) };
            waited.map(|_| r)
        })();
        // SAFETY: execution finished (or never started); the buffer is no longer in use.
        unsafe { self.device.free_command_buffers(self.upload_pool, &cbs) };
        result
    }
}
