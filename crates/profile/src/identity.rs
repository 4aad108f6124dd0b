//! Who the device is: the identifiers a profile is matched against.

use serde::{Deserialize, Serialize};

use crate::memory::{MemoryHeap, MemoryType};

/// PCI vendor IDs (and Khronos-assigned IDs for vendors without one) as reported in
/// `VkPhysicalDeviceProperties::vendorID`.
pub mod vendor {
    pub const QUALCOMM: u32 = 0x5143;
    pub const ARM: u32 = 0x13B5;
    pub const IMAGINATION: u32 = 0x1010;
    pub const APPLE: u32 = 0x106B;
    pub const NVIDIA: u32 = 0x10DE;
    pub const AMD: u32 = 0x1002;
    pub const INTEL: u32 = 0x8086;
    /// Samsung's PCI id, reported by Xclipse GPUs (RDNA-based, but not AMD's 0x1002).
    pub const SAMSUNG: u32 = 0x144D;
    /// `VK_VENDOR_ID_MESA`, used by lavapipe/llvmpipe.
    pub const MESA: u32 = 0x10005;
}

/// `VkDriverId` values (Vulkan 1.2 core), the ones the profiles name.
pub mod driver {
    pub const AMD_PROPRIETARY: u32 = 1;
    pub const AMD_OPEN_SOURCE: u32 = 2;
    pub const MESA_RADV: u32 = 3;
    pub const NVIDIA_PROPRIETARY: u32 = 4;
    pub const INTEL_PROPRIETARY_WINDOWS: u32 = 5;
    pub const INTEL_OPEN_SOURCE_MESA: u32 = 6;
    pub const IMAGINATION_PROPRIETARY: u32 = 7;
    pub const QUALCOMM_PROPRIETARY: u32 = 8;
    pub const ARM_PROPRIETARY: u32 = 9;
    pub const MOLTENVK: u32 = 14;
    pub const MESA_LLVMPIPE: u32 = 13;
    pub const MESA_TURNIP: u32 = 18;
    pub const MESA_PANVK: u32 = 20;
    pub const SAMSUNG_PROPRIETARY: u32 = 21;
    pub const MESA_NVK: u32 = 24;
    pub const MESA_HONEYKRISP: u32 = 26;
}

/// `VkPhysicalDeviceType`, without Vulkan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeviceType {
    Other,
    IntegratedGpu,
    DiscreteGpu,
    VirtualGpu,
    Cpu,
}

impl DeviceType {
    /// Preference when no device is named: discrete > integrated > virtual > CPU > other.
    pub fn preference(self) -> u32 {
        match self {
            DeviceType::DiscreteGpu => 4,
            DeviceType::IntegratedGpu => 3,
            DeviceType::VirtualGpu => 2,
            DeviceType::Cpu => 1,
            DeviceType::Other => 0,
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            DeviceType::Other => "other",
            DeviceType::IntegratedGpu => "integrated_gpu",
            DeviceType::DiscreteGpu => "discrete_gpu",
            DeviceType::VirtualGpu => "virtual_gpu",
            DeviceType::Cpu => "cpu",
        }
    }
}

/// Everything about a physical device that profile selection and memory-type selection need.
/// Built by `tilegraph-vk` from `VkPhysicalDeviceProperties2` / `VkPhysicalDeviceDriverProperties`
/// / `VkPhysicalDeviceMemoryProperties`, or by hand in tests from published device reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeviceIdentity {
    pub vendor_id: u32,
    pub device_id: u32,
    /// `VkDriverId`; 0 when the driver does not report one (Vulkan 1.1 without the extension).
    pub driver_id: u32,
    pub device_name: String,
    pub driver_version: u32,
    /// Packed `VK_MAKE_API_VERSION`.
    pub api_version: u32,
    pub device_type: DeviceType,
    pub memory_types: Vec<MemoryType>,
    pub memory_heaps: Vec<MemoryHeap>,
}

impl DeviceIdentity {
    /// "major.minor.patch" of the packed API version.
    pub fn api_version_string(&self) -> String {
        let v = self.api_version;
        format!("{}.{}.{}", (v >> 22) & 0x7F, (v >> 12) & 0x3FF, v & 0xFFF)
    }
}
