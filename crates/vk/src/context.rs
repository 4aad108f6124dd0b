//! The logical device: created for one physical device, with only the requested features, the
//! profile chosen for it, and a gpu-allocator whose allocations land in the profile's memory type.

use std::collections::BTreeSet;
use std::mem::ManuallyDrop;
use std::sync::atomic::AtomicU64;
use std::sync::Mutex;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use gpu_allocator::{AllocationSizes, AllocatorDebugSettings};
use tilegraph_profile::{Profile, ProfileSet, Selection};

pub use crate::device_config::DeviceConfig;
use crate::error::{VkError, VkResultExt};
use crate::features::{Feature, FeatureRequest};
use crate::instance::{Instance, PhysicalDevice, MIN_API_VERSION};
use crate::validation::Validation;

/// Where [`Context::inject_fault_at`] makes a call fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FaultSite {
    /// The start of the next frame's recording, before anything is recorded.
    FrameStart,
    /// The frame's `vkQueueSubmit` (the executor's own submission).
    Submit,
    /// The wait for a frame slot's fence before the slot is reused.
    FenceWait,
    /// `vkCreateGraphicsPipelines` (a pipeline made while a frame records).
    PipelineCreation,
    /// A memory allocation (resources built while a frame records, buffers grown).
    Allocation,
}

/// How to build a [`Context`].
#[derive(Debug, Clone)]
pub struct ContextOptions {
    pub app_name: String,
    pub validation: Validation,
    /// Index or name substring of the device (`TILEGRAPH_DEVICE`).
    pub device: Option<String>,
    /// Profile forced by name (`TILEGRAPH_PROFILE`).
    pub profile: Option<String>,
    /// Who forced [`Self::profile`], as the selection reports it: `TILEGRAPH_PROFILE` unless
    /// the caller says otherwise ([`Self::force_profile`]).
    pub profile_forced_by: String,
    pub features: FeatureRequest,
    /// Where the device has no second queue for async compute (lavapipe has one queue),
    /// submit a profile's two-queue plans to the one queue in order instead of turning async
    /// compute off: their semaphore waits, barriers and transfers run (and are validated), the
    /// overlap does not. For tests.
    pub async_on_one_queue: bool,
    /// The queue policy to use instead of the profile's `[queues]` (async compute on or off,
    /// the sharing mode): what `--async-compute` measures.
    pub queues: Option<tilegraph_profile::QueuePolicy>,
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
            profile_forced_by: tilegraph_profile::PROFILE_ENV.to_string(),
            features: FeatureRequest::executor(),
            async_on_one_queue: false,
            queues: None,
        }
    }

    /// Forces profile `name`, credited to `by` (`--profile`): it takes precedence over
    /// `TILEGRAPH_PROFILE`.
    pub fn force_profile(&mut self, name: &str, by: &str) {
        self.profile = Some(name.to_string());
        self.profile_forced_by = by.to_string();
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

/// The queue the async compute passes of a plan are submitted to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AsyncQueue {
    pub queue: vk::Queue,
    pub family: u32,
}

/// The device a frame runs on.
pub struct Context {
    pub physical: PhysicalDevice,
    pub selection: Selection,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    /// Where the profile's async compute runs (`None`: it is off, and the profile says so).
    /// The same queue as `queue` under [`ContextOptions::async_on_one_queue`].
    pub async_queue: Option<AsyncQueue>,
    pub(crate) enabled: BTreeSet<Feature>,
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) allocations: AtomicU64,
    /// Bytes of device memory allocated through the context and not freed yet.
    pub(crate) allocated_bytes: AtomicU64,
    /// The most bytes the context may hold ([`Context::set_memory_budget`]; `u64::MAX`: no cap).
    pub(crate) memory_budget: AtomicU64,
    pub(crate) sync2: Sync2,
    pub(crate) dynrend: DynRendering,
    pub(crate) debug_utils: Option<ash::ext::debug_utils::Device>,
    pub(crate) conditional: Option<ash::ext::conditional_rendering::Device>,
    pub(crate) upload_pool: vk::CommandPool,
    /// tilegraph created the device (and destroys it); an adopted one is the engine's.
    owns_device: bool,
    /// What tilegraph made on the device is destroyed (by `destroy_checked` or Drop).
    device_destroyed: bool,
    // Declared last: dropped after the device is destroyed in Drop.
    instance: ManuallyDrop<Instance>,
    /// Not `Sync`: the upload pool and the queue are used by `&self` methods and must be
    /// externally synchronized (one thread at a time). Still `Send`.
    /// The NUL-terminated name of the debug label being opened (kept: labels allocate nothing).
    pub(crate) label_scratch: std::cell::RefCell<Vec<u8>>,
    /// A failure injected at a site ([`Context::inject_fault_at`]), taken by the first call
    /// that reaches the site.
    injected_fault: std::cell::Cell<Option<(FaultSite, vk::Result)>>,
    _one_thread: std::marker::PhantomData<std::cell::Cell<()>>,
}

