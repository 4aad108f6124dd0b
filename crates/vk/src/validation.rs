//! Validation-layer messages: routed through `log`, and collected so that a test can fail on them.

use std::ffi::{c_void, CStr};
use std::sync::Mutex;

use ash::vk;

/// Whether to load `VK_LAYER_KHRONOS_validation` (with synchronization validation and the
/// best-practices checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Validation {
    /// Never (release builds by default).
    Off,
    /// When the layer is installed; otherwise a warning (debug builds by default).
    IfAvailable,
    /// Always; a missing layer is an error (tests).
    Required,
}

impl Validation {
    /// `TILEGRAPH_VALIDATION=0|1|required` overrides; otherwise on in debug builds, off in release.
    pub fn from_env() -> Self {
        match std::env::var("TILEGRAPH_VALIDATION").ok().as_deref() {
            Some("0" | "off" | "false") => Validation::Off,
            Some("required") => Validation::Required,
            Some(_) => Validation::IfAvailable,
            None if cfg!(debug_assertions) => Validation::IfAvailable,
            None => Validation::Off,
        }
    }
}

/// A best-practices message that does not apply to tilegraph, and why. The same list, with the
/// same reasons, is docs/PROFILES.md's "Silenced best-practices messages" (a test checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Silenced {
    /// The message id name (`UNASSIGNED-BestPractices-...`).
    pub id: &'static str,
    /// Text the message must contain (empty: every message of the id).
    pub contains: &'static str,
    pub reason: &'static str,
}

