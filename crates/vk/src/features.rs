//! Device features by name: passes ask for what they need, the device enables only that.
//!
//! DESIGN.md: "Device features are enabled only when a pass needs them." A request lists required
//! and optional features; a required one that the device lacks is a typed error naming it, an
//! optional one is a log line and the pass that wanted it chooses another path.

use std::collections::BTreeSet;
use std::fmt;

use ash::vk;
use serde::Serialize;

/// A device capability that some tilegraph pass may need.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Feature {
    /// `vkCmdPipelineBarrier2` (core 1.3, VK_KHR_synchronization2 on 1.2). The executor needs it.
    Synchronization2,
    /// `vkCmdBeginRendering` (core 1.3, VK_KHR_dynamic_rendering on 1.2).
    DynamicRendering,
    /// `vkCmdDrawIndexedIndirectCount` (core 1.2 feature).
    DrawIndirectCount,
    /// More than one draw per indirect call.
    MultiDrawIndirect,
    /// `gl_DrawID` / `gl_BaseInstance` in vertex shaders.
    ShaderDrawParameters,
    /// Min/max sampler reduction, for one-tap HiZ downsampling.
    SamplerFilterMinmax,
    /// `vkResetQueryPool` from the host.
    HostQueryReset,
    /// Vertex and fragment invocation counters.
    PipelineStatisticsQuery,
    /// Exact sample counts from occlusion queries.
    OcclusionQueryPrecise,
    /// VK_EXT_conditional_rendering.
    ConditionalRendering,
    /// Storage writes from fragment shaders (raster occlusion flags).
    FragmentStoresAndAtomics,
    /// Depth clamp (shadow casters, near-plane crossing proxies).
    DepthClamp,
    /// The `geometryShader` feature: what Vulkan asks for before a fragment shader may read
    /// `gl_PrimitiveID` (the visibility buffer's triangle id), even with no geometry shader.
    GeometryShader,
    /// An array of textures indexed by a value uniform over a draw (the forward passes' material
    /// texture).
    SampledImageArrayDynamicIndexing,
    /// An array of textures indexed per pixel (core 1.2 feature, from descriptor indexing): the
    /// visibility-buffer resolve's material texture. Without it, textures go into one array
    /// image (`TextureBinding::Layers`).
    SampledImageArrayNonUniformIndexing,
    /// Timeline semaphores (core 1.2 feature): the waits between the graphics and the async
    /// compute queue's submissions. Without it, async compute is off.
    TimelineSemaphore,
}

impl Feature {
    pub const ALL: [Feature; 16] = [
        Feature::Synchronization2,
        Feature::DynamicRendering,
        Feature::DrawIndirectCount,
        Feature::MultiDrawIndirect,
        Feature::ShaderDrawParameters,
        Feature::SamplerFilterMinmax,
        Feature::HostQueryReset,
        Feature::PipelineStatisticsQuery,
        Feature::OcclusionQueryPrecise,
        Feature::ConditionalRendering,
        Feature::FragmentStoresAndAtomics,
        Feature::DepthClamp,
        Feature::GeometryShader,
        Feature::SampledImageArrayDynamicIndexing,
        Feature::SampledImageArrayNonUniformIndexing,
        Feature::TimelineSemaphore,
    ];
}

impl Feature {
    /// The extension that provides the feature on every Vulkan version (none of the others:
    /// they are core features, or core from 1.3 and enabled through an extension before).
    pub fn extension_only(self) -> Option<&'static str> {
        match self {
            Feature::ConditionalRendering => Some("VK_EXT_conditional_rendering"),
            _ => None,
        }
    }
}

impl fmt::Display for Feature {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)?;
        match self.extension_only() {
            Some(e) => write!(f, " ({e})"),
            None => Ok(()),
        }
    }
}

/// What the caller wants enabled.
#[derive(Debug, Clone, Default)]
pub struct FeatureRequest {
    pub required: BTreeSet<Feature>,
    pub optional: BTreeSet<Feature>,
}