impl Context {
    /// Creates the instance, picks the device, selects its profile and creates the logical device
    /// with exactly the features requested (required ones must exist; optional ones are logged).
    pub fn new(options: ContextOptions) -> Result<Self, VkError> {
        let instance = Instance::new(&options.app_name, options.validation)?;
        let physical = instance.choose_device(options.device.as_deref())?;
        let mut selection = select_profile(&physical, options.profile.as_deref())?;
        if let tilegraph_profile::MatchedBy::Forced { by, .. } = &mut selection.matched_by {
            by.clone_from(&options.profile_forced_by);
        }
        Self::with_instance(instance, physical, selection, &options)
    }

    fn with_instance(
        instance: Instance,
        physical: PhysicalDevice,
        mut selection: Selection,
        options: &ContextOptions,
    ) -> Result<Self, VkError> {
        let mut config = DeviceConfig::new(&physical, &options.features)?;
        if let Some(queues) = options.queues {
            selection.profile.queues = queues;
        }
        let async_on_one_queue = options.async_on_one_queue;
        let queue_family = config.queue_family;
        // Async compute: on where the profile asks for it and the device has the queue and
        // timeline semaphores (or the caller runs it on one queue).
        let wanted = selection.profile.queues.async_compute;
        let timelines = config.enabled.contains(&Feature::TimelineSemaphore);
        let second = physical.async_compute_queue.filter(|_| wanted && timelines);
        let priorities = [1.0f32, 1.0];
        let mut queue_info = vec![vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(if second == Some((queue_family, 1)) {
                &priorities[..2]
            } else {
                &priorities[..1]
            })];
        if let Some((family, _)) = second.filter(|(f, _)| *f != queue_family) {
            queue_info.push(
                vk::DeviceQueueCreateInfo::default()
                    .queue_family_index(family)
                    .queue_priorities(&priorities[..1]),
            );
        }
        let info = config.chain(vk::DeviceCreateInfo::default().queue_create_infos(&queue_info));
        // SAFETY: feature structs are chained only for this API version / enabled extensions, and
        // every enabled feature was reported as supported.
        let device = unsafe { instance.raw.create_device(physical.raw, &info, None) }
            .vk("vkCreateDevice")?;
        // SAFETY: queue 0 of a family we created.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let async_queue = match second {
            // SAFETY: a queue of the create infos above.
            Some((family, index)) => Some(AsyncQueue {
                queue: unsafe { device.get_device_queue(family, index) },
                family,
            }),
            None if wanted && timelines && async_on_one_queue => Some(AsyncQueue {
                queue,
                family: queue_family,
            }),
            None => None,
        };
        if wanted && async_queue.is_none() {
            log::info!(
                "profile {} asks for async compute, but {}: it is off",
                selection.profile.name,
                if timelines {
                    "the device has no second compute queue"
                } else {
                    "the device has no timeline semaphores"
                }
            );
            selection.profile.queues.async_compute = false;
        }
        log::info!(
            "device created with features [{}] and extensions [{}]",
            config
                .enabled
                .iter()
                .map(|f| f.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            config
                .extensions
                .iter()
                .map(|e| e.to_string_lossy())
                .collect::<Vec<_>>()
                .join(", ")
        );
        let enabled = std::mem::take(&mut config.enabled);
        let made = DeviceParts {
            device,
            queue,
            queue_family,
            async_queue,
            enabled,
            owned: true,
        };
        Self::from_device(instance, physical, selection, made)
    }

