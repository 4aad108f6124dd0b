//! The logical device: created for one physical device, with only the requested features, the
//! profile chosen for it, and a gpu-allocator whose allocations land in the profile's memory type.

use std::collections::BTreeSet;
use std::ffi::CStr;
use std::mem::ManuallyDrop;
use std::sync::atomic::AtomicU64;
use std::sync::Mutex;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use gpu_allocator::{AllocationSizes, AllocatorDebugSettings};
use tilegraph_profile::{Profile, ProfileSet, Selection};

use crate::error::{VkError, VkResultExt};
use crate::features::{Feature, FeatureRequest, FeatureStructs};
use crate::instance::{Instance, PhysicalDevice};
use crate::validation::Validation;

/// How to build a [`Context`].
#[derive(Debug, Clone)]
pub struct ContextOptions {
    pub app_name: String,
    pub validation: Validation,
    /// Index or name substring of the device (`TILEGRAPH_DEVICE`).
    pub device: Option<String>,
    /// Profile forced by name (`TILEGRAPH_PROFILE`).
    pub profile: Option<String>,
    pub features: FeatureRequest,
}

impl ContextOptions {
    /// Options from the environment: `TILEGRAPH_DEVICE`, `TILEGRAPH_PROFILE`,
    /// `TILEGRAPH_VALIDATION`, with the executor's own required features.
    pub fn from_env() -> Self {
        ContextOptions {
            app_name: "tilegraph".into(),
            validation: Validation::from_env(),
            device: std::env::var("TILEGRAPH_DEVICE").ok(),
            profile: std::env::var(tilegraph_profile::PROFILE_ENV).ok(),
            features: FeatureRequest::executor(),
        }
    }
}

/// Device-level function tables for paths that differ between Vulkan 1.2 (+extensions) and 1.3.
pub(crate) enum Sync2 {
    Core,
    Khr(ash::khr::synchronization2::Device),
    Missing,
}
pub(crate) enum DynRendering {
    Core,
    Khr(ash::khr::dynamic_rendering::Device),
    Missing,
}

/// The device a frame runs on.
pub struct Context {
    pub physical: PhysicalDevice,
    pub selection: Selection,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub(crate) enabled: BTreeSet<Feature>,
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) allocations: AtomicU64,
    pub(crate) sync2: Sync2,
    pub(crate) dynrend: DynRendering,
    pub(crate) debug_utils: Option<ash::ext::debug_utils::Device>,
    pub(crate) conditional: Option<ash::ext::conditional_rendering::Device>,
    pub(crate) upload_pool: vk::CommandPool,
    /// The device and what it owns are destroyed (by `destroy_checked` or Drop).
    device_destroyed: bool,
    // Declared last: dropped after the device is destroyed in Drop.
    instance: ManuallyDrop<Instance>,
    /// Not `Sync`: the upload pool and the queue are used by `&self` methods and must be
    /// externally synchronized (one thread at a time). Still `Send`.
    _one_thread: std::marker::PhantomData<std::cell::Cell<()>>,
}

impl Context {
    /// Creates the instance, picks the device, selects its profile and creates the logical device
    /// with exactly the features requested (required ones must exist; optional ones are logged).
    pub fn new(options: ContextOptions) -> Result<Self, VkError> {
        let instance = Instance::new(&options.app_name, options.validation)?;
        let physical = instance.choose_device(options.device.as_deref())?;
        let profiles = ProfileSet::from_env()?;
        let mut selection = profiles.select(&physical.identity, options.profile.as_deref())?;
        if selection.profile.render_pass.store_op_none && !physical.api13() {
            // VK_ATTACHMENT_STORE_OP_NONE is core from 1.3 (tilegraph enables none of the
            // extensions that add it earlier): plans for this device store read-only
            // attachments instead, and the graph synchronizes that store as the write it is.
            log::info!(
                "{:?} is a Vulkan {} device: profile {} plans STORE instead of STORE_OP_NONE",
                physical.identity.device_name,
                physical.identity.api_version_string(),
                selection.profile.name
            );
            selection.profile.render_pass.store_op_none = false;
        }
        log::info!(
            "device {:?} ({}; Vulkan {}), profile {} ({})",
            physical.identity.device_name,
            physical.driver_name,
            physical.identity.api_version_string(),
            selection.profile.name,
            selection.matched_by
        );
        Self::with_instance(instance, physical, selection, &options.features)
    }

