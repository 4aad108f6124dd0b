//! The logical device: created for one physical device, with only the requested features, the
//! profile chosen for it, and a gpu-allocator whose allocations land in the profile's memory type.

use std::collections::BTreeSet;
use std::ffi::CStr;
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use ash::vk;
use gpu_allocator::vulkan::{
    Allocation, AllocationCreateDesc, AllocationScheme, Allocator, AllocatorCreateDesc,
};
use gpu_allocator::{AllocationSizes, AllocatorDebugSettings, MemoryLocation};
use tilegraph_profile::{
    select_memory_type, MemoryChoice, MemoryUse, Profile, ProfileSet, Selection,
};

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

/// A buffer and its memory.
#[derive(Debug)]
pub struct Buffer {
    pub raw: vk::Buffer,
    pub size: u64,
    pub memory: MemoryChoice,
    allocation: Allocation,
}

impl Buffer {
    /// The mapped bytes, when the memory type is host-visible.
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation.mapped_slice()
    }
    pub fn mapped_mut(&mut self) -> Option<&mut [u8]> {
        self.allocation.mapped_slice_mut()
    }
    /// Memory property flags of the allocation, as gpu-allocator reports them.
    pub fn memory_properties(&self) -> vk::MemoryPropertyFlags {
        self.allocation.memory_properties()
    }
}

/// An image and its memory.
#[derive(Debug)]
pub struct Image {
    pub raw: vk::Image,
    pub format: vk::Format,
    pub extent: vk::Extent2D,
    pub mip_levels: u32,
    pub memory: MemoryChoice,
    allocation: Allocation,
}

impl Image {
    pub fn memory_properties(&self) -> vk::MemoryPropertyFlags {
        self.allocation.memory_properties()
    }
}

/// Device-level function tables for paths that differ between Vulkan 1.2 (+extensions) and 1.3.
enum Sync2 {
    Core,
    Khr(ash::khr::synchronization2::Device),
    Missing,
}
enum DynRendering {
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
    enabled: BTreeSet<Feature>,
    allocator: ManuallyDrop<Mutex<Allocator>>,
    allocations: AtomicU64,
    sync2: Sync2,
    dynrend: DynRendering,
    debug_utils: Option<ash::ext::debug_utils::Device>,
    conditional: Option<ash::ext::conditional_rendering::Device>,
    upload_pool: vk::CommandPool,
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

    /// Number of device-memory allocations made through this context so far.
    pub fn allocation_count(&self) -> u64 {
        self.allocations.load(Ordering::Relaxed)
    }

    /// The memory type the profile picks for `use_` among `type_bits`.
    pub fn choose_memory(&self, use_: MemoryUse, type_bits: u32) -> Result<MemoryChoice, VkError> {
        Ok(select_memory_type(
            &self.profile().memory,
            &self.physical.identity.memory_types,
            type_bits,
            use_,
        )?)
    }