    /// Adopts an engine's device: tilegraph records on its `queue_family` with the features the
    /// engine says it enabled, chooses the profile from the device's identity (or the one
    /// forced by name), and never destroys the device or the instance — only what it creates
    /// on them (its allocator's memory, its command pool, and what its executors and passes
    /// make). Ask [`DeviceConfig::new`] what to enable before creating the device.
    ///
    /// # Safety
    ///
    /// `adopted.device` was created from `adopted.physical_device` of `instance` with at least
    /// the features in `adopted.enabled` and their extensions ([`DeviceConfig`]), has a queue
    /// `queue_index` in `queue_family`, and stays valid until this context is destroyed. The
    /// engine synchronizes its own use of that queue with tilegraph's (one thread at a time),
    /// and has waited for the GPU work tilegraph's objects are used by before destroying the
    /// context.
    pub unsafe fn adopt(instance: Instance, adopted: AdoptedDevice) -> Result<Self, VkError> {
        let AdoptedDevice {
            physical_device,
            device,
            queue_family,
            queue_index,
            enabled,
            profile,
            profile_forced_by,
        } = adopted;
        if device == vk::Device::null() {
            return Err(VkError::Invalid {
                what: "adopted device".into(),
                reason: "the handle is null".into(),
            });
        }
        let physical = instance.physical_device(physical_device, queue_family)?;
        if physical.api_version() < MIN_API_VERSION {
            return Err(VkError::MissingRequired {
                device: physical.identity.device_name.clone(),
                what: "Vulkan version",
                missing: "1.2".into(),
            });
        }
        let unsupported: Vec<String> = enabled
            .iter()
            .filter(|f| !physical.supported.contains(f))
            .map(|f| f.to_string())
            .collect();
        if !unsupported.is_empty() {
            return Err(VkError::MissingRequired {
                device: physical.identity.device_name.clone(),
                what: "features the engine says it enabled (the device does not support them)",
                missing: unsupported.join(", "),
            });
        }
        let mut selection = select_profile(&physical, profile.as_deref())?;
        if let tilegraph_profile::MatchedBy::Forced { by, .. } = &mut selection.matched_by {
            by.clone_from(&profile_forced_by);
        }
        if selection.profile.queues.async_compute {
            // The engine's device and submission: its plans stay on one queue for now.
            log::info!(
                "profile {}: async compute is off on an adopted device (the engine submits one queue)",
                selection.profile.name
            );
            selection.profile.queues.async_compute = false;
        }
        // SAFETY: the caller vouches that `device` was created from this instance.
        let device = unsafe { ash::Device::load(instance.raw.fp_v1_0(), device) };
        // SAFETY: the caller vouches that the queue exists.
        let queue = unsafe { device.get_device_queue(queue_family, queue_index) };
        let made = DeviceParts {
            device,
            queue,
            queue_family,
            async_queue: None,
            enabled,
            owned: false,
        };
        Self::from_device(instance, physical, selection, made)
    }

