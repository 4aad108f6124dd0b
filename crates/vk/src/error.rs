use ash::vk;

/// Everything the Vulkan backend can report. Device loss and out-of-memory are values, not panics.
#[derive(Debug, thiserror::Error)]
pub enum VkError {
    #[error("cannot load the Vulkan loader (libvulkan.so.1): {0}; install it with `apt-get install libvulkan1 mesa-vulkan-drivers`")]
    Loader(String),
    #[error("{call} failed: {result}")]
    Call {
        call: &'static str,
        result: vk::Result,
    },
    #[error("the GPU device was lost during {call}")]
    DeviceLost { call: &'static str },
    #[error("out of {kind} memory during {call}")]
    OutOfMemory {
        call: &'static str,
        kind: &'static str,
    },
    #[error(
        "no Vulkan 1.2+ physical device with a graphics+compute queue was found (saw: {seen})"
    )]
    NoDevice { seen: String },
    #[error("TILEGRAPH_DEVICE={wanted:?} names no device (available: {available})")]
    DeviceNotFound { wanted: String, available: String },
    #[error("device {device:?} lacks required {what}: {missing}")]
    MissingRequired {
        device: String,
        what: &'static str,
        missing: String,
    },
    #[error("the Khronos validation layer (VK_LAYER_KHRONOS_validation) is required but not installed; install it with `apt-get install vulkan-validationlayers`")]
    ValidationLayerMissing,
    #[error("{count} validation message(s):\n{messages}")]
    Validation { count: usize, messages: String },
    #[error("memory for {name:?}: {source}")]
    Allocation {
        name: String,
        #[source]
        source: gpu_allocator::AllocationError,
    },
    #[error(transparent)]
    Profile(#[from] tilegraph_profile::ProfileError),
    #[error("invalid SPIR-V module {name}: {reason}")]
    Spirv { name: String, reason: String },
    #[error("{what}: {reason}")]
    Invalid { what: String, reason: String },
}

impl VkError {
    /// Maps a failed Vulkan call to the most specific error.
    pub fn call(call: &'static str, result: vk::Result) -> Self {
        match result {
            vk::Result::ERROR_DEVICE_LOST => VkError::DeviceLost { call },
            vk::Result::ERROR_OUT_OF_HOST_MEMORY => VkError::OutOfMemory { call, kind: "host" },
            vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => VkError::OutOfMemory {
                call,
                kind: "device",
            },
            result => VkError::Call { call, result },
        }
    }
}

impl VkError {
    /// Out of host or device memory, from a Vulkan call, gpu-allocator or the context's memory
    /// budget: freeing memory and retrying the frame may succeed.
    pub fn is_out_of_memory(&self) -> bool {
        matches!(
            self,
            VkError::OutOfMemory { .. }
                | VkError::Allocation {
                    source: gpu_allocator::AllocationError::OutOfMemory,
                    ..
                }
        )
    }

    /// The device was lost: the engine destroys what it made on it (tilegraph's objects too)
    /// and the device.
    pub fn is_device_lost(&self) -> bool {
        matches!(self, VkError::DeviceLost { .. })
    }
}

/// Shorthand: `unsafe { device.foo() }.vk("vkFoo")?`.
pub(crate) trait VkResultExt<T> {
    fn vk(self, call: &'static str) -> Result<T, VkError>;
}

impl<T> VkResultExt<T> for Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T, VkError> {
        self.map_err(|r| VkError::call(call, r))
    }
}