/// Best-practices messages reviewed and silenced: logged at debug level, not failures.
pub const SILENCED: &[Silenced] = &[
    Silenced {
        id: "UNASSIGNED-BestPractices-vkCreateInstance-specialuse-extension-debugging",
        contains: "",
        reason: "VK_EXT_debug_utils and VK_EXT_validation_features are what validation reports through; tilegraph enables them only when validation is on",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "VK_ACCESS_2_SHADER_SAMPLED_READ_BIT: accessMask",
        reason: "the 1.3.239 layer's table of accesses per layout predates synchronization2's SHADER_SAMPLED_READ, a part of the SHADER_READ it allows",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "DEPTH_STENCIL_ATTACHMENT_WRITE_BIT: accessMask is vkCmdPipelineBarrier2, but for layout VK_IMAGE_LAYOUT_DEPTH_STENCIL_READ_ONLY_OPTIMAL",
        reason: "depth written inside a render pass that ends it read-only: the next barrier's source must name that write (the end-of-pass dependency only makes it available), whatever layout the pass left",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "VK_ACCESS_2_INPUT_ATTACHMENT_READ_BIT|VK_ACCESS_2_COLOR_ATTACHMENT_READ_BIT|VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT: accessMask",
        reason: "an input attachment a render pass loads and stores: its store is a colour-attachment write, which the barrier into the pass names whatever layout the subpass reads it in",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "VK_ACCESS_2_INPUT_ATTACHMENT_READ_BIT|VK_ACCESS_2_COLOR_ATTACHMENT_READ_BIT: accessMask is vkCmdPipelineBarrier2, but for layout VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL",
        reason: "an input attachment a render pass loads and keeps with STORE_OP_NONE: LOAD of a colour-format attachment is a colour-attachment read (the spec's access for load ops), which the barrier into the pass names whatever layout the subpass reads it in",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT: accessMask is vkCmdPipelineBarrier2, but for layout VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL",
        reason: "a colour attachment written in one subpass and read as an input attachment in a later one (the visibility buffer's ids kept for the oracle, under merging profiles): the barrier after the render pass must name that write, whatever layout the pass left",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "VK_ACCESS_2_INPUT_ATTACHMENT_READ_BIT|VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT|VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT: accessMask is vkCmdPipelineBarrier2, but for layout VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL",
        reason: "the barrier into a render pass names every access the pass makes to the depth (tested and written, then read as an input attachment by deferred texturing's resolve on tilers), in the layout of its first use",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "VK_ACCESS_2_INPUT_ATTACHMENT_READ_BIT|VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT: accessMask is vkCmdPipelineBarrier2, but for layout VK_IMAGE_LAYOUT_DEPTH_STENCIL_READ_ONLY_OPTIMAL",
        reason: "depth read as an input attachment in the read-only depth layout (deferred texturing's resolve on tilers), which the spec allows there: the barrier after the pass names that read; the 1.3.239 layer's table of accesses per layout lists shader reads and depth reads only",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ImageBarrierAccessLayout",
        contains: "VK_ACCESS_2_INPUT_ATTACHMENT_READ_BIT|VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT: accessMask is vkCmdPipelineBarrier2, but for layout VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL",
        reason: "the barrier into a render pass names every access the pass makes to the image (written as a colour attachment, then read as an input attachment), in the layout of its first use",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-SpirvDeprecated_WorkgroupSize",
        contains: "",
        reason: "the compute shaders are SPIR-V 1.0-1.3 for Vulkan 1.1-1.3 drivers; LocalSizeId needs VK_KHR_maintenance4, which the mobile families' drivers may lack",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-Error-Result",
        contains: "vkGetPhysicalDeviceImageFormatProperties(): Returned error VK_ERROR_FORMAT_NOT_SUPPORTED",
        reason: "a support query: the answer 'not supported' is what it asks for",
    },
    // Vendor checks (Arm and IMG: `mali-valhall`, `powervr-b`; NVIDIA: `desktop-nvidia`).
    Silenced {
        id: "UNASSIGNED-BestPractices-vkCmdBeginRenderPass-attachment-needs-readback",
        contains: "",
        reason: "the graph loads an attachment only when a later render pass reads what an earlier one wrote — two-phase culling's second depth pass after the pyramid build, a pass reading a sampled result; load/store inference keeps every other attachment on chip (crates/graph tests)",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-vkCmdDrawIndexed-many-small-indexed-drawcalls",
        contains: "",
        reason: "scene content: the test scenes' props are small meshes, already drawn instanced per mesh; an engine's scene decides its draw sizes",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-vkCmdDrawIndexed-sparse-index-buffer",
        contains: "",
        reason: "every mesh lives in one shared index buffer (one bind a frame) with mesh-local indices and a vertex offset: a draw uses its own range densely, which the check measures against the whole buffer",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-vkCreateComputePipelines-compute-spatial-locality",
        contains: "(64, 1, 1)",
        reason: "the culling shaders (64x1x1) read and write storage buffers only — the pyramid is a buffer; their SPIR-V declares no image",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-vkCreateComputePipelines-compute-work-group-size",
        contains: "(16, 16, 1)",
        reason: "the HiZ reduction's 16x16 tiles reduce up to four levels through shared memory (measured on the H100, docs/BENCHMARKS.md); lavapipe's profile runs one level per dispatch; a mobile tile size is a tuning knob to measure on the devices",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-AllocateMemory-SetPriority",
        contains: "",
        reason: "VK_EXT_memory_priority is not among the extensions tilegraph enables (lavapipe, where the suite runs, lacks it); the allocation's memory type is the profile's choice",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-DepthBiasNoAttachment",
        contains: "depthBiasEnable == VK_TRUE without a depth-stencil attachment",
        reason: "the 1.3.239 layer looks for a depth attachment in every subpass of the render pass, not in the one drawn in: the occlusion proxies, the only pipelines with a depth bias, always draw in a subpass with the depth they test (declared read-only by the graph), but a subpass before them in the same render pass may have none (the visibility buffer's resolve)",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-ClearColor-NotCompressed",
        contains: "",
        reason: "the clear values are content: the scene's sky colour, and the visibility buffer's 'no instance' id",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-CreateImage-Depth32Format",
        contains: "",
        reason: "D32 with reverse-Z is the precision the culling tests hold to (seed 000); D16 is a tuning knob (issue 23), D24S8 has no stencil user here",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-CreatePipelineLayout-LargePipelineLayout",
        contains: "",
        reason: "the scene's set 0 carries every scene buffer, bound once a frame and shared by all scene pipelines",
    },
    Silenced {
        id: "UNASSIGNED-BestPractices-Pipeline-SortAndBind",
        contains: "",
        reason: "two-phase culling runs the same culling pipelines once per phase, with the depth pass and pyramid between them: the order is the algorithm's",
    },
];