    /// The context over a device: extension function tables for what is enabled, the
    /// allocator and the upload pool. A device tilegraph created is destroyed again when this
    /// fails.
    fn from_device(
        instance: Instance,
        physical: PhysicalDevice,
        selection: Selection,
        made: DeviceParts,
    ) -> Result<Self, VkError> {
        let DeviceParts {
            device,
            queue,
            queue_family,
            async_queue,
            enabled,
            owned,
        } = made;
        let api13 = physical.api13();
        let uses = |f: Feature| enabled.contains(&f);
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
        let destroy_device = |device: &ash::Device| {
            if owned {
                // SAFETY: nothing made from the device is alive (the callers' order).
                unsafe { device.destroy_device(None) };
            }
        };
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
                destroy_device(&device);
                return Err(VkError::Allocation {
                    name: "allocator".into(),
                    source,
                });
            }
        };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            // Each one-time submission allocates its command buffer and frees it: no reset.
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        // SAFETY: valid device and family.
        let upload_pool = match unsafe { device.create_command_pool(&pool_info, None) } {
            Ok(p) => p,
            Err(r) => {
                drop(allocator);
                destroy_device(&device);
                return Err(VkError::call("vkCreateCommandPool", r));
            }
        };
        Ok(Context {
            physical,
            selection,
            device,
            queue,
            queue_family,
            async_queue,
            enabled,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            allocations: AtomicU64::new(0),
            allocated_bytes: AtomicU64::new(0),
            memory_budget: AtomicU64::new(u64::MAX),
            sync2,
            dynrend,
            debug_utils,
            conditional,
            upload_pool,
            owns_device: owned,
            device_destroyed: false,
            instance: ManuallyDrop::new(instance),
            label_scratch: std::cell::RefCell::new(Vec::new()),
            injected_fault: std::cell::Cell::new(None),
            _one_thread: std::marker::PhantomData,
        })
    }

    /// Makes the next frame executed on this context fail as if a Vulkan call had returned
    /// `result` (`ERROR_DEVICE_LOST`, `ERROR_OUT_OF_DEVICE_MEMORY`, ...), after the frame
    /// began: fault injection, for tests of an engine's error paths and of tilegraph's.
    pub fn inject_fault(&self, result: vk::Result) {
        self.inject_fault_at(FaultSite::FrameStart, result);
    }

    /// Makes the next call that reaches `site` fail as if its Vulkan call had returned
    /// `result`: a frame's start, its submission, the wait for a frame slot's fence, a graphics
    /// pipeline's creation, a memory allocation. One fault at a time; a new one replaces it.
    pub fn inject_fault_at(&self, site: FaultSite, result: vk::Result) {
        self.injected_fault.set(Some((site, result)));
    }

    /// The fault injected at `site`, once, as the error of `call`.
    pub(crate) fn injected_fault_at(
        &self,
        site: FaultSite,
        call: &'static str,
    ) -> Result<(), VkError> {
        match self.injected_fault.get() {
            Some((at, result)) if at == site => {
                self.injected_fault.set(None);
                Err(VkError::call(call, result))
            }
            _ => Ok(()),
        }
    }

    /// Whether tilegraph created the device (and destroys it); an adopted one is the engine's.
    pub fn owns_device(&self) -> bool {
        self.owns_device
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

    /// What the device does with optimally tiled images of `format`
    /// (`vkGetPhysicalDeviceFormatProperties`).
    pub fn format_features(&self, format: vk::Format) -> vk::FormatFeatureFlags {
        // SAFETY: valid physical device of this instance.
        unsafe {
            self.instance
                .raw
                .get_physical_device_format_properties(self.physical.raw, format)
        }
        .optimal_tiling_features
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

    /// The ids of the reviewed, silenced best-practices messages the layer reported
    /// ([`crate::SILENCED`]): what shows that a vendor's checks ran.
    pub fn silenced_validation_ids(&self) -> Vec<&'static str> {
        self.instance.validation().silenced_ids()
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

/// The profile for `physical`: the one forced by name, else the one its identity matches.
/// `STORE_OP_NONE` is core from Vulkan 1.3 (tilegraph enables none of the extensions that add
/// it earlier): on older devices plans store read-only attachments instead, and the graph
/// synchronizes that store as the write it is.
fn select_profile(physical: &PhysicalDevice, forced: Option<&str>) -> Result<Selection, VkError> {
    let profiles = ProfileSet::from_env()?;
    let mut selection = profiles.select(&physical.identity, forced)?;
    if selection.profile.render_pass.store_op_none && !physical.api13() {
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
    Ok(selection)
}

/// A device made or adopted, before the context around it.
struct DeviceParts {
    device: ash::Device,
    queue: vk::Queue,
    queue_family: u32,
    async_queue: Option<AsyncQueue>,
    enabled: BTreeSet<Feature>,
    owned: bool,
}

/// An engine's device, handed to [`Context::adopt`].
#[derive(Debug, Clone)]
pub struct AdoptedDevice {
    pub physical_device: vk::PhysicalDevice,
    pub device: vk::Device,
    /// The queue tilegraph records for (graphics and compute), and submits to when it owns
    /// the frame's submission.
    pub queue_family: u32,
    pub queue_index: u32,
    /// The tilegraph features the engine enabled on the device ([`DeviceConfig::enabled`]):
    /// tilegraph uses no other.
    pub enabled: BTreeSet<Feature>,
    /// A profile forced by name (as `TILEGRAPH_PROFILE` does), else the device's own.
    pub profile: Option<String>,
    /// What forced [`Self::profile`], as the selection reports it ("forced by {this} {name}"):
    /// the engine's own setting, a C field (`TgAdoptInfo.profile`), a system property.
    pub profile_forced_by: String,
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
        // memory blocks), then the device. Runs once (flag above). An adopted device is the
        // engine's: it has waited for the GPU (Context::adopt's contract) and destroys it.
        unsafe {
            if self.owns_device {
                if let Err(e) = self.device.device_wait_idle() {
                    log::error!("vkDeviceWaitIdle at teardown: {e}");
                }
            }
            self.device.destroy_command_pool(self.upload_pool, None);
            ManuallyDrop::drop(&mut self.allocator);
            if self.owns_device {
                self.device.destroy_device(None);
            }
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