    /// Allocates memory for `requirements` in exactly the type the profile chooses: the
    /// requirement's type bits are narrowed to that one type before gpu-allocator sees them.
    pub fn allocate(
        &self,
        name: &str,
        requirements: vk::MemoryRequirements,
        use_: MemoryUse,
        linear: bool,
    ) -> Result<(Allocation, MemoryChoice), VkError> {
        let choice = self.choose_memory(use_, requirements.memory_type_bits)?;
        let narrowed = vk::MemoryRequirements {
            memory_type_bits: 1 << choice.type_index,
            ..requirements
        };
        let mut allocator = self.allocator.lock().map_err(|_| VkError::Invalid {
            what: "allocator".into(),
            reason: "a thread panicked while holding it".into(),
        })?;
        let allocation = allocator
            .allocate(&AllocationCreateDesc {
                name,
                requirements: narrowed,
                // Unknown: let the narrowed type bits alone decide; gpu-allocator maps the
                // memory whenever the type is host-visible.
                location: MemoryLocation::Unknown,
                linear,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|source| VkError::Allocation {
                name: name.to_string(),
                source,
            })?;
        self.allocations.fetch_add(1, Ordering::Relaxed);
        Ok((allocation, choice))
    }

    pub fn free(&self, allocation: Allocation) {
        match self.allocator.lock() {
            Ok(mut a) => {
                if let Err(e) = a.free(allocation) {
                    log::error!("freeing device memory: {e}");
                }
            }
            Err(_) => log::error!("allocator lock poisoned; leaking an allocation"),
        }
    }

    /// Creates a buffer in the memory type the profile picks for `use_`.
    pub fn create_buffer(
        &self,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        use_: MemoryUse,
    ) -> Result<Buffer, VkError> {
        if size == 0 {
            return Err(VkError::Invalid {
                what: format!("buffer {name:?}"),
                reason: "size is zero".into(),
            });
        }
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info with non-zero size.
        let raw = unsafe { self.device.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        // SAFETY: raw is a live buffer of this device.
        let req = unsafe { self.device.get_buffer_memory_requirements(raw) };
        let (allocation, memory) = match self.allocate(name, req, use_, true) {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: unbound, unused buffer.
                unsafe { self.device.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        // SAFETY: the allocation satisfies the buffer's requirements (size, alignment, type).
        if let Err(r) = unsafe {
            self.device
                .bind_buffer_memory(raw, allocation.memory(), allocation.offset())
        } {
            // SAFETY: unused buffer; allocation returned to the allocator.
            unsafe { self.device.destroy_buffer(raw, None) };
            self.free(allocation);
            return Err(VkError::call("vkBindBufferMemory", r));
        }
        self.set_name(raw, name);
        Ok(Buffer {
            raw,
            size,
            memory,
            allocation,
        })
    }

    /// The range of a buffer's memory to flush or invalidate: atom-aligned, and never past the
    /// end of its memory object (a dedicated allocation's object is exactly its size, which
    /// need not be a multiple of the atom: that range runs to `VK_WHOLE_SIZE`).
    fn mapped_range(&self, buffer: &Buffer) -> vk::MappedMemoryRange<'static> {
        let atom = self.physical.limits.non_coherent_atom_size.max(1);
        let a = &buffer.allocation;
        let start = a.offset() / atom * atom;
        // SAFETY: the allocation's memory object is live while the buffer is.
        let range = vk::MappedMemoryRange::default().memory(unsafe { a.memory() });
        if a.is_dedicated() {
            return range.offset(start).size(vk::WHOLE_SIZE);
        }
        // Sub-allocated: gpu-allocator's blocks are far larger than an atom and sized in
        // multiples of it, so rounding up stays inside the block.
        let end = (a.offset() + a.size()).div_ceil(atom) * atom;
        range.offset(start).size(end - start)
    }

    fn is_coherent(buffer: &Buffer) -> bool {
        buffer
            .memory
            .flags
            .contains(tilegraph_profile::MemoryFlags::HOST_COHERENT)
    }

    /// Makes GPU writes visible to the host for a mapped buffer in non-coherent memory (no-op on
    /// coherent memory). Call after the fence that covers the writes.
    pub fn invalidate_mapped(&self, buffer: &Buffer) -> Result<(), VkError> {
        if Self::is_coherent(buffer) {
            return Ok(());
        }
        let range = self.mapped_range(buffer);
        // SAFETY: the memory is mapped by gpu-allocator; the range is atom-aligned and inside it.
        unsafe { self.device.invalidate_mapped_memory_ranges(&[range]) }
            .vk("vkInvalidateMappedMemoryRanges")
    }

    /// Makes host writes to a mapped buffer in non-coherent memory visible to the device (no-op
    /// on coherent memory). Call before submitting work that reads them.
    pub fn flush_mapped(&self, buffer: &Buffer) -> Result<(), VkError> {
        if Self::is_coherent(buffer) {
            return Ok(());
        }
        let range = self.mapped_range(buffer);
        // SAFETY: as for `invalidate_mapped`.
        unsafe { self.device.flush_mapped_memory_ranges(&[range]) }.vk("vkFlushMappedMemoryRanges")
    }

    /// Copies `bytes` into a mapped buffer at `offset` and flushes it (non-coherent memory):
    /// the one way the host writes GPU-visible memory. Errors when the buffer is not mapped or
    /// too small.
    pub fn write_mapped(
        &self,
        buffer: &mut Buffer,
        offset: usize,
        bytes: &[u8],
    ) -> Result<(), VkError> {
        let size = buffer.size;
        let target = buffer
            .mapped_mut()
            .and_then(|m| m.get_mut(offset..offset.checked_add(bytes.len())?));
        let Some(target) = target else {
            return Err(VkError::Invalid {
                what: format!("buffer of {size} bytes"),
                reason: format!(
                    "cannot write {} bytes at offset {offset}: not host-visible or too small",
                    bytes.len()
                ),
            });
        };
        target.copy_from_slice(bytes);
        self.flush_mapped(buffer)
    }

    pub fn destroy_buffer(&self, buffer: Buffer) {
        // SAFETY: the caller guarantees the GPU no longer uses the buffer.
        unsafe { self.device.destroy_buffer(buffer.raw, None) };
        self.free(buffer.allocation);
    }

    /// Creates a 2D image in the memory type the profile picks for `use_`.
    pub fn create_image(
        &self,
        name: &str,
        info: &vk::ImageCreateInfo<'_>,
        use_: MemoryUse,
    ) -> Result<Image, VkError> {
        if info.extent.width == 0 || info.extent.height == 0 {
            return Err(VkError::Invalid {
                what: format!("image {name:?}"),
                reason: "zero extent".into(),
            });
        }
        // SAFETY: valid create info (checked extent; format/usage validated by the layer).
        let raw = unsafe { self.device.create_image(info, None) }.vk("vkCreateImage")?;
        // SAFETY: live image.
        let req = unsafe { self.device.get_image_memory_requirements(raw) };
        let linear = info.tiling == vk::ImageTiling::LINEAR;
        let (allocation, memory) = match self.allocate(name, req, use_, linear) {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: unbound, unused image.
                unsafe { self.device.destroy_image(raw, None) };
                return Err(e);
            }
        };
        // SAFETY: allocation satisfies the requirements.
        if let Err(r) = unsafe {
            self.device
                .bind_image_memory(raw, allocation.memory(), allocation.offset())
        } {
            // SAFETY: unused image.
            unsafe { self.device.destroy_image(raw, None) };
            self.free(allocation);
            return Err(VkError::call("vkBindImageMemory", r));
        }
        self.set_name(raw, name);
        Ok(Image {
            raw,
            format: info.format,
            extent: vk::Extent2D {
                width: info.extent.width,
                height: info.extent.height,
            },
            mip_levels: info.mip_levels,
            memory,
            allocation,
        })
    }

    pub fn destroy_image(&self, image: Image) {
        // SAFETY: the caller guarantees the GPU no longer uses the image.
        unsafe { self.device.destroy_image(image.raw, None) };
        self.free(image.allocation);
    }

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
        if let Some(du) = &self.debug_utils {
            let Ok(c) = std::ffi::CString::new(name.replace('\0', "")) else {
                return;
            };
            let label = vk::DebugUtilsLabelEXT::default().label_name(&c);
            // SAFETY: cb is recording.
            unsafe { du.cmd_begin_debug_utils_label(cb, &label) };
        }
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

    /// Waits until the device is idle.
    pub fn wait_idle(&self) -> Result<(), VkError> {
        // SAFETY: valid device.
        unsafe { self.device.device_wait_idle() }.vk("vkDeviceWaitIdle")
    }
}

fn missing_feature(f: Feature) -> VkError {
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