    fn with_instance(
        instance: Instance,
        physical: PhysicalDevice,
        selection: Selection,
        request: &FeatureRequest,
    ) -> Result<Self, VkError> {
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
        let api13 = physical.identity.api_version >= vk::API_VERSION_1_3;
        let queue_family = physical
            .queue_family
            .ok_or_else(|| VkError::MissingRequired {
                device: physical.identity.device_name.clone(),
                what: "queue family",
                missing: "graphics + compute".into(),
            })?;

        let mut s = FeatureStructs::default();
        let mut ext_names: Vec<&CStr> = Vec::new();
        for f in &enabled {
            s.set(*f, api13);
            if let Some(e) = FeatureStructs::extension(*f, api13) {
                if !ext_names.contains(&e) {
                    ext_names.push(e);
                }
            }
        }
        // A portability implementation (MoltenVK) must have its subset extension enabled
        // (VUID-VkDeviceCreateInfo-pProperties-04451).
        let portability = c"VK_KHR_portability_subset";
        if physical
            .extensions
            .iter()
            .any(|e| e.as_c_str() == portability)
        {
            ext_names.push(portability);
        }
        let ext_ptrs: Vec<_> = ext_names.iter().map(|e| e.as_ptr()).collect();
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let uses = |f: Feature| enabled.contains(&f);
        let mut f2 = vk::PhysicalDeviceFeatures2::default().features(s.core);
        let mut info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&ext_ptrs);
        info = info
            .push_next(&mut f2)
            .push_next(&mut s.v11)
            .push_next(&mut s.v12);
        if api13 {
            info = info.push_next(&mut s.v13);
        } else {
            if uses(Feature::Synchronization2) {
                info = info.push_next(&mut s.sync2);
            }
            if uses(Feature::DynamicRendering) {
                info = info.push_next(&mut s.dynrend);
            }
        }
        if uses(Feature::ConditionalRendering) {
            info = info.push_next(&mut s.cond);
        }
        // SAFETY: feature structs are chained only for this API version / enabled extensions, and
        // every enabled feature was reported as supported.
        let device = unsafe { instance.raw.create_device(physical.raw, &info, None) }
            .vk("vkCreateDevice")?;
        // SAFETY: queue 0 of a family we created.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let sync2 = match (uses(Feature::Synchronization2), api13) {
            (false, _) => Sync2::Missing,
            (true, true) => Sync2::Core,
            (true, false) => Sync2::Khr(ash::khr::synchronization2::Device::new(
                &instance.raw,
                &device,
            )),
        };
        let dynrend = match (uses(Feature::DynamicRendering), api13) {
            (false, _) => DynRendering::Missing,
            (true, true) => DynRendering::Core,
            (true, false) => DynRendering::Khr(ash::khr::dynamic_rendering::Device::new(
                &instance.raw,
                &device,
            )),
        };
        let debug_utils = instance
            .debug_utils
            .as_ref()
            .map(|_| ash::ext::debug_utils::Device::new(&instance.raw, &device));
        let conditional = uses(Feature::ConditionalRendering)
            .then(|| ash::ext::conditional_rendering::Device::new(&instance.raw, &device));

        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.raw.clone(),
            device: device.clone(),
            physical_device: physical.raw,
            debug_settings: AllocatorDebugSettings::default(),
            buffer_device_address: false,
            allocation_sizes: AllocationSizes::default(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: nothing was created from the device yet.
                unsafe { device.destroy_device(None) };
                return Err(VkError::Allocation {
                    name: "allocator".into(),
                    source,
                });
            }
        };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            .flags(
                vk::CommandPoolCreateFlags::TRANSIENT
                    | vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER,
            );
        // SAFETY: valid device and family.
        let upload_pool = match unsafe { device.create_command_pool(&pool_info, None) } {
            Ok(p) => p,
            Err(r) => {
                drop(allocator);
                // SAFETY: the allocator is gone; nothing else was created.
                unsafe { device.destroy_device(None) };
                return Err(VkError::call("vkCreateCommandPool", r));
            }
        };
        log::info!(
            "device created with features [{}] and extensions [{}]",
            enabled
                .iter()
                .map(|f| f.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            ext_names
                .iter()
                .map(|e| e.to_string_lossy())
                .collect::<Vec<_>>()
                .join(", ")
        );
        Ok(Context {
            physical,
            selection,
            device,
            queue,
            queue_family,
            enabled,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            allocations: AtomicU64::new(0),
            sync2,
            dynrend,
            debug_utils,
            conditional,
            upload_pool,
            device_destroyed: false,
            instance: ManuallyDrop::new(instance),
            _one_thread: std::marker::PhantomData,
        })
    }

    pub fn profile(&self) -> &Profile {
        &self.selection.profile
    }

    pub fn instance(&self) -> &Instance {
        &self.instance
    }

    /// Why the device cannot create a 2D optimal-tiling image of this format, usage, sample
    /// count, mip count and extent (`vkGetPhysicalDeviceImageFormatProperties`), or `None` when
    /// it can. Creating an unsupported combination would be invalid usage, not an error code.
    pub fn image_support_problem(
        &self,
        format: vk::Format,
        usage: vk::ImageUsageFlags,
        samples: vk::SampleCountFlags,
        mip_levels: u32,
        extent: vk::Extent2D,
    ) -> Option<String> {
        // SAFETY: valid physical device of this instance.
        let props = unsafe {
            self.instance
                .raw
                .get_physical_device_image_format_properties(
                    self.physical.raw,
                    format,
                    vk::ImageType::TYPE_2D,
                    vk::ImageTiling::OPTIMAL,
                    usage,
                    vk::ImageCreateFlags::empty(),
                )
        };
        let props = match props {
            Ok(p) => p,
            Err(vk::Result::ERROR_FORMAT_NOT_SUPPORTED) => {
                return Some(format!("{format:?} with usage {usage:?} is not supported"))
            }
            Err(r) => return Some(format!("vkGetPhysicalDeviceImageFormatProperties: {r:?}")),
        };
        if !props.sample_counts.contains(samples) {
            return Some(format!(
                "{format:?} with usage {usage:?} supports samples {:?}, not {samples:?}",
                props.sample_counts
            ));
        }
        if mip_levels > props.max_mip_levels
            || extent.width > props.max_extent.width
            || extent.height > props.max_extent.height
        {
            return Some(format!(
                "{format:?} with usage {usage:?} allows {} mips and {}x{} px",
                props.max_mip_levels, props.max_extent.width, props.max_extent.height
            ));
        }
        None
    }

    pub fn has_feature(&self, f: Feature) -> bool {
        self.enabled.contains(&f)
    }

    pub fn enabled_features(&self) -> &BTreeSet<Feature> {
        &self.enabled
    }

    /// Validation messages since the last call (and clears them). A test calls
    /// [`Context::check_validation`] at its end.
    pub fn take_validation_messages(&self) -> Vec<String> {
        self.instance.validation().take()
    }

    /// `Err` with every validation message reported so far; clears them.
    pub fn check_validation(&self) -> Result<(), VkError> {
        let m = self.take_validation_messages();
        if m.is_empty() {
            Ok(())
        } else {
            Err(VkError::Validation {
                count: m.len(),
                messages: m.join("\n"),
            })
        }
    }

    pub fn validation_enabled(&self) -> bool {
        self.instance.validation_enabled()
    }

    /// Waits until the device is idle.
    pub fn wait_idle(&self) -> Result<(), VkError> {
        // SAFETY: valid device.
        unsafe { self.device.device_wait_idle() }.vk("vkDeviceWaitIdle")
    }
}

