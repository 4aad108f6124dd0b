//! The engine's device handed to tilegraph: what to enable before creating it, adopting it,
//! the profile chosen for it, and a memory budget.

use std::ffi::{c_char, c_void, CString};

use tilegraph_passes::cull::Culling;
use tilegraph_passes::{RenderOptions, Technique};
use tilegraph_vk::ash::vk::{self, Handle};
use tilegraph_vk::{AdoptedDevice, Context, DeviceConfig, FaultSite, Feature, Instance};

use crate::registry::{self, Kind};
use crate::status::{arg, boundary, optional_string, out, Failure, TgStatus};

/// `vkGetInstanceProcAddr` as the engine has it (the loader's, or its own layer chain's):
/// `PFN_vkVoidFunction (VkInstance, const char*)`.
pub type TgGetInstanceProcAddr = Option<
    unsafe extern "system" fn(
        instance: *mut c_void,
        name: *const c_char,
    ) -> Option<unsafe extern "system" fn()>,
>;

/// A tilegraph context over the engine's device.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TgContext {
    pub raw: u64,
}

/// How a frame decides what gets shaded.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgTechnique {
    /// Forward colour passes; the depth pre-pass as the profile says.
    Forward = 0,
    /// Forward with a depth pre-pass, whatever the profile says.
    Prepass = 1,
    /// Visibility buffer: id pass, then resolve.
    Visbuf = 2,
    /// Deferred texturing: G-buffer of material, normal, UV and UV derivatives, then one
    /// full-screen pass sampling the textures and shading.
    DeferredTexturing = 3,
}

/// Which culling runs before drawing (docs/CULLING.md measures each).
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgCulling {
    None = 0,
    Frustum = 1,
    Hiz = 2,
    HizTwoPhase = 3,
    Oq = 4,
    OqConditional = 5,
    RasterOcclusion = 6,
    /// Needs the scene's clusters (`tg_scene_attach_clusters`).
    FrustumClusters = 7,
    /// Needs the scene's clusters (`tg_scene_attach_clusters`).
    HizTwoPhaseClusters = 8,
    /// Last frame's depth reprojected: not conservative (docs/ACCURACY.md).
    Reproject = 9,
    /// Occluders rasterized on the CPU, same frame (knobs `software_*`).
    SoftwareOcclusion = 10,
    /// A precomputed visible set (`TgRendererDesc::pvs`, baked by `tilegraph pvs`): the
    /// camera cell's instances the frustum holds. Exact only at its samples (docs/ACCURACY.md).
    Pvs = 11,
}

/// Device features tilegraph may need, as bits of `TgDeviceRequirements::features`.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgFeature {
    /// VkPhysicalDeviceVulkan13Features.synchronization2 (VK_KHR_synchronization2 on 1.2).
    Synchronization2 = 1 << 0,
    /// VkPhysicalDeviceVulkan13Features.dynamicRendering (VK_KHR_dynamic_rendering on 1.2).
    DynamicRendering = 1 << 1,
    /// VkPhysicalDeviceVulkan12Features.drawIndirectCount.
    DrawIndirectCount = 1 << 2,
    /// VkPhysicalDeviceFeatures.multiDrawIndirect.
    MultiDrawIndirect = 1 << 3,
    /// VkPhysicalDeviceVulkan11Features.shaderDrawParameters.
    ShaderDrawParameters = 1 << 4,
    /// VkPhysicalDeviceVulkan12Features.samplerFilterMinmax.
    SamplerFilterMinmax = 1 << 5,
    /// VkPhysicalDeviceVulkan12Features.hostQueryReset.
    HostQueryReset = 1 << 6,
    /// VkPhysicalDeviceFeatures.pipelineStatisticsQuery.
    PipelineStatisticsQuery = 1 << 7,
    /// VkPhysicalDeviceFeatures.occlusionQueryPrecise.
    OcclusionQueryPrecise = 1 << 8,
    /// VkPhysicalDeviceConditionalRenderingFeaturesEXT.conditionalRendering.
    ConditionalRendering = 1 << 9,
    /// VkPhysicalDeviceFeatures.fragmentStoresAndAtomics.
    FragmentStoresAndAtomics = 1 << 10,
    /// VkPhysicalDeviceFeatures.depthClamp.
    DepthClamp = 1 << 11,
    /// VkPhysicalDeviceFeatures.geometryShader.
    GeometryShader = 1 << 12,
    /// VkPhysicalDeviceFeatures.shaderSampledImageArrayDynamicIndexing.
    SampledImageArrayDynamicIndexing = 1 << 13,
    /// VkPhysicalDeviceVulkan12Features.shaderSampledImageArrayNonUniformIndexing.
    SampledImageArrayNonUniformIndexing = 1 << 14,
    /// VkPhysicalDeviceVulkan12Features.timelineSemaphore (async compute's waits).
    TimelineSemaphore = 1 << 15,
}