impl FeatureRequest {
    pub fn require(mut self, f: impl IntoIterator<Item = Feature>) -> Self {
        self.required.extend(f);
        self
    }
    pub fn want(mut self, f: impl IntoIterator<Item = Feature>) -> Self {
        self.optional.extend(f);
        self
    }
    /// What the executor itself needs (barriers, dynamic rendering), the pipeline statistics it
    /// reports per pass where the device has them, and the texture array indexing the scene
    /// passes use where the device has it (else textures are layers of one image).
    pub fn executor() -> Self {
        Self::default()
            .require([Feature::Synchronization2, Feature::DynamicRendering])
            .want([
                Feature::PipelineStatisticsQuery,
                Feature::SampledImageArrayDynamicIndexing,
                Feature::SampledImageArrayNonUniformIndexing,
                Feature::TimelineSemaphore,
            ])
    }
}

/// Feature structs of someone else's (an engine's `VkDeviceCreateInfo` chain) to enable
/// features in; `None` for a struct not chained.
#[derive(Default)]
pub struct FeatureTargets<'a> {
    pub core: Option<&'a mut vk::PhysicalDeviceFeatures>,
    pub v11: Option<&'a mut vk::PhysicalDeviceVulkan11Features<'static>>,
    pub v12: Option<&'a mut vk::PhysicalDeviceVulkan12Features<'static>>,
    pub v13: Option<&'a mut vk::PhysicalDeviceVulkan13Features<'static>>,
    pub sync2: Option<&'a mut vk::PhysicalDeviceSynchronization2Features<'static>>,
    pub dynrend: Option<&'a mut vk::PhysicalDeviceDynamicRenderingFeatures<'static>>,
    pub cond: Option<&'a mut vk::PhysicalDeviceConditionalRenderingFeaturesEXT<'static>>,
}

impl FeatureTargets<'_> {
    /// Sets `f`'s boolean in the struct that holds it on a device of this API version;
    /// `Err(struct name)` when that struct is `None`.
    pub fn enable(&mut self, f: Feature, api13: bool) -> Result<(), &'static str> {
        fn set<T>(
            s: &mut Option<&mut T>,
            name: &'static str,
            field: impl FnOnce(&mut T),
        ) -> Result<(), &'static str> {
            s.as_deref_mut().map(field).ok_or(name)
        }
        let t = vk::TRUE;
        const CORE: &str = "VkPhysicalDeviceFeatures";
        const V11: &str = "VkPhysicalDeviceVulkan11Features";
        const V12: &str = "VkPhysicalDeviceVulkan12Features";
        const V13: &str = "VkPhysicalDeviceVulkan13Features";
        match f {
            Feature::Synchronization2 if api13 => {
                set(&mut self.v13, V13, |s| s.synchronization2 = t)
            }
            Feature::Synchronization2 => set(
                &mut self.sync2,
                "VkPhysicalDeviceSynchronization2Features",
                |s| s.synchronization2 = t,
            ),
            Feature::DynamicRendering if api13 => {
                set(&mut self.v13, V13, |s| s.dynamic_rendering = t)
            }
            Feature::DynamicRendering => set(
                &mut self.dynrend,
                "VkPhysicalDeviceDynamicRenderingFeatures",
                |s| s.dynamic_rendering = t,
            ),
            Feature::DrawIndirectCount => set(&mut self.v12, V12, |s| s.draw_indirect_count = t),
            Feature::MultiDrawIndirect => set(&mut self.core, CORE, |s| s.multi_draw_indirect = t),
            Feature::ShaderDrawParameters => {
                set(&mut self.v11, V11, |s| s.shader_draw_parameters = t)
            }
            Feature::SamplerFilterMinmax => {
                set(&mut self.v12, V12, |s| s.sampler_filter_minmax = t)
            }
            Feature::HostQueryReset => set(&mut self.v12, V12, |s| s.host_query_reset = t),
            Feature::PipelineStatisticsQuery => {
                set(&mut self.core, CORE, |s| s.pipeline_statistics_query = t)
            }
            Feature::OcclusionQueryPrecise => {
                set(&mut self.core, CORE, |s| s.occlusion_query_precise = t)
            }
            Feature::ConditionalRendering => set(
                &mut self.cond,
                "VkPhysicalDeviceConditionalRenderingFeaturesEXT",
                |s| s.conditional_rendering = t,
            ),
            Feature::FragmentStoresAndAtomics => {
                set(&mut self.core, CORE, |s| s.fragment_stores_and_atomics = t)
            }
            Feature::DepthClamp => set(&mut self.core, CORE, |s| s.depth_clamp = t),
            Feature::GeometryShader => set(&mut self.core, CORE, |s| s.geometry_shader = t),
            Feature::SampledImageArrayDynamicIndexing => set(&mut self.core, CORE, |s| {
                s.shader_sampled_image_array_dynamic_indexing = t
            }),
            Feature::SampledImageArrayNonUniformIndexing => set(&mut self.v12, V12, |s| {
                s.shader_sampled_image_array_non_uniform_indexing = t
            }),
            Feature::TimelineSemaphore => set(&mut self.v12, V12, |s| s.timeline_semaphore = t),
        }
    }
}

