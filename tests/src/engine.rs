//! A stand-in for a game engine's Vulkan setup, written the way an engine writes it — straight
//! ash, no tilegraph: its own instance with the validation layer, synchronization validation and
//! its own debug messenger, its own device and queue. Tests hand these to tilegraph
//! ([`Engine::adopt`]) and check, after tilegraph is gone, that the engine can still destroy
//! everything with the layer silent (nothing tilegraph made was left alive on the device).

use std::ffi::{c_void, CStr};
use std::sync::Mutex;

use tilegraph_vk::ash::{self, vk};
use tilegraph_vk::{AdoptedDevice, Context, DeviceConfig, FeatureRequest, Instance, VkError};

/// What the engine's messenger collected (warnings and errors), boxed: its address is the
/// messenger's user data.
#[derive(Default)]
struct Messages(Mutex<Vec<String>>);

unsafe extern "system" fn collect(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    // Loader messages about the machine's other manifests are not about this program.
    if types == vk::DebugUtilsMessageTypeFlagsEXT::GENERAL {
        return vk::FALSE;
    }
    let failure = vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
        | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING;
    if !severity.intersects(failure) {
        return vk::FALSE;
    }
    // SAFETY: valid for the call (spec); the message is NUL-terminated or null.
    let text = unsafe { data.as_ref() }
        .filter(|d| !d.p_message.is_null())
        .map(|d| {
            unsafe { CStr::from_ptr(d.p_message) }
                .to_string_lossy()
                .into_owned()
        })
        .unwrap_or_default();
    // SAFETY: the user data is the engine's boxed `Messages`, alive while the messenger is.
    if let Some(m) = unsafe { (user_data as *const Messages).as_ref() } {
        if let Ok(mut m) = m.0.lock() {
            m.push(text);
        }
    }
    vk::FALSE
}

/// The engine's instance, device and messenger.
pub struct Engine {
    entry: ash::Entry,
    pub instance: ash::Instance,
    debug_utils: ash::ext::debug_utils::Instance,
    messenger: vk::DebugUtilsMessengerEXT,
    messages: Box<Messages>,
    pub physical: vk::PhysicalDevice,
    pub queue_family: u32,
    pub device: Option<ash::Device>,
}

impl Engine {
    /// An instance with validation (synchronization validation on) and a messenger, and the
    /// first physical device with a graphics + compute queue (lavapipe in CI).
    pub fn start() -> Engine {
        crate::init_logging();
        // SAFETY: loading the system's Vulkan loader.
        let entry = unsafe { ash::Entry::load() }.expect("the Vulkan loader");
        let app = vk::ApplicationInfo::default()
            .application_name(c"engine")
            .api_version(vk::API_VERSION_1_3);
        let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
        let extensions = [
            ash::ext::debug_utils::NAME.as_ptr(),
            ash::ext::validation_features::NAME.as_ptr(),
        ];
        let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        let messages = Box::<Messages>::default();
        let messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                    | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(collect))
            .user_data(&*messages as *const Messages as *mut c_void);
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions)
            .push_next(&mut features);
        // SAFETY: every pointer refers to locals that outlive the call.
        let instance = crate::lifecycle(|| unsafe { entry.create_instance(&info, None) })
            .expect("vkCreateInstance");
        let debug_utils = ash::ext::debug_utils::Instance::new(&entry, &instance);
        // SAFETY: the messages box outlives the messenger (destroyed in `destroy`).
        let messenger = unsafe { debug_utils.create_debug_utils_messenger(&messenger_info, None) }
            .expect("vkCreateDebugUtilsMessengerEXT");
        // SAFETY: valid instance.
        let physicals = unsafe { instance.enumerate_physical_devices() }.expect("physical devices");
        let want = vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE;
        let (physical, queue_family) = physicals
            .iter()
            .find_map(|&p| {
                // SAFETY: `p` belongs to the instance.
                let families = unsafe { instance.get_physical_device_queue_family_properties(p) };
                let family = families.iter().position(|f| f.queue_flags.contains(want))?;
                Some((p, family as u32))
            })
            .expect("a device with a graphics + compute queue");
        Engine {
            entry,
            instance,
            debug_utils,
            messenger,
            messages,
            physical,
            queue_family,
            device: None,
        }
    }

    /// The engine's `vkGetInstanceProcAddr`, as it would hand it to tilegraph.
    pub fn get_instance_proc_addr(&self) -> vk::PFN_vkGetInstanceProcAddr {
        self.entry.static_fn().get_instance_proc_addr
    }

    /// The whole embedding handshake: tilegraph adopts the instance, says what `request` needs
    /// on the engine's physical device, the engine creates its device with that (and its own
    /// queue), and tilegraph adopts the device with `profile` forced (or detected).
    pub fn adopt(
        &mut self,
        request: &FeatureRequest,
        profile: Option<&str>,
    ) -> Result<Context, VkError> {
        // SAFETY: the instance and its loader entry point outlive the context (`destroy` is
        // called after the context is gone).
        let instance = unsafe {
            Instance::adopt(self.get_instance_proc_addr(), self.instance.handle(), true)
        }?;
        let physical = instance.physical_device(self.physical, self.queue_family)?;
        let mut config = DeviceConfig::new(&physical, request)?;
        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(self.queue_family)
            .queue_priorities(&priorities)];
        let info = config.chain(vk::DeviceCreateInfo::default().queue_create_infos(&queues));
        // SAFETY: features and extensions as the physical device reported them.
        let device =
            crate::lifecycle(|| unsafe { self.instance.create_device(self.physical, &info, None) })
                .expect("vkCreateDevice");
        let handle = device.handle();
        self.device = Some(device);
        let adopted = AdoptedDevice {
            physical_device: self.physical,
            device: handle,
            queue_family: self.queue_family,
            queue_index: 0,
            enabled: config.enabled.clone(),
            profile: profile.map(str::to_string),
            profile_forced_by: "the test engine".into(),
        };
        // SAFETY: the device was created just above with the configuration tilegraph asked
        // for; the engine destroys it only after the context.
        unsafe { Context::adopt(instance, adopted) }
    }

    /// The messages the engine's messenger has collected so far (and clears them).
    pub fn take_messages(&self) -> Vec<String> {
        self.messages
            .0
            .lock()
            .map(|mut m| std::mem::take(&mut *m))
            .unwrap_or_default()
    }

    /// Destroys the device, the messenger and the instance, in that order, and returns every
    /// message the layer reported, including those of the teardown (objects left alive).
    pub fn destroy(self) -> Vec<String> {
        crate::lifecycle(|| self.teardown())
    }

    fn teardown(mut self) -> Vec<String> {
        if let Some(device) = self.device.take() {
            // SAFETY: tilegraph is gone; the engine waits, then destroys its device.
            unsafe {
                let _ = device.device_wait_idle();
                device.destroy_device(None);
            }
        }
        let messages = self.take_messages();
        // SAFETY: everything made from the instance is gone.
        unsafe {
            self.debug_utils
                .destroy_debug_utils_messenger(self.messenger, None);
            self.instance.destroy_instance(None);
        }
        messages
    }
}
