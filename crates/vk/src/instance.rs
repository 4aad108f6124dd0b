//! The Vulkan instance, the validation layer and physical-device discovery.

use std::collections::BTreeSet;
use std::ffi::{CStr, CString};

use ash::vk;
use tilegraph_profile::{DeviceIdentity, DeviceType, MemoryFlags, MemoryHeap, MemoryType};

use crate::error::{VkError, VkResultExt};
use crate::features::{Feature, FeatureStructs, EXT_CONDITIONAL_RENDERING, KHR_DYNREND, KHR_SYNC2};
use crate::validation::{debug_callback, Validation, ValidationSink};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";
/// Lowest API version tilegraph runs on.
pub const MIN_API_VERSION: u32 = vk::API_VERSION_1_2;

/// Owns the loader, the instance, and (when validation is on) the debug messenger and the sink
/// that collects its messages.
pub struct Instance {
    /// Keeps the loader library loaded for as long as the instance lives.
    _entry: ash::Entry,
    pub(crate) raw: ash::Instance,
    pub(crate) debug_utils: Option<ash::ext::debug_utils::Instance>,
    messenger: vk::DebugUtilsMessengerEXT,
    /// Boxed so its address, handed to the messenger, never moves.
    sink: Box<ValidationSink>,
    validation_enabled: bool,
    /// tilegraph created the instance and destroys it; an adopted one is the engine's.
    owned: bool,
}

/// One physical device as discovered, before any logical device exists.
#[derive(Debug, Clone)]
pub struct PhysicalDevice {
    pub index: usize,
    pub raw: vk::PhysicalDevice,
    pub identity: DeviceIdentity,
    pub driver_name: String,
    pub driver_info: String,
    /// Features the device supports among those tilegraph knows.
    pub supported: BTreeSet<Feature>,
    /// Queue family with graphics and compute, if any.
    pub queue_family: Option<u32>,
    /// A queue for async compute beside the first of `queue_family`, as (family, index): the
    /// first queue of a compute-only family with timestamps where the device has one (its own
    /// engine on most desktop GPUs), else the second queue of `queue_family`.
    pub async_compute_queue: Option<(u32, u32)>,
    pub limits: DeviceLimits,
    pub(crate) extensions: BTreeSet<CString>,
}

/// The limits the executor and passes consult.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct DeviceLimits {
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    /// Valid bits of timestamps on the chosen queue family (0 = no timestamps).
    pub timestamp_valid_bits: u32,
    pub max_color_attachments: u32,
    pub max_image_dimension_2d: u32,
    pub max_compute_work_group_invocations: u32,
    /// The largest range of a storage buffer one descriptor may bind.
    pub max_storage_buffer_range: u32,
    /// Granularity of flush/invalidate on non-coherent host memory.
    pub non_coherent_atom_size: u64,
    /// `bufferImageGranularity`: buffers and optimal-tiling images placed in one allocation must
    /// not share a page of this size.
    pub buffer_image_granularity: u64,
    /// `subPixelPrecisionBits`: the rasterizer snaps vertices to 1 / 2^bits of a pixel (what the
    /// cluster cone test leaves room for).
    pub sub_pixel_precision_bits: u32,
    /// The fewest of `maxPerStageDescriptorSamplers` / `...SampledImages` and
    /// `maxDescriptorSetSamplers` / `...SampledImages`: how many combined image samplers one
    /// shader stage may bind (16 on some phones).
    pub max_sampled_images: u32,
    /// `maxImageArrayLayers`.
    pub max_image_array_layers: u32,
}

impl PhysicalDevice {
    pub fn api_version(&self) -> u32 {
        self.identity.api_version
    }
    pub fn api13(&self) -> bool {
        self.identity.api_version >= vk::API_VERSION_1_3
    }
    pub fn has_extension(&self, name: &CStr) -> bool {
        self.extensions.contains(name)
    }
}