/// The silenced entry that covers the message `id` / `text`, if any.
pub fn silenced(id: &str, text: &str) -> Option<&'static Silenced> {
    SILENCED
        .iter()
        .find(|s| s.id == id && text.contains(s.contains))
}

/// Collects every warning and error the layer reports. Lives in a `Box` whose address is the
/// messenger's user data, so it must outlive the messenger (the `Instance` guarantees that).
#[derive(Debug, Default)]
pub struct ValidationSink {
    messages: Mutex<Vec<String>>,
    /// The ids of the [`SILENCED`] messages seen, each once.
    silenced: Mutex<Vec<&'static str>>,
}

impl ValidationSink {
    pub fn count(&self) -> usize {
        self.messages.lock().map(|m| m.len()).unwrap_or(0)
    }

    /// Returns and clears the collected messages.
    pub fn take(&self) -> Vec<String> {
        self.messages
            .lock()
            .map(|mut m| std::mem::take(&mut *m))
            .unwrap_or_default()
    }

    /// The ids of the silenced messages the layer reported so far, each once.
    pub fn silenced_ids(&self) -> Vec<&'static str> {
        self.silenced.lock().map(|s| s.clone()).unwrap_or_default()
    }

    fn push_silenced(&self, id: &'static str) {
        if let Ok(mut s) = self.silenced.lock() {
            if !s.contains(&id) {
                s.push(id);
            }
        }
    }

    fn push(&self, message: String) {
        if let Ok(mut m) = self.messages.lock() {
            m.push(message);
        }
    }
}

/// The messenger callback. Warnings and errors are failures; info and verbose are only logged.
///
/// # Safety
/// Called by the loader with a valid callback-data pointer; `user_data` is the address of the
/// `ValidationSink` owned by the instance.
pub(crate) unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the loader passes a valid pointer for the duration of the call.
    let Some(data) = (unsafe { data.as_ref() }) else {
        return vk::FALSE;
    };
    let text = |p: *const std::ffi::c_char| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: non-null strings in the callback data are NUL-terminated (spec).
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    let id = text(data.p_message_id_name);
    let body = text(data.p_message);
    if let Some(s) = silenced(&id, &body) {
        log::debug!(target: "vulkan", "silenced (docs/PROFILES.md): [{id}] {body}");
        // SAFETY: as below: user_data is the sink, alive while the messenger is.
        if let Some(sink) = unsafe { (user_data as *const ValidationSink).as_ref() } {
            sink.push_silenced(s.id);
        }
        return vk::FALSE;
    }
    let message = format!("[{id}] {body}");
    // GENERAL messages come from the loader about the machine (manifests of other drivers and
    // layers it could not load), not about this program's use of the API: logged, not failures.
    let failure = severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
            | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
    ) && !types.contains(vk::DebugUtilsMessageTypeFlagsEXT::GENERAL);
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        log::error!(target: "vulkan", "{message}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        log::warn!(target: "vulkan", "{message}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::INFO) {
        log::debug!(target: "vulkan", "{message}");
    } else {
        log::trace!(target: "vulkan", "{message}");
    }
    if failure {
        // SAFETY: user_data is the Box<ValidationSink> address set at messenger creation; the
        // instance destroys the messenger before dropping the box.
        if let Some(sink) = unsafe { (user_data as *const ValidationSink).as_ref() } {
            sink.push(message);
        }
    }
    vk::FALSE
}
