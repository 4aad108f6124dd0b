//! What a device must be created with for a [`crate::FeatureRequest`]: [`DeviceConfig`].

use std::collections::BTreeSet;
use std::ffi::CStr;

use ash::vk;

use crate::error::VkError;
use crate::features::{Feature, FeatureRequest, FeatureStructs};
use crate::instance::PhysicalDevice;

/// What a device must be created with for a [`FeatureRequest`]: the features (the required
/// ones, and the optional ones the device supports), their Vulkan feature structs, and the
/// extensions they need. An engine asks for it before creating its device, enables at least
/// this, and hands [`DeviceConfig::enabled`] to [`Context::adopt`].
pub struct DeviceConfig {
    pub enabled: BTreeSet<Feature>,
    pub extensions: Vec<&'static CStr>,
    /// The graphics + compute queue family tilegraph would use.
    pub queue_family: u32,
    structs: Box<FeatureStructs>,
    extension_ptrs: Vec<*const std::ffi::c_char>,
    api13: bool,
}

impl DeviceConfig {
    /// The configuration `request` needs on `physical`: an error naming what is missing when a
    /// required feature is not supported.
    pub fn new(physical: &PhysicalDevice, request: &FeatureRequest) -> Result<Self, VkError> {
        let missing: Vec<String> = request
            .required
            .iter()
            .filter(|f| !physical.supported.contains(f))
            .map(|f| f.to_string())
            .collect();
        if !missing.is_empty() {
            return Err(VkError::MissingRequired {
                device: physical.identity.device_name.clone(),
                what: "features",
                missing: missing.join(", "),
            });
        }
        let mut enabled: BTreeSet<Feature> = request.required.clone();
        for f in &request.optional {
            if physical.supported.contains(f) {
                enabled.insert(*f);
            } else {
                log::info!("optional feature {f} is not supported by {:?}; passes that want it take another path", physical.identity.device_name);
            }
        }
        let queue_family = physical
            .queue_family
            .ok_or_else(|| VkError::MissingRequired {
                device: physical.identity.device_name.clone(),
                what: "queue family",
                missing: "graphics + compute".into(),
            })?;
        let api13 = physical.api13();
        let mut structs = Box::<FeatureStructs>::default();
        let mut extensions: Vec<&'static CStr> = Vec::new();
        for f in &enabled {
            structs.set(*f, api13);
            if let Some(e) = FeatureStructs::extension(*f, api13) {
                if !extensions.contains(&e) {
                    extensions.push(e);
                }
            }
        }
        // A portability implementation (MoltenVK) must have its subset extension enabled
        // (VUID-VkDeviceCreateInfo-pProperties-04451).
        let portability = c"VK_KHR_portability_subset";
        if physical.has_extension(portability) {
            extensions.push(portability);
        }
        let extension_ptrs = extensions.iter().map(|e| e.as_ptr()).collect();
        Ok(DeviceConfig {
            enabled,
            extensions,
            queue_family,
            structs,
            extension_ptrs,
            api13,
        })
    }

    /// Adds an extension of the engine's own (`VK_KHR_swapchain`, ...) to the list
    /// [`DeviceConfig::chain`] enables; a name already there is not repeated.
    pub fn add_extension(&mut self, name: &'static CStr) {
        if !self.extensions.contains(&name) {
            self.extensions.push(name);
            self.extension_ptrs.push(name.as_ptr());
        }
    }

    /// `info` with the extensions and the feature structs chained (replacing its extension
    /// list — add the engine's own with [`DeviceConfig::add_extension`]; `info` must chain no
    /// feature struct of its own).
    pub fn chain<'a>(&'a mut self, info: vk::DeviceCreateInfo<'a>) -> vk::DeviceCreateInfo<'a> {
        let uses = |f: Feature| self.enabled.contains(&f);
        let (sync2, dynrend, cond) = (
            uses(Feature::Synchronization2),
            uses(Feature::DynamicRendering),
            uses(Feature::ConditionalRendering),
        );
        let api13 = self.api13;
        let s = &mut *self.structs;
        let mut info = info.enabled_extension_names(&self.extension_ptrs);
        info.p_enabled_features = std::ptr::null();
        s.features2 = vk::PhysicalDeviceFeatures2::default().features(s.core);
        info = info
            .push_next(&mut s.features2)
            .push_next(&mut s.v11)
            .push_next(&mut s.v12);
        if api13 {
            info = info.push_next(&mut s.v13);
        } else {
            if sync2 {
                info = info.push_next(&mut s.sync2);
            }
            if dynrend {
                info = info.push_next(&mut s.dynrend);
            }
        }
        if cond {
            info = info.push_next(&mut s.cond);
        }
        info
    }
}