impl Instance {
    /// Creates the instance. With validation, `VK_LAYER_KHRONOS_validation` is loaded with
    /// synchronization validation and the best-practices checks enabled, and every message goes
    /// through `log` and the sink (but the reviewed [`crate::SILENCED`] ones).
    pub fn new(app_name: &str, validation: Validation) -> Result<Self, VkError> {
        // SAFETY: loading the system Vulkan loader; failure is reported, not assumed.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::Loader(e.to_string()))?;
        // SAFETY: plain global queries on a loaded entry.
        let layers = unsafe { entry.enumerate_instance_layer_properties() }
            .vk("vkEnumerateInstanceLayerProperties")?;
        let has_layer = layers
            .iter()
            .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
        let validation_enabled = match (validation, has_layer) {
            (Validation::Off, _) => false,
            (_, true) => true,
            (Validation::IfAvailable, false) => {
                log::warn!(
                    "VK_LAYER_KHRONOS_validation is not installed: running without validation"
                );
                false
            }
            (Validation::Required, false) => return Err(VkError::ValidationLayerMissing),
        };
        // SAFETY: global query; None = the implementation's own extensions.
        let exts = unsafe { entry.enumerate_instance_extension_properties(None) }
            .vk("vkEnumerateInstanceExtensionProperties")?;
        let has_ext = |name: &CStr| {
            exts.iter()
                .any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name))
        };
        // The validation layer also provides VK_EXT_debug_utils itself.
        let layer_exts = if validation_enabled {
            // SAFETY: global query for the layer's own extensions.
            unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                .vk("vkEnumerateInstanceExtensionProperties(layer)")?
        } else {
            Vec::new()
        };
        let layer_has = |name: &CStr| {
            layer_exts
                .iter()
                .any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name))
        };
        let debug_utils_available =
            has_ext(ash::ext::debug_utils::NAME) || layer_has(ash::ext::debug_utils::NAME);
        // Without a messenger nothing would be reported: validation that cannot report is off.
        if validation_enabled && !debug_utils_available {
            if validation == Validation::Required {
                return Err(VkError::MissingRequired {
                    device: "the Vulkan instance".into(),
                    what: "extension (validation messages need it)",
                    missing: "VK_EXT_debug_utils".into(),
                });
            }
            log::warn!("VK_EXT_debug_utils is missing: validation messages cannot be reported");
        }

        let app_name_c = CString::new(app_name.replace('\0', "")).unwrap_or_default();
        let app = vk::ApplicationInfo::default()
            .application_name(&app_name_c)
            .engine_name(c"tilegraph")
            .engine_version(vk::make_api_version(0, 0, 1, 0))
            .api_version(vk::API_VERSION_1_3);
        let mut layer_ptrs = Vec::new();
        let mut ext_ptrs = Vec::new();
        if debug_utils_available {
            ext_ptrs.push(ash::ext::debug_utils::NAME.as_ptr());
        }
        if has_ext(ash::khr::portability_enumeration::NAME) {
            ext_ptrs.push(ash::khr::portability_enumeration::NAME.as_ptr());
        }
        let mut validation_ext = false;
        if validation_enabled {
            layer_ptrs.push(VALIDATION_LAYER.as_ptr());
            validation_ext = layer_has(ash::ext::validation_features::NAME);
            if validation_ext {
                ext_ptrs.push(ash::ext::validation_features::NAME.as_ptr());
            } else {
                log::warn!("validation layer lacks VK_EXT_validation_features: synchronization validation is off");
            }
        }
        let sink = Box::new(ValidationSink::default());
        let severity = vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
            | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
            | vk::DebugUtilsMessageSeverityFlagsEXT::INFO;
        let kinds = vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
            | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
            | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE;
        let sink_ptr = &*sink as *const ValidationSink as *mut std::ffi::c_void;
        let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(severity)
            .message_type(kinds)
            .pfn_user_callback(Some(debug_callback))
            .user_data(sink_ptr);
        // Best practices too: the vendor checks (Arm, IMG, NVIDIA) are switched on for a whole
        // process by a `vk_layer_settings.txt` (`cargo xtask test` runs one process per vendor).
        let enables = [
            vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION,
            vk::ValidationFeatureEnableEXT::BEST_PRACTICES,
        ];
        // The layer's shader validation cache is one file per user that every device reads at
        // creation and rewrites at destruction; devices of parallel tests share it, and it is
        // one suspect of a rare crash of test binaries. Off: the layer validates each shader
        // module again instead (milliseconds for tilegraph's shaders).
        let disables = [vk::ValidationFeatureDisableEXT::SHADER_VALIDATION_CACHE];
        let mut features = vk::ValidationFeaturesEXT::default()
            .enabled_validation_features(&enables)
            .disabled_validation_features(&disables);
        let flags = if has_ext(ash::khr::portability_enumeration::NAME) {
            vk::InstanceCreateFlags::ENUMERATE_PORTABILITY_KHR
        } else {
            vk::InstanceCreateFlags::empty()
        };
        let mut info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layer_ptrs)
            .enabled_extension_names(&ext_ptrs)
            .flags(flags);
        if validation_enabled && debug_utils_available {
            // Chained so that messages from vkCreateInstance/vkDestroyInstance are caught too.
            info = info.push_next(&mut messenger_info);
        }
        if validation_ext {
            info = info.push_next(&mut features);
        }
        // SAFETY: every pointer in `info` refers to locals that outlive the call.
        let raw = unsafe { entry.create_instance(&info, None) }.vk("vkCreateInstance")?;
        let debug_utils =
            debug_utils_available.then(|| ash::ext::debug_utils::Instance::new(&entry, &raw));
        let mut messenger = vk::DebugUtilsMessengerEXT::null();
        if let (true, Some(du)) = (validation_enabled, &debug_utils) {
            // SAFETY: the sink outlives the messenger: Drop destroys the messenger first.
            match unsafe { du.create_debug_utils_messenger(&messenger_info, None) } {
                Ok(m) => messenger = m,
                Err(r) => {
                    // SAFETY: nothing else was created from this instance yet.
                    unsafe { raw.destroy_instance(None) };
                    return Err(VkError::call("vkCreateDebugUtilsMessengerEXT", r));
                }
            }
        }
        log::info!(
            "Vulkan instance created (validation {}, debug utils {})",
            if validation_enabled {
                "on, synchronization validation and best practices on"
            } else {
                "off"
            },
            if debug_utils_available { "on" } else { "off" }
        );
        Ok(Instance {
            _entry: entry,
            raw,
            debug_utils,
            messenger,
            sink,
            validation_enabled,
            owned: true,
        })
    }

    /// An instance the engine created, adopted from its handle and the `vkGetInstanceProcAddr`
    /// it was created through. tilegraph never destroys it and installs no messenger: validation
    /// messages go wherever the engine sends them. Object names and debug labels are used only
    /// when `debug_utils` says the engine enabled `VK_EXT_debug_utils` on it.
    ///
    /// # Safety
    ///
    /// `get_instance_proc_addr` resolves functions for `raw` (the loader's, or a layer
    /// chain's), `raw` is a live instance, and both stay valid until every object tilegraph
    /// makes from this adoption is gone; with `debug_utils`, the extension is enabled on `raw`.
    pub unsafe fn adopt(
        get_instance_proc_addr: vk::PFN_vkGetInstanceProcAddr,
        raw: vk::Instance,
        debug_utils: bool,
    ) -> Result<Self, VkError> {
        if raw == vk::Instance::null() {
            return Err(VkError::Invalid {
                what: "adopted instance".into(),
                reason: "the handle is null".into(),
            });
        }
        // SAFETY: the caller vouches for the function and the handle (above).
        let entry = unsafe {
            ash::Entry::from_static_fn(ash::StaticFn {
                get_instance_proc_addr,
            })
        };
        // SAFETY: as above: `raw` was created through this entry point.
        let instance = unsafe { ash::Instance::load(entry.static_fn(), raw) };
        let debug_utils =
            debug_utils.then(|| ash::ext::debug_utils::Instance::new(&entry, &instance));
        Ok(Instance {
            _entry: entry,
            raw: instance,
            debug_utils,
            messenger: vk::DebugUtilsMessengerEXT::null(),
            sink: Box::default(),
            validation_enabled: false,
            owned: false,
        })
    }

    /// Whether tilegraph created this instance (and destroys it).
    pub fn owned(&self) -> bool {
        self.owned
    }

    /// The physical device `raw` of this instance, described, with `queue_family` as the
    /// queue family tilegraph records for (it must do graphics and compute).
    pub fn physical_device(
        &self,
        raw: vk::PhysicalDevice,
        queue_family: u32,
    ) -> Result<PhysicalDevice, VkError> {
        // SAFETY: valid instance.
        let raws =
            unsafe { self.raw.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
        let index = raws
            .iter()
            .position(|&r| r == raw)
            .ok_or_else(|| VkError::Invalid {
                what: "adopted physical device".into(),
                reason: "it is not a physical device of the adopted instance".into(),
            })?;
        let mut pd = self.describe(index, raw)?;
        // SAFETY: `raw` belongs to this instance (found above).
        let families = unsafe { self.raw.get_physical_device_queue_family_properties(raw) };
        let want = vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE;
        let family = families
            .get(queue_family as usize)
            .filter(|q| q.queue_flags.contains(want))
            .ok_or_else(|| VkError::MissingRequired {
                device: pd.identity.device_name.clone(),
                what: "queue family",
                missing: format!("graphics + compute on family {queue_family}"),
            })?;
        pd.queue_family = Some(queue_family);
        pd.async_compute_queue = async_compute_queue(&families, queue_family);
        pd.limits.timestamp_valid_bits = family.timestamp_valid_bits;
        Ok(pd)
    }

    pub fn validation_enabled(&self) -> bool {
        self.validation_enabled
    }

    pub fn raw(&self) -> &ash::Instance {
        &self.raw
    }

    /// Validation messages collected so far.
    pub fn validation(&self) -> &ValidationSink {
        &self.sink
    }

    /// Every physical device, with its identity and what it supports.
    pub fn physical_devices(&self) -> Result<Vec<PhysicalDevice>, VkError> {
        // SAFETY: valid instance.
        let raws =
            unsafe { self.raw.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
        raws.into_iter()
            .enumerate()
            .map(|(index, raw)| self.describe(index, raw))
            .collect()
    }

    fn describe(&self, index: usize, raw: vk::PhysicalDevice) -> Result<PhysicalDevice, VkError> {
        let inst = &self.raw;
        // SAFETY: `raw` comes from this instance.
        let props = unsafe { inst.get_physical_device_properties(raw) };
        let api12 = props.api_version >= vk::API_VERSION_1_2;
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        if api12 {
            let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
            // SAFETY: DriverProperties is core in 1.2, which this device reports.
            unsafe { inst.get_physical_device_properties2(raw, &mut props2) };
        }
        // SAFETY: plain queries on a valid physical device.
        let mem = unsafe { inst.get_physical_device_memory_properties(raw) };
        let queues = unsafe { inst.get_physical_device_queue_family_properties(raw) };
        let ext_props = unsafe { inst.enumerate_device_extension_properties(raw) }
            .vk("vkEnumerateDeviceExtensionProperties")?;
        let extensions: BTreeSet<CString> = ext_props
            .iter()
            .filter_map(|e| e.extension_name_as_c_str().ok().map(CStr::to_owned))
            .collect();
        let want = vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE;
        let queue_family = queues
            .iter()
            .position(|q| q.queue_flags.contains(want))
            .map(|i| i as u32);
        let timestamp_valid_bits = queue_family
            .and_then(|i| queues.get(i as usize))
            .map_or(0, |q| q.timestamp_valid_bits);
        let async_compute_queue = queue_family.and_then(|g| async_compute_queue(&queues, g));

        let name = props
            .device_name_as_c_str()
            .map(|c| c.to_string_lossy().into_owned())
            .unwrap_or_default();
        let memory_types = mem.memory_types
            [..(mem.memory_type_count as usize).min(vk::MAX_MEMORY_TYPES)]
            .iter()
            .map(|t| MemoryType {
                flags: MemoryFlags(t.property_flags.as_raw()),
                heap_index: t.heap_index,
            })
            .collect();
        let memory_heaps = mem.memory_heaps
            [..(mem.memory_heap_count as usize).min(vk::MAX_MEMORY_HEAPS)]
            .iter()
            .map(|h| MemoryHeap {
                size_bytes: h.size,
                device_local: h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL),
            })
            .collect();
        let device_type = match props.device_type {
            vk::PhysicalDeviceType::INTEGRATED_GPU => DeviceType::IntegratedGpu,
            vk::PhysicalDeviceType::DISCRETE_GPU => DeviceType::DiscreteGpu,
            vk::PhysicalDeviceType::VIRTUAL_GPU => DeviceType::VirtualGpu,
            vk::PhysicalDeviceType::CPU => DeviceType::Cpu,
            _ => DeviceType::Other,
        };
        let identity = DeviceIdentity {
            vendor_id: props.vendor_id,
            device_id: props.device_id,
            driver_id: if api12 {
                driver.driver_id.as_raw() as u32
            } else {
                0
            },
            device_name: name,
            driver_version: props.driver_version,
            api_version: props.api_version,
            device_type,
            memory_types,
            memory_heaps,
        };
        let mut pd = PhysicalDevice {
            index,
            raw,
            identity,
            driver_name: driver
                .driver_name_as_c_str()
                .map(|c| c.to_string_lossy().into_owned())
                .unwrap_or_default(),
            driver_info: driver
                .driver_info_as_c_str()
                .map(|c| c.to_string_lossy().into_owned())
                .unwrap_or_default(),
            supported: BTreeSet::new(),
            queue_family,
            async_compute_queue,
            limits: DeviceLimits {
                timestamp_period_ns: props.limits.timestamp_period,
                timestamp_valid_bits,
                max_color_attachments: props.limits.max_color_attachments,
                max_image_dimension_2d: props.limits.max_image_dimension2_d,
                max_compute_work_group_invocations: props.limits.max_compute_work_group_invocations,
                max_storage_buffer_range: props.limits.max_storage_buffer_range,
                non_coherent_atom_size: props.limits.non_coherent_atom_size.max(1),
                buffer_image_granularity: props.limits.buffer_image_granularity.max(1),
                sub_pixel_precision_bits: props.limits.sub_pixel_precision_bits,
                max_sampled_images: [
                    props.limits.max_per_stage_descriptor_samplers,
                    props.limits.max_per_stage_descriptor_sampled_images,
                    props.limits.max_descriptor_set_samplers,
                    props.limits.max_descriptor_set_sampled_images,
                ]
                .into_iter()
                .min()
                .unwrap_or(0),
                max_image_array_layers: props.limits.max_image_array_layers,
            },
            extensions,
        };
        if api12 {
            pd.supported = self.query_features(&pd);
        }
        Ok(pd)
    }

    fn query_features(&self, pd: &PhysicalDevice) -> BTreeSet<Feature> {
        let api13 = pd.api13();
        let mut s = FeatureStructs::default();
        let has_sync2 = pd.has_extension(KHR_SYNC2);
        let has_dynrend = pd.has_extension(KHR_DYNREND);
        let has_cond = pd.has_extension(EXT_CONDITIONAL_RENDERING);
        {
            let mut f2 = vk::PhysicalDeviceFeatures2::default()
                .push_next(&mut s.v11)
                .push_next(&mut s.v12);
            if api13 {
                f2 = f2.push_next(&mut s.v13);
            } else {
                if has_sync2 {
                    f2 = f2.push_next(&mut s.sync2);
                }
                if has_dynrend {
                    f2 = f2.push_next(&mut s.dynrend);
                }
            }
            if has_cond {
                f2 = f2.push_next(&mut s.cond);
            }
            // SAFETY: only structs valid for this API version / present extensions are chained.
            unsafe { self.raw.get_physical_device_features2(pd.raw, &mut f2) };
            s.core = f2.features;
        }
        Feature::ALL
            .into_iter()
            .filter(|f| {
                let ext_ok =
                    FeatureStructs::extension(*f, api13).is_none_or(|e| pd.has_extension(e));
                ext_ok && s.get(*f, api13)
            })
            .collect()
    }

    /// Chooses a device: `wanted` (index or case-insensitive name substring, from
    /// `TILEGRAPH_DEVICE`) or the most capable type: discrete > integrated > virtual > CPU.
    pub fn choose_device(&self, wanted: Option<&str>) -> Result<PhysicalDevice, VkError> {
        let all = self.physical_devices()?;
        let usable: Vec<&PhysicalDevice> = all
            .iter()
            .filter(|d| d.queue_family.is_some() && d.api_version() >= MIN_API_VERSION)
            .collect();
        let describe = |v: &[PhysicalDevice]| {
            v.iter()
                .map(|d| {
                    format!(
                        "{}: {} (Vulkan {})",
                        d.index,
                        d.identity.device_name,
                        d.identity.api_version_string()
                    )
                })
                .collect::<Vec<_>>()
                .join("; ")
        };
        if let Some(w) = wanted.map(str::trim).filter(|w| !w.is_empty()) {
            let found = match w.parse::<usize>() {
                Ok(i) => usable.iter().find(|d| d.index == i),
                Err(_) => {
                    let lw = w.to_lowercase();
                    usable
                        .iter()
                        .find(|d| d.identity.device_name.to_lowercase().contains(&lw))
                }
            };
            return found
                .map(|d| (*d).clone())
                .ok_or_else(|| VkError::DeviceNotFound {
                    wanted: w.to_string(),
                    available: describe(&all),
                });
        }
        usable
            .iter()
            .max_by_key(|d| {
                (
                    d.identity.device_type.preference(),
                    std::cmp::Reverse(d.index),
                )
            })
            .map(|d| (*d).clone())
            .ok_or_else(|| VkError::NoDevice {
                seen: describe(&all),
            })
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        if !self.owned {
            return; // the engine's: it destroys it
        }
        if let Some(du) = &self.debug_utils {
            if self.messenger != vk::DebugUtilsMessengerEXT::null() {
                // SAFETY: created from this instance; destroyed once, before the sink is dropped.
                unsafe { du.destroy_debug_utils_messenger(self.messenger, None) };
            }
        }
        // SAFETY: the Context that borrowed this instance has destroyed its device already
        // (Context owns the Instance and drops it last).
        unsafe { self.raw.destroy_instance(None) };
    }
}

/// The queue async compute would run on beside the first queue of `graphics`: a compute-only
/// family's first queue (with timestamps, which the per-pass timings write there), else the
/// second queue of `graphics`; `None` where the device has neither (lavapipe: one queue).
fn async_compute_queue(
    families: &[vk::QueueFamilyProperties],
    graphics: u32,
) -> Option<(u32, u32)> {
    let compute_only = families.iter().enumerate().find(|(i, q)| {
        *i as u32 != graphics
            && q.queue_count > 0
            && q.timestamp_valid_bits > 0
            && q.queue_flags.contains(vk::QueueFlags::COMPUTE)
            && !q.queue_flags.contains(vk::QueueFlags::GRAPHICS)
    });
    match compute_only {
        Some((i, _)) => Some((i as u32, 0)),
        None => families
            .get(graphics as usize)
            .filter(|q| q.queue_count >= 2)
            .map(|_| (graphics, 1)),
    }
}
