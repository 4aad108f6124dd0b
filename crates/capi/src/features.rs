//! `tg_enable_features`: tilegraph's features set in the engine's own Vulkan feature structs,
//! each checked by its `sType` before it is written.

use std::collections::BTreeSet;
use std::ffi::c_void;

use tilegraph_vk::ash::vk::{self, TaggedStructure};
use tilegraph_vk::{Feature, FeatureTargets};

use crate::context::{features_of, TgDeviceRequirements};
use crate::status::{arg, boundary, Failure, TgStatus};

/// The engine's feature structs that `tg_enable_features` sets booleans in; a null one is
/// one the engine does not chain (an error when a feature needs it).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct TgFeatureStructs {
    /// VkPhysicalDeviceFeatures2.
    pub features2: *mut c_void,
    /// VkPhysicalDeviceVulkan11Features.
    pub vulkan11: *mut c_void,
    /// VkPhysicalDeviceVulkan12Features.
    pub vulkan12: *mut c_void,
    /// VkPhysicalDeviceVulkan13Features (Vulkan 1.3 devices).
    pub vulkan13: *mut c_void,
    /// VkPhysicalDeviceSynchronization2Features (Vulkan 1.2 devices).
    pub synchronization2: *mut c_void,
    /// VkPhysicalDeviceDynamicRenderingFeatures (Vulkan 1.2 devices).
    pub dynamic_rendering: *mut c_void,
    /// VkPhysicalDeviceConditionalRenderingFeaturesEXT.
    pub conditional_rendering: *mut c_void,
}

/// Sets, in the engine's own feature structs, the booleans of every feature in
/// `requirements->features` (the engine chains the structs into VkDeviceCreateInfo itself,
/// with its own features set too). A feature whose struct is null or has the wrong sType is
/// TG_STATUS_INVALID_ARGUMENT naming the struct.
///
/// # Safety
/// `requirements` is valid; every non-null pointer in `structs` points to the Vulkan struct
/// its field names.
#[no_mangle]
pub unsafe extern "C" fn tg_enable_features(
    requirements: *const TgDeviceRequirements,
    structs: *const TgFeatureStructs,
) -> TgStatus {
    boundary("tg_enable_features", || {
        // SAFETY: the caller's contract.
        let req = unsafe { arg(requirements, "requirements") }?;
        // SAFETY: as above.
        let s = unsafe { arg(structs, "structs") }?;
        let features = features_of(req.features)?;
        // SAFETY: as above: each pointer is the struct it names (sType checked inside).
        unsafe { enable(&features, req.vulkan13 != 0, s) }
    })
}

/// The struct at `ptr`, if non-null, after checking its `sType`.
///
/// # Safety
/// A non-null `ptr` points to a live `T` (whose first field is `sType`).
unsafe fn tagged<'a, T: TaggedStructure>(
    ptr: *mut c_void,
    name: &str,
) -> Result<Option<&'a mut T>, Failure> {
    if ptr.is_null() {
        return Ok(None);
    }
    if ptr.align_offset(std::mem::align_of::<T>()) != 0 {
        return Err(Failure::new(
            TgStatus::Misaligned,
            format!("`structs->{name}` is not aligned for its struct"),
        ));
    }
    // SAFETY: every Vulkan struct with a TaggedStructure impl starts with its sType.
    let s_type = unsafe { *ptr.cast::<vk::StructureType>() };
    if s_type != T::STRUCTURE_TYPE {
        return Err(Failure::invalid(format!(
            "`structs->{name}` has sType {s_type:?}, not {:?}",
            T::STRUCTURE_TYPE
        )));
    }
    // SAFETY: the caller's contract, the sType agrees.
    Ok(Some(unsafe { &mut *ptr.cast::<T>() }))
}

/// Sets each of `features` in the struct the engine gave for it.
///
/// # Safety
/// Every non-null pointer of `s` points to the struct its field names.
unsafe fn enable(
    features: &BTreeSet<Feature>,
    api13: bool,
    s: &TgFeatureStructs,
) -> Result<(), Failure> {
    // SAFETY: the caller's contract (each checked by sType).
    let features2: Option<&mut vk::PhysicalDeviceFeatures2<'static>> =
        unsafe { tagged(s.features2, "features2") }?;
    let mut targets = FeatureTargets {
        core: features2.map(|f| &mut f.features),
        // SAFETY: as above.
        v11: unsafe { tagged(s.vulkan11, "vulkan11") }?,
        // SAFETY: as above.
        v12: unsafe { tagged(s.vulkan12, "vulkan12") }?,
        // SAFETY: as above.
        v13: unsafe { tagged(s.vulkan13, "vulkan13") }?,
        // SAFETY: as above.
        sync2: unsafe { tagged(s.synchronization2, "synchronization2") }?,
        // SAFETY: as above.
        dynrend: unsafe { tagged(s.dynamic_rendering, "dynamic_rendering") }?,
        // SAFETY: as above.
        cond: unsafe { tagged(s.conditional_rendering, "conditional_rendering") }?,
    };
    for f in features {
        targets.enable(*f, api13).map_err(|name| {
            Failure::invalid(format!(
                "feature {f} goes in {name}, and `structs` has none (chain one and pass it)"
            ))
        })?;
    }
    Ok(())
}
