//! The sample's own Vulkan, as an engine has it: an instance with the Android surface
//! extensions, a surface on the activity's `ANativeWindow`, a device created with what
//! tilegraph asks for plus `VK_KHR_swapchain`, a swapchain and the per-frame objects. tilegraph
//! adopts the instance and the device (`Context::adopt`) and records into this code's command
//! buffers; this code submits and presents.

use std::ffi::CStr;

use tilegraph_graph::ResourceState;
use tilegraph_passes::{EngineTarget, RenderOptions};
use tilegraph_vk::ash::{self, vk};
use tilegraph_vk::executor::ImageHandle;
use tilegraph_vk::{AdoptedDevice, Context, DeviceConfig, FeatureRequest, Instance, VkError};

/// Frames the CPU may record ahead of the GPU.
pub const FRAMES_IN_FLIGHT: usize = 2;

/// The instance and device, owned by the sample (tilegraph never destroys them).
pub struct Device {
    /// Keeps libvulkan.so loaded while the instance lives.
    _entry: ash::Entry,
    pub instance: ash::Instance,
    pub surface_fn: ash::khr::surface::Instance,
    pub surface: vk::SurfaceKHR,
    pub physical: vk::PhysicalDevice,
    pub family: u32,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub swapchain_fn: ash::khr::swapchain::Device,
}

fn vk_err(call: &'static str) -> impl Fn(vk::Result) -> VkError {
    move |r| VkError::call(call, r)
}

/// Everything any culling of the cycle may need, asked for as optional: a culling whose
/// features the device lacks is skipped by the touch cycle.
pub fn feature_request() -> FeatureRequest {
    let mut request = FeatureRequest::executor();
    for culling in crate::report::CYCLE {
        let options = RenderOptions {
            culling,
            ..RenderOptions::default()
        };
        request
            .optional
            .extend(options.needs().into_iter().map(|(f, _)| f));
    }
    request
}

impl Device {
    /// Instance, surface on `window`, device and queue; then tilegraph adopts them (with
    /// `profile` forced, or the device's own) and the context is returned with them.
    ///
    /// # Safety
    /// `window` is the activity's live `ANativeWindow`.
    pub unsafe fn new(
        window: *mut vk::ANativeWindow,
        profile: Option<String>,
    ) -> Result<(Device, Context), VkError> {
        // SAFETY: loads the system's libvulkan.so.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::Loader(e.to_string()))?;
        let app = vk::ApplicationInfo::default()
            .application_name(c"tilegraph sample")
            .api_version(vk::API_VERSION_1_3);
        let extensions = [
            ash::khr::surface::NAME.as_ptr(),
            ash::khr::android_surface::NAME.as_ptr(),
        ];
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_extension_names(&extensions);
        // SAFETY: pointers to locals alive for the call.
        let instance =
            unsafe { entry.create_instance(&info, None) }.map_err(vk_err("vkCreateInstance"))?;
        let surface_fn = ash::khr::surface::Instance::new(&entry, &instance);
        let android = ash::khr::android_surface::Instance::new(&entry, &instance);
        let surface_info = vk::AndroidSurfaceCreateInfoKHR::default().window(window);
        // SAFETY: the caller's window.
        let surface = unsafe { android.create_android_surface(&surface_info, None) }
            .map_err(vk_err("vkCreateAndroidSurfaceKHR"))?;
        // SAFETY: live instance.
        let physicals = unsafe { instance.enumerate_physical_devices() }
            .map_err(vk_err("vkEnumeratePhysicalDevices"))?;
        let want = vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE;
        let (physical, family) = physicals
            .iter()
            .find_map(|&p| {
                // SAFETY: `p` is the instance's.
                let families = unsafe { instance.get_physical_device_queue_family_properties(p) };
                families.iter().enumerate().find_map(|(i, f)| {
                    let i = i as u32;
                    // SAFETY: valid family index and surface.
                    let present =
                        unsafe { surface_fn.get_physical_device_surface_support(p, i, surface) };
                    (f.queue_flags.contains(want) && present == Ok(true)).then_some((p, i))
                })
            })
            .ok_or_else(|| VkError::NoDevice {
                seen: "no queue with graphics, compute and present".into(),
            })?;

        // tilegraph says what it needs; the sample adds its swapchain.
        // SAFETY: the instance outlives the context (the sample destroys it last).
        let adopted = unsafe {
            Instance::adopt(
                entry.static_fn().get_instance_proc_addr,
                instance.handle(),
                false,
            )
        }?;
        let described = adopted.physical_device(physical, family)?;
        let mut config = DeviceConfig::new(&described, &feature_request())?;
        config.add_extension(ash::khr::swapchain::NAME);
        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let info = config.chain(vk::DeviceCreateInfo::default().queue_create_infos(&queues));
        // SAFETY: features and extensions the physical device reported.
        let device = unsafe { instance.create_device(physical, &info, None) }
            .map_err(vk_err("vkCreateDevice"))?;
        // SAFETY: queue 0 of the family created above.
        let queue = unsafe { device.get_device_queue(family, 0) };
        let swapchain_fn = ash::khr::swapchain::Device::new(&instance, &device);
        let handed = AdoptedDevice {
            physical_device: physical,
            device: device.handle(),
            queue_family: family,
            queue_index: 0,
            enabled: config.enabled.clone(),
            profile,
            profile_forced_by: "debug.tilegraph.profile".into(),
        };
        // SAFETY: created above with tilegraph's configuration; destroyed after the context.
        let ctx = unsafe { Context::adopt(adopted, handed) }?;
        let d = Device {
            _entry: entry,
            instance,
            surface_fn,
            surface,
            physical,
            family,
            device,
            queue,
            swapchain_fn,
        };
        Ok((d, ctx))
    }