pub(crate) fn missing_feature(f: Feature) -> VkError {
    VkError::MissingRequired {
        device: String::new(),
        what: "feature (not enabled)",
        missing: f.to_string(),
    }
}

impl Context {
    /// Destroys the device (waiting for it first) and everything it owns, keeping the instance.
    /// Runs once.
    fn destroy_device(&mut self) {
        if self.device_destroyed {
            return;
        }
        self.device_destroyed = true;
        // SAFETY: teardown order: wait, then every child object, the allocator (which frees its
        // memory blocks), then the device. Runs once (flag above).
        unsafe {
            if let Err(e) = self.device.device_wait_idle() {
                log::error!("vkDeviceWaitIdle at teardown: {e}");
            }
            self.device.destroy_command_pool(self.upload_pool, None);
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
        }
    }

    /// Tears the context down and checks validation once more: the layer reports the objects
    /// still alive when the device is destroyed (a leaked pipeline, buffer or view), which no
    /// check before the teardown can see. Tests end with this.
    pub fn destroy_checked(mut self) -> Result<(), VkError> {
        let mut messages = self.take_validation_messages();
        self.destroy_device();
        messages.extend(self.take_validation_messages());
        if messages.is_empty() {
            Ok(())
        } else {
            Err(VkError::Validation {
                count: messages.len(),
                messages: messages.join("\n"),
            })
        }
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        self.destroy_device();
        // SAFETY: the device is gone; the instance (and its debug messenger) goes last.
        unsafe { ManuallyDrop::drop(&mut self.instance) };
    }
}