const FEATURE_BITS: [(Feature, TgFeature); 16] = [
    (Feature::Synchronization2, TgFeature::Synchronization2),
    (Feature::DynamicRendering, TgFeature::DynamicRendering),
    (Feature::DrawIndirectCount, TgFeature::DrawIndirectCount),
    (Feature::MultiDrawIndirect, TgFeature::MultiDrawIndirect),
    (
        Feature::ShaderDrawParameters,
        TgFeature::ShaderDrawParameters,
    ),
    (Feature::SamplerFilterMinmax, TgFeature::SamplerFilterMinmax),
    (Feature::HostQueryReset, TgFeature::HostQueryReset),
    (
        Feature::PipelineStatisticsQuery,
        TgFeature::PipelineStatisticsQuery,
    ),
    (
        Feature::OcclusionQueryPrecise,
        TgFeature::OcclusionQueryPrecise,
    ),
    (
        Feature::ConditionalRendering,
        TgFeature::ConditionalRendering,
    ),
    (
        Feature::FragmentStoresAndAtomics,
        TgFeature::FragmentStoresAndAtomics,
    ),
    (Feature::DepthClamp, TgFeature::DepthClamp),
    (Feature::GeometryShader, TgFeature::GeometryShader),
    (
        Feature::SampledImageArrayDynamicIndexing,
        TgFeature::SampledImageArrayDynamicIndexing,
    ),
    (
        Feature::SampledImageArrayNonUniformIndexing,
        TgFeature::SampledImageArrayNonUniformIndexing,
    ),
    (Feature::TimelineSemaphore, TgFeature::TimelineSemaphore),
];

fn feature_bits(features: impl IntoIterator<Item = Feature>) -> u32 {
    features
        .into_iter()
        .filter_map(|f| FEATURE_BITS.iter().find(|(g, _)| *g == f))
        .fold(0, |bits, (_, t)| bits | *t as u32)
}

pub(crate) fn features_of(bits: u32) -> Result<std::collections::BTreeSet<Feature>, Failure> {
    let known = FEATURE_BITS.iter().fold(0u32, |b, (_, t)| b | *t as u32);
    if bits & !known != 0 {
        return Err(Failure::invalid(format!(
            "feature bits {:#x} are no TgFeature",
            bits & !known
        )));
    }
    Ok(FEATURE_BITS
        .iter()
        .filter(|(_, t)| bits & *t as u32 != 0)
        .map(|(f, _)| *f)
        .collect())
}

pub(crate) fn technique(raw: u32) -> Result<Technique, Failure> {
    match raw {
        0 => Ok(Technique::Forward),
        1 => Ok(Technique::Prepass),
        2 => Ok(Technique::Visbuf),
        3 => Ok(Technique::DeferredTexturing),
        _ => Err(Failure::invalid(format!(
            "technique {raw} is no TgTechnique"
        ))),
    }
}

pub(crate) fn culling(raw: u32) -> Result<Culling, Failure> {
    Ok(match raw {
        0 => Culling::None,
        1 => Culling::Frustum,
        2 => Culling::Hiz,
        3 => Culling::HizTwoPhase,
        4 => Culling::Oq,
        5 => Culling::OqConditional,
        6 => Culling::RasterOcclusion,
        7 => Culling::FrustumClusters,
        8 => Culling::HizTwoPhaseClusters,
        9 => Culling::Reproject,
        10 => Culling::SoftwareOcclusion,
        11 => Culling::Pvs,
        _ => return Err(Failure::invalid(format!("culling {raw} is no TgCulling"))),
    })
}

