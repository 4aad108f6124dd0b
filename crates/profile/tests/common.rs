//! Device identities of real GPUs, as their drivers report them, for detection and memory tests.
#![allow(dead_code)]

use tilegraph_profile::{
    driver, vendor, DeviceIdentity, DeviceType, MemoryFlags, MemoryHeap, MemoryType,
};

pub const DL: u32 = 0x1;
pub const HV: u32 = 0x2;
pub const HC: u32 = 0x4;
pub const CACHED: u32 = 0x8;
pub const LAZY: u32 = 0x10;

pub fn types(list: &[(u32, u32)]) -> Vec<MemoryType> {
    list.iter()
        .map(|&(flags, heap_index)| MemoryType {
            flags: MemoryFlags(flags),
            heap_index,
        })
        .collect()
}

pub fn heaps(list: &[(u64, bool)]) -> Vec<MemoryHeap> {
    list.iter()
        .map(|&(size_bytes, device_local)| MemoryHeap {
            size_bytes,
            device_local,
        })
        .collect()
}

pub fn identity(
    vendor_id: u32,
    device_id: u32,
    driver_id: u32,
    name: &str,
    device_type: DeviceType,
) -> DeviceIdentity {
    DeviceIdentity {
        vendor_id,
        device_id,
        driver_id,
        device_name: name.to_string(),
        driver_version: 0,
        api_version: (1 << 22) | (3 << 12),
        device_type,
        memory_types: types(&[(DL | HV | HC | CACHED, 0)]),
        memory_heaps: heaps(&[(2 << 30, true)]),
    }
}

/// lavapipe on Mesa 22.3 (read off this machine's vulkaninfo): one heap, one type with flags 0xF.
pub fn lavapipe() -> DeviceIdentity {
    identity(
        vendor::MESA,
        0,
        driver::MESA_LLVMPIPE,
        "llvmpipe (LLVM 15.0.6, 256 bits)",
        DeviceType::Cpu,
    )
}

/// Adreno as seed 001 describes it: type 0 = DEVICE_LOCAL (1), type 1 = DEVICE_LOCAL |
/// HOST_VISIBLE | HOST_COHERENT | HOST_CACHED (15), one device-local heap.
pub fn adreno_740() -> DeviceIdentity {
    let mut d = identity(
        vendor::QUALCOMM,
        0x4305_0A01,
        driver::QUALCOMM_PROPRIETARY,
        "Adreno (TM) 740",
        DeviceType::IntegratedGpu,
    );
    d.memory_types = types(&[(DL, 0), (DL | HV | HC | CACHED, 0)]);
    d.memory_heaps = heaps(&[(7 << 30, true)]);
    d
}

/// A Mali Valhall table with a lazily allocated type and a protected heap; heap sizes from a
/// Mali-G57 r51p0 report, flag values as Arm's driver reports the four kinds (docs/PROFILES.md).
pub fn mali_g710() -> DeviceIdentity {
    let mut d = identity(
        vendor::ARM,
        0xA862_0000,
        driver::ARM_PROPRIETARY,
        "Mali-G710",
        DeviceType::IntegratedGpu,
    );
    d.memory_types = types(&[
        (DL | HV | HC, 0),
        (DL | HV | HC | CACHED, 0),
        (DL | LAZY, 0),
        (DL | 0x20, 1),
    ]);
    d.memory_heaps = heaps(&[(2_941_546_496, true), (104_857_600, true)]);
    d
}

/// An NVIDIA desktop table (a published vulkaninfo of a 6 GiB card): VRAM heap, system heap with
/// host-visible coherent and host-cached types, and the ~256 MiB device-local host-visible BAR.
pub fn nvidia_rtx() -> DeviceIdentity {
    let mut d = identity(
        vendor::NVIDIA,
        0x2206,
        driver::NVIDIA_PROPRIETARY,
        "NVIDIA GeForce RTX 3080",
        DeviceType::DiscreteGpu,
    );
    // Seven format-specific types with no flags precede the real ones, as NVIDIA reports them.
    let mut t = vec![(0, 1); 7];
    t.extend([
        (DL, 0),
        (HV | HC, 1),
        (HV | HC | CACHED, 1),
        (DL | HV | HC, 2),
    ]);
    d.memory_types = types(&t);
    d.memory_heaps = heaps(&[
        (6_442_450_944, true),
        (50_523_119_616, false),
        (257_949_696, true),
    ]);
    d
}