    /// Destroys the device, the surface and the instance (tilegraph's context is gone).
    pub fn destroy(self) {
        // SAFETY: nothing made from them is alive.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_device(None);
            self.surface_fn.destroy_surface(self.surface, None);
            self.instance.destroy_instance(None);
        }
    }
}

/// One frame slot: the command buffer the renderer records into, its fence, and the
/// semaphore its swapchain image is acquired with.
struct Slot {
    cb: vk::CommandBuffer,
    fence: vk::Fence,
    acquired: vk::Semaphore,
    submitted: bool,
}

/// The swapchain, its images' views, one "rendered" semaphore per image, and the slots.
pub struct Swapchain {
    pub swapchain: vk::SwapchainKHR,
    pub extent: vk::Extent2D,
    pub format: vk::Format,
    images: Vec<ImageHandle>,
    rendered: Vec<vk::Semaphore>,
    pool: vk::CommandPool,
    slots: Vec<Slot>,
    next: usize,
}

/// A frame being recorded: what the renderer records into.
pub struct Frame {
    pub slot: usize,
    pub cb: vk::CommandBuffer,
    pub image: u32,
}

impl Swapchain {
    pub fn new(d: &Device) -> Result<Self, VkError> {
        // SAFETY: live surface and physical device.
        let caps = unsafe {
            d.surface_fn
                .get_physical_device_surface_capabilities(d.physical, d.surface)
        }
        .map_err(vk_err("vkGetPhysicalDeviceSurfaceCapabilitiesKHR"))?;
        // SAFETY: as above.
        let formats = unsafe {
            d.surface_fn
                .get_physical_device_surface_formats(d.physical, d.surface)
        }
        .map_err(vk_err("vkGetPhysicalDeviceSurfaceFormatsKHR"))?;
        // tilegraph's colour is linear: an UNORM target shows it as the desktop does.
        let format = formats
            .iter()
            .map(|f| f.format)
            .find(|f| matches!(*f, vk::Format::R8G8B8A8_UNORM | vk::Format::B8G8R8A8_UNORM))
            .or_else(|| formats.first().map(|f| f.format))
            .ok_or_else(|| VkError::Invalid {
                what: "surface".into(),
                reason: "no surface format".into(),
            })?;
        let extent = caps.current_extent;
        let count = (caps.min_image_count + 1).min(if caps.max_image_count == 0 {
            u32::MAX
        } else {
            caps.max_image_count
        });
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(d.surface)
            .min_image_count(count)
            .image_format(format)
            .image_color_space(vk::ColorSpaceKHR::SRGB_NONLINEAR)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::COLOR_ATTACHMENT)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(vk::CompositeAlphaFlagsKHR::INHERIT)
            .present_mode(vk::PresentModeKHR::FIFO)
            .clipped(true);
        // SAFETY: valid create info.
        let swapchain = unsafe { d.swapchain_fn.create_swapchain(&info, None) }
            .map_err(vk_err("vkCreateSwapchainKHR"))?;
        let mut s = Swapchain {
            swapchain,
            extent,
            format,
            images: Vec::new(),
            rendered: Vec::new(),
            pool: vk::CommandPool::null(),
            slots: Vec::new(),
            next: 0,
        };
        match s.fill(d) {
            Ok(()) => Ok(s),
            Err(e) => {
                s.destroy(d);
                Err(e)
            }
        }
    }

    fn fill(&mut self, d: &Device) -> Result<(), VkError> {
        // SAFETY: live swapchain.
        let images = unsafe { d.swapchain_fn.get_swapchain_images(self.swapchain) }
            .map_err(vk_err("vkGetSwapchainImagesKHR"))?;
        for image in images {
            let view_info = vk::ImageViewCreateInfo::default()
                .image(image)
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(self.format)
                .subresource_range(vk::ImageSubresourceRange {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    base_mip_level: 0,
                    level_count: 1,
                    base_array_layer: 0,
                    layer_count: 1,
                });
            // SAFETY: a swapchain image.
            let view = unsafe { d.device.create_image_view(&view_info, None) }
                .map_err(vk_err("vkCreateImageView"))?;
            self.images.push(ImageHandle {
                raw: image,
                view,
                full_view: view,
                mip_views: Vec::new(),
                format: self.format,
                extent: self.extent,
                mip_levels: 1,
                aspect: vk::ImageAspectFlags::COLOR,
            });
            // SAFETY: valid device.
            let rendered = unsafe {
                d.device
                    .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
            }
            .map_err(vk_err("vkCreateSemaphore"))?;
            self.rendered.push(rendered);
        }
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(d.family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device and family.
        self.pool = unsafe { d.device.create_command_pool(&pool_info, None) }
            .map_err(vk_err("vkCreateCommandPool"))?;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(FRAMES_IN_FLIGHT as u32);
        // SAFETY: live pool.
        let cbs = unsafe { d.device.allocate_command_buffers(&alloc) }
            .map_err(vk_err("vkAllocateCommandBuffers"))?;
        for cb in cbs {
            // SAFETY: valid device.
            let fence = unsafe { d.device.create_fence(&vk::FenceCreateInfo::default(), None) }
                .map_err(vk_err("vkCreateFence"))?;
            // SAFETY: valid device.
            let acquired = unsafe {
                d.device
                    .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
            }
            .map_err(vk_err("vkCreateSemaphore"))?;
            self.slots.push(Slot {
                cb,
                fence,
                acquired,
                submitted: false,
            });
        }
        Ok(())
    }

    /// Waits for the next slot's last frame, acquires an image, begins the command buffer.
    /// `Ok(None)`: the swapchain is out of date (recreate it).
    pub fn begin(&mut self, d: &Device) -> Result<Option<Frame>, VkError> {
        let slot = self.next;
        let s = &mut self.slots[slot];
        // SAFETY: the fence was submitted with the slot's last frame.
        unsafe {
            if s.submitted {
                d.device
                    .wait_for_fences(&[s.fence], true, u64::MAX)
                    .map_err(vk_err("vkWaitForFences"))?;
                d.device
                    .reset_fences(&[s.fence])
                    .map_err(vk_err("vkResetFences"))?;
                s.submitted = false;
            }
        }
        // SAFETY: the slot's semaphore is unsignalled (its last wait completed with the fence).
        let acquired = unsafe {
            d.swapchain_fn.acquire_next_image(
                self.swapchain,
                u64::MAX,
                s.acquired,
                vk::Fence::null(),
            )
        };
        let image = match acquired {
            Ok((i, _)) => i,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => return Ok(None),
            Err(r) => return Err(VkError::call("vkAcquireNextImageKHR", r)),
        };
        // SAFETY: the buffer's last submission completed (fence above).
        unsafe {
            d.device
                .reset_command_buffer(s.cb, vk::CommandBufferResetFlags::empty())
                .map_err(vk_err("vkResetCommandBuffer"))?;
            d.device
                .begin_command_buffer(s.cb, &vk::CommandBufferBeginInfo::default())
                .map_err(vk_err("vkBeginCommandBuffer"))?;
        }
        Ok(Some(Frame {
            slot,
            cb: s.cb,
            image,
        }))
    }

    /// The target tilegraph renders `frame` into: the acquired image, left for presentation.
    pub fn target(&self, frame: &Frame) -> Option<EngineTarget<'_>> {
        self.images
            .get(frame.image as usize)
            .map(|image| EngineTarget {
                image,
                initial: ResourceState::SWAPCHAIN_ACQUIRED,
                final_state: ResourceState::PRESENT,
            })
    }

    /// Ends, submits (after the acquire, before the present) and presents `frame`.
    pub fn submit(&mut self, d: &Device, frame: Frame) -> Result<(), VkError> {
        let s = &mut self.slots[frame.slot];
        let rendered = self.rendered[frame.image as usize];
        let waits = [s.acquired];
        let stages = [vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT];
        let cbs = [frame.cb];
        let signals = [rendered];
        let submit = vk::SubmitInfo::default()
            .wait_semaphores(&waits)
            .wait_dst_stage_mask(&stages)
            .command_buffers(&cbs)
            .signal_semaphores(&signals);
        // SAFETY: recorded buffer, unsignalled fence, semaphores as above.
        unsafe {
            d.device
                .end_command_buffer(frame.cb)
                .map_err(vk_err("vkEndCommandBuffer"))?;
            d.device
                .queue_submit(d.queue, &[submit], s.fence)
                .map_err(vk_err("vkQueueSubmit"))?;
        }
        s.submitted = true;
        self.next = (self.next + 1) % self.slots.len();
        let swapchains = [self.swapchain];
        let indices = [frame.image];
        let present = vk::PresentInfoKHR::default()
            .wait_semaphores(&signals)
            .swapchains(&swapchains)
            .image_indices(&indices);
        // SAFETY: the image was acquired and rendered.
        match unsafe { d.swapchain_fn.queue_present(d.queue, &present) } {
            Ok(_) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(()),
            Err(r) => Err(VkError::call("vkQueuePresentKHR", r)),
        }
    }

    /// A frame whose recording failed: its command buffer is recorded again with only the
    /// acquired image's move to the present layout, and submitted and presented like any
    /// frame — the acquire semaphore is waited on and the image goes back to the swapchain.
    pub fn submit_blank(&mut self, d: &Device, frame: Frame) -> Result<(), VkError> {
        let image = self.images[frame.image as usize].raw;
        let barrier = [vk::ImageMemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT)
            .dst_stage_mask(vk::PipelineStageFlags2::NONE)
            .old_layout(vk::ImageLayout::UNDEFINED)
            .new_layout(vk::ImageLayout::PRESENT_SRC_KHR)
            .image(image)
            .subresource_range(vk::ImageSubresourceRange {
                aspect_mask: vk::ImageAspectFlags::COLOR,
                base_mip_level: 0,
                level_count: 1,
                base_array_layer: 0,
                layer_count: 1,
            })];
        // SAFETY: the buffer is not pending (never submitted since the slot's fence wait).
        unsafe {
            d.device
                .reset_command_buffer(frame.cb, vk::CommandBufferResetFlags::empty())
                .map_err(vk_err("vkResetCommandBuffer"))?;
            d.device
                .begin_command_buffer(frame.cb, &vk::CommandBufferBeginInfo::default())
                .map_err(vk_err("vkBeginCommandBuffer"))?;
            d.device.cmd_pipeline_barrier2(
                frame.cb,
                &vk::DependencyInfo::default().image_memory_barriers(&barrier),
            );
        }
        self.submit(d, frame)
    }

    pub fn destroy(self, d: &Device) {
        // SAFETY: the device is idle (the caller waited); null handles are ignored.
        unsafe {
            let _ = d.device.device_wait_idle();
            for s in &self.slots {
                d.device.destroy_fence(s.fence, None);
                d.device.destroy_semaphore(s.acquired, None);
            }
            d.device.destroy_command_pool(self.pool, None);
            for (image, rendered) in self.images.iter().zip(&self.rendered) {
                d.device.destroy_image_view(image.view, None);
                d.device.destroy_semaphore(*rendered, None);
            }
            d.swapchain_fn.destroy_swapchain(self.swapchain, None);
        }
    }
}

/// A system property (`adb shell setprop debug.tilegraph.profile adreno-7xx`), if set.
pub fn system_property(name: &CStr) -> Option<String> {
    let mut value = [0 as libc::c_char; 92]; // PROP_VALUE_MAX
                                             // SAFETY: `name` is NUL-terminated; `value` has PROP_VALUE_MAX bytes.
    let len = unsafe { libc::__system_property_get(name.as_ptr(), value.as_mut_ptr()) };
    if len <= 0 {
        return None;
    }
    // SAFETY: the property value is NUL-terminated within the buffer.
    let s = unsafe { CStr::from_ptr(value.as_ptr()) };
    s.to_str().ok().map(str::to_string)
}