/// The engine's instance and physical device, and what it means to render with.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgDeviceQuery {
    /// The `vkGetInstanceProcAddr` the instance was created through.
    pub get_instance_proc_addr: TgGetInstanceProcAddr,
    /// VkInstance.
    pub instance: *mut c_void,
    /// VkPhysicalDevice.
    pub physical_device: *mut c_void,
    /// The graphics + compute queue family tilegraph will record for.
    pub queue_family: u32,
    /// A TgTechnique.
    pub technique: u32,
    /// A TgCulling.
    pub culling: u32,
}

/// What the engine enables on its device for tilegraph.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgDeviceRequirements {
    /// TgFeature bits: enable each (`tg_enable_features` sets them in the engine's structs).
    pub features: u32,
    /// Whether the device is Vulkan 1.3 (synchronization2 and dynamic rendering are then in
    /// VkPhysicalDeviceVulkan13Features; otherwise in their extensions' structs).
    pub vulkan13: u32,
    pub extension_count: u32,
    /// Device extensions to enable (static strings), `extension_count` of them.
    pub extensions: [*const c_char; 8],
}

/// The engine's device for `tg_context_adopt`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgAdoptInfo {
    pub get_instance_proc_addr: TgGetInstanceProcAddr,
    /// VkInstance (tilegraph never destroys it).
    pub instance: *mut c_void,
    /// Non-zero when VK_EXT_debug_utils is enabled on the instance (objects get names).
    pub instance_has_debug_utils: u32,
    /// VkPhysicalDevice.
    pub physical_device: *mut c_void,
    /// VkDevice (tilegraph never destroys it).
    pub device: *mut c_void,
    pub queue_family: u32,
    pub queue_index: u32,
    /// TgFeature bits the device was created with (`TgDeviceRequirements::features` or more).
    pub enabled_features: u32,
    /// A profile name to force ("adreno-7xx", "mali-valhall", ...), or null for the device's own.
    pub profile: *const c_char,
}

/// The context's profile and why it was chosen.
pub(crate) struct ContextObject {
    pub ctx: Context,
    profile: CString,
    reason: CString,
}

fn request(query: &TgDeviceQuery) -> Result<RenderOptions, Failure> {
    Ok(RenderOptions {
        technique: technique(query.technique)?,
        culling: culling(query.culling)?,
        ..RenderOptions::default()
    })
}

/// # Safety
/// The caller's handles and function are valid (see the public functions).
unsafe fn adopt_instance(
    gipa: TgGetInstanceProcAddr,
    instance: *mut c_void,
    debug_utils: bool,
) -> Result<Instance, Failure> {
    let gipa = gipa
        .ok_or_else(|| Failure::new(TgStatus::NullPointer, "`get_instance_proc_addr` is null"))?;
    // SAFETY: the same signature as ash's PFN_vkGetInstanceProcAddr: handles are
    // pointer-sized (a dispatchable VkInstance is a pointer), the result an optional
    // function pointer, the same "system" calling convention.
    let gipa: vk::PFN_vkGetInstanceProcAddr = unsafe { std::mem::transmute(gipa) };
    if instance.is_null() {
        return Err(Failure::new(TgStatus::NullPointer, "`instance` is null"));
    }
    let raw = vk::Instance::from_raw(instance as u64);
    // SAFETY: the caller's contract: a live instance created through `gipa`.
    Ok(unsafe { Instance::adopt(gipa, raw, debug_utils) }?)
}

/// What the engine must enable on its device to render with `query`'s technique and culling
/// on `query`'s physical device: features (bits of TgFeature) and device extensions. Call it
/// before vkCreateDevice; a required feature the device lacks is TG_STATUS_MISSING_FEATURE.
///
/// # Safety
/// `query` points to a valid TgDeviceQuery whose handles are live and whose
/// `get_instance_proc_addr` resolves the instance's functions; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_device_requirements(
    query: *const TgDeviceQuery,
    out_requirements: *mut TgDeviceRequirements,
) -> TgStatus {
    boundary("tg_device_requirements", || {
        // SAFETY: the caller's contract.
        let query = unsafe { arg(query, "query") }?;
        // SAFETY: as above.
        let out_requirements = unsafe { out(out_requirements, "out_requirements") }?;
        if query.physical_device.is_null() {
            return Err(Failure::new(
                TgStatus::NullPointer,
                "`query->physical_device` is null",
            ));
        }
        let options = request(query)?;
        // SAFETY: as above.
        let instance =
            unsafe { adopt_instance(query.get_instance_proc_addr, query.instance, false) }?;
        let physical = instance.physical_device(
            vk::PhysicalDevice::from_raw(query.physical_device as u64),
            query.queue_family,
        )?;
        let config = DeviceConfig::new(&physical, &options.device_features())?;
        let mut extensions = [std::ptr::null(); 8];
        for (slot, e) in extensions.iter_mut().zip(&config.extensions) {
            *slot = e.as_ptr();
        }
        *out_requirements = TgDeviceRequirements {
            features: feature_bits(config.enabled.iter().copied()),
            vulkan13: u32::from(physical.api13()),
            extension_count: config.extensions.len().min(8) as u32,
            extensions,
        };
        Ok(())
    })
}