/// Owned feature structs for querying / enabling, chained on demand.
#[derive(Default)]
pub(crate) struct FeatureStructs {
    pub core: vk::PhysicalDeviceFeatures,
    /// Chains `core` (filled by `DeviceConfig::chain`).
    pub features2: vk::PhysicalDeviceFeatures2<'static>,
    pub v11: vk::PhysicalDeviceVulkan11Features<'static>,
    pub v12: vk::PhysicalDeviceVulkan12Features<'static>,
    pub v13: vk::PhysicalDeviceVulkan13Features<'static>,
    pub sync2: vk::PhysicalDeviceSynchronization2Features<'static>,
    pub dynrend: vk::PhysicalDeviceDynamicRenderingFeatures<'static>,
    pub cond: vk::PhysicalDeviceConditionalRenderingFeaturesEXT<'static>,
}

pub(crate) const EXT_CONDITIONAL_RENDERING: &std::ffi::CStr = ash::ext::conditional_rendering::NAME;
pub(crate) const KHR_SYNC2: &std::ffi::CStr = ash::khr::synchronization2::NAME;
pub(crate) const KHR_DYNREND: &std::ffi::CStr = ash::khr::dynamic_rendering::NAME;

impl FeatureStructs {
    pub fn get(&self, f: Feature, api13: bool) -> bool {
        let b = |v: vk::Bool32| v == vk::TRUE;
        match f {
            Feature::Synchronization2 if api13 => b(self.v13.synchronization2),
            Feature::Synchronization2 => b(self.sync2.synchronization2),
            Feature::DynamicRendering if api13 => b(self.v13.dynamic_rendering),
            Feature::DynamicRendering => b(self.dynrend.dynamic_rendering),
            Feature::DrawIndirectCount => b(self.v12.draw_indirect_count),
            Feature::MultiDrawIndirect => b(self.core.multi_draw_indirect),
            Feature::ShaderDrawParameters => b(self.v11.shader_draw_parameters),
            Feature::SamplerFilterMinmax => b(self.v12.sampler_filter_minmax),
            Feature::HostQueryReset => b(self.v12.host_query_reset),
            Feature::PipelineStatisticsQuery => b(self.core.pipeline_statistics_query),
            Feature::OcclusionQueryPrecise => b(self.core.occlusion_query_precise),
            Feature::ConditionalRendering => b(self.cond.conditional_rendering),
            Feature::FragmentStoresAndAtomics => b(self.core.fragment_stores_and_atomics),
            Feature::DepthClamp => b(self.core.depth_clamp),
            Feature::GeometryShader => b(self.core.geometry_shader),
            Feature::SampledImageArrayDynamicIndexing => {
                b(self.core.shader_sampled_image_array_dynamic_indexing)
            }
            Feature::SampledImageArrayNonUniformIndexing => {
                b(self.v12.shader_sampled_image_array_non_uniform_indexing)
            }
            Feature::TimelineSemaphore => b(self.v12.timeline_semaphore),
        }
    }

    pub fn set(&mut self, f: Feature, api13: bool) {
        let mut targets = FeatureTargets {
            core: Some(&mut self.core),
            v11: Some(&mut self.v11),
            v12: Some(&mut self.v12),
            v13: Some(&mut self.v13),
            sync2: Some(&mut self.sync2),
            dynrend: Some(&mut self.dynrend),
            cond: Some(&mut self.cond),
        };
        // Every struct is present: nothing can be missing.
        let enabled = targets.enable(f, api13);
        debug_assert!(enabled.is_ok());
    }

    /// The device extension a feature needs on this API version, if any.
    pub fn extension(f: Feature, api13: bool) -> Option<&'static std::ffi::CStr> {
        match f {
            Feature::Synchronization2 if !api13 => Some(KHR_SYNC2),
            Feature::DynamicRendering if !api13 => Some(KHR_DYNREND),
            Feature::ConditionalRendering => Some(EXT_CONDITIONAL_RENDERING),
            _ => None,
        }
    }
}