/// Adopts the engine's device: tilegraph records for `queue_family` with the features the
/// engine enabled, chooses the profile from the device's identity (or the one forced by
/// name), and never destroys the instance or the device — only what it makes on them.
///
/// # Safety
/// `info`'s handles are live, the device was created from its physical device with at least
/// `enabled_features`, and they stay valid until `tg_context_destroy`. tilegraph uses the queue
/// only from the calling thread, inside tilegraph calls (uploads at scene upload); the engine
/// does not use the queue concurrently.
#[no_mangle]
pub unsafe extern "C" fn tg_context_adopt(
    info: *const TgAdoptInfo,
    out_context: *mut TgContext,
) -> TgStatus {
    boundary("tg_context_adopt", || {
        // SAFETY: the caller's contract.
        let info = unsafe { arg(info, "info") }?;
        // SAFETY: as above.
        let out_context = unsafe { out(out_context, "out_context") }?;
        *out_context = TgContext { raw: 0 };
        for (ptr, name) in [
            (info.physical_device, "info->physical_device"),
            (info.device, "info->device"),
        ] {
            if ptr.is_null() {
                return Err(Failure::new(
                    TgStatus::NullPointer,
                    format!("`{name}` is null"),
                ));
            }
        }
        // SAFETY: as above.
        let profile = unsafe { optional_string(info.profile, "info->profile") }?;
        let enabled = features_of(info.enabled_features)?;
        // SAFETY: as above.
        let instance = unsafe {
            adopt_instance(
                info.get_instance_proc_addr,
                info.instance,
                info.instance_has_debug_utils != 0,
            )
        }?;
        let adopted = AdoptedDevice {
            physical_device: vk::PhysicalDevice::from_raw(info.physical_device as u64),
            device: vk::Device::from_raw(info.device as u64),
            queue_family: info.queue_family,
            queue_index: info.queue_index,
            enabled,
            profile: profile.map(str::to_string),
            profile_forced_by: "TgAdoptInfo.profile".into(),
        };
        // SAFETY: as above.
        let ctx = unsafe { Context::adopt(instance, adopted) }?;
        let object = ContextObject {
            profile: CString::new(ctx.profile().name.as_str()).unwrap_or_default(),
            reason: CString::new(ctx.selection.matched_by.to_string()).unwrap_or_default(),
            ctx,
        };
        *out_context = TgContext {
            raw: registry::insert(Kind::Context, object)?,
        };
        Ok(())
    })
}

/// Destroys the context: what tilegraph made on the device (its memory, its command pool).
/// The engine has waited for every frame tilegraph recorded; renderers made from the context
/// are destroyed first (TG_STATUS_IN_USE otherwise). A zero handle is a no-op.
#[no_mangle]
pub extern "C" fn tg_context_destroy(context: TgContext) -> TgStatus {
    boundary("tg_context_destroy", || {
        if context.raw == 0 {
            return Ok(());
        }
        let object = registry::remove::<ContextObject>(context.raw, Kind::Context, "context")?;
        drop(object);
        Ok(())
    })
}

/// The profile's name and why it was chosen ("forced by ...", "device name matches ...").
/// The strings live as long as the context.
///
/// # Safety
/// The out-pointers are writable (either may be null).
#[no_mangle]
pub unsafe extern "C" fn tg_context_profile(
    context: TgContext,
    out_name: *mut *const c_char,
    out_reason: *mut *const c_char,
) -> TgStatus {
    boundary("tg_context_profile", || {
        registry::with(
            context.raw,
            Kind::Context,
            "context",
            |c: &ContextObject| {
                if !out_name.is_null() {
                    // SAFETY: the caller's contract.
                    unsafe { *out(out_name, "out_name")? = c.profile.as_ptr() };
                }
                if !out_reason.is_null() {
                    // SAFETY: the caller's contract.
                    unsafe { *out(out_reason, "out_reason")? = c.reason.as_ptr() };
                }
                Ok(())
            },
        )
    })
}

/// Caps the device memory tilegraph may hold, in bytes (0: no cap). An allocation past it
/// fails the frame with TG_STATUS_OUT_OF_MEMORY, as the driver's would; the next frame retries.
#[no_mangle]
pub extern "C" fn tg_context_set_memory_budget(context: TgContext, bytes: u64) -> TgStatus {
    boundary("tg_context_set_memory_budget", || {
        registry::with(
            context.raw,
            Kind::Context,
            "context",
            |c: &ContextObject| {
                c.ctx.set_memory_budget((bytes != 0).then_some(bytes));
                Ok(())
            },
        )
    })
}

/// The device memory tilegraph holds now, in bytes.
///
/// # Safety
/// `out_bytes` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_context_memory(context: TgContext, out_bytes: *mut u64) -> TgStatus {
    boundary("tg_context_memory", || {
        // SAFETY: the caller's contract.
        let out_bytes = unsafe { out(out_bytes, "out_bytes") }?;
        registry::with(
            context.raw,
            Kind::Context,
            "context",
            |c: &ContextObject| {
                *out_bytes = c.ctx.allocated_bytes();
                Ok(())
            },
        )
    })
}

/// Where `tg_context_inject_fault_at` makes a call fail.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgFaultSite {
    /// The start of the next frame's recording (what `tg_context_inject_fault` injects).
    FrameStart = 0,
    /// The frame's submission — by tilegraph's own executor; an engine submits its frames
    /// itself, so its renderers never reach this site.
    Submit = 1,
    /// The wait for a frame slot's fence (tilegraph's own executor, likewise).
    FenceWait = 2,
    /// A graphics pipeline's creation (a renderer's first frames, or after its plan changes).
    PipelineCreation = 3,
    /// A memory allocation (a frame's resources, a grown buffer).
    Allocation = 4,
}

/// Fault injection at a site inside a frame: the next call that reaches `site` (a
/// TgFaultSite) fails as if its Vulkan call had returned `vk_result`, with the statuses of
/// `tg_context_inject_fault`. The frame then fails: reset its command buffer, do not submit it;
/// the next frame records as if the fault had not been.
#[no_mangle]
pub extern "C" fn tg_context_inject_fault_at(
    context: TgContext,
    site: u32,
    vk_result: i32,
) -> TgStatus {
    boundary("tg_context_inject_fault_at", || {
        let site = match site {
            0 => FaultSite::FrameStart,
            1 => FaultSite::Submit,
            2 => FaultSite::FenceWait,
            3 => FaultSite::PipelineCreation,
            4 => FaultSite::Allocation,
            other => {
                return Err(Failure::invalid(format!(
                    "fault site {other} is no TgFaultSite"
                )))
            }
        };
        inject(context, site, vk_result)
    })
}

fn inject(context: TgContext, site: FaultSite, vk_result: i32) -> Result<(), Failure> {
    if vk_result >= 0 {
        return Err(Failure::invalid(format!(
            "VkResult {vk_result} is not an error code"
        )));
    }
    registry::with(
        context.raw,
        Kind::Context,
        "context",
        |c: &ContextObject| {
            c.ctx.inject_fault_at(site, vk::Result::from_raw(vk_result));
            Ok(())
        },
    )
}

/// Fault injection for the engine's tests of its error paths: the next frame recorded on the
/// context fails, after it began, as if a Vulkan call had returned `vk_result` (a negative
/// VkResult: VK_ERROR_DEVICE_LOST is TG_STATUS_DEVICE_LOST, VK_ERROR_OUT_OF_DEVICE_MEMORY
/// TG_STATUS_OUT_OF_MEMORY, others TG_STATUS_VULKAN). The frame's command buffer must then be
/// reset, not submitted, as after any failure.
#[no_mangle]
pub extern "C" fn tg_context_inject_fault(context: TgContext, vk_result: i32) -> TgStatus {
    boundary("tg_context_inject_fault", || {
        inject(context, FaultSite::FrameStart, vk_result)
    })
}
