//! Device creation, profile selection, validation plumbing and memory placement on lavapipe.

use tilegraph_e2e::{gpu, gpu_with};
use tilegraph_profile::{MemoryFlags, MemoryUse};
use tilegraph_vk::ash::vk;
use tilegraph_vk::{Feature, FeatureRequest};

#[test]
fn lavapipe_is_detected_as_lavapipe() {
    let g = gpu(None).unwrap();
    if std::env::var_os("TILEGRAPH_PROFILE").is_none()
        && g.physical.identity.device_name.starts_with("llvmpipe")
    {
        assert_eq!(
            g.profile().name,
            "lavapipe",
            "matched by {}",
            g.selection.matched_by
        );
    }
    assert!(g.validation_enabled());
    assert!(g.has_feature(Feature::Synchronization2));
}

#[test]
fn forced_profiles_all_create_a_device() {
    for name in ["adreno-7xx", "mali-valhall", "powervr-b", "desktop-nvidia"] {
        let g = gpu(Some(name)).unwrap();
        assert_eq!(g.profile().name, name);
        assert!(g.selection.matched_by.to_string().contains("forced"));
    }
}

/// Proves that the harness catches validation errors: one invalid call on purpose.
#[test]
fn a_deliberate_validation_error_is_caught() {
    let g = gpu(None).unwrap();
    // VUID-VkBufferCreateInfo-usage-requiredbitmask: usage must not be 0.
    let info = vk::BufferCreateInfo::default()
        .size(256)
        .usage(vk::BufferUsageFlags::empty());
    // SAFETY: deliberately invalid usage, caught by the layer; the driver tolerates it.
    let buffer = unsafe { g.device.create_buffer(&info, None) };
    if let Ok(b) = buffer {
        // SAFETY: unused buffer.
        unsafe { g.device.destroy_buffer(b, None) };
    }
    let messages = g.take_validation_messages();
    assert!(
        messages
            .iter()
            .any(|m| m.contains("VUID-VkBufferCreateInfo-usage")),
        "the layer did not report the invalid call: {messages:?}"
    );
    // And the same report, had it not been taken, would have failed the test:
    let info = vk::BufferCreateInfo::default()
        .size(256)
        .usage(vk::BufferUsageFlags::empty());
    // SAFETY: as above.
    if let Ok(b) = unsafe { g.device.create_buffer(&info, None) } {
        // SAFETY: unused buffer.
        unsafe { g.device.destroy_buffer(b, None) };
    }
    let err = g.check_validation().unwrap_err();
    assert!(err.to_string().contains("validation message"), "{err}");
}

#[test]
fn allocations_land_in_the_profile_chosen_type() {
    for profile in ["lavapipe", "adreno-7xx", "mali-valhall"] {
        let g = gpu(Some(profile)).unwrap();
        for use_ in [
            MemoryUse::StaticGeometry,
            MemoryUse::GpuOnly,
            MemoryUse::Streaming,
            MemoryUse::Readback,
            MemoryUse::Staging,
        ] {
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::TRANSFER_SRC;
            let b = g.create_buffer("probe", 4096, usage, use_).unwrap();
            let expected = g.choose_memory(use_, u32::MAX).unwrap();
            assert_eq!(b.memory, expected);
            assert_eq!(
                b.memory_properties().as_raw(),
                expected.flags.bits(),
                "{profile} {use_:?}"
            );
            if use_.host_access() {
                assert!(b.mapped().is_some(), "{use_:?} must be mapped");
            }
            g.destroy_buffer(b);
        }
        // Narrowed type bits are honoured: no allowed type is an error, not a silent fallback.
        let err = g.choose_memory(MemoryUse::Streaming, 0).unwrap_err();
        assert!(err.to_string().contains("no memory type"), "{err}");
        let _ = MemoryFlags::HOST_VISIBLE;
    }
}

#[test]
fn optional_features_are_enabled_only_when_supported() {
    let want = FeatureRequest::default().want(Feature::ALL);
    let g = gpu_with(None, want).unwrap();
    for f in Feature::ALL {
        assert_eq!(g.has_feature(f), g.physical.supported.contains(&f), "{f}");
    }
}

#[test]
fn an_unknown_device_name_is_a_typed_error() {
    tilegraph_e2e::init_logging();
    let mut o = tilegraph_e2e::options(None, FeatureRequest::default());
    o.device = Some("no such gpu 9000".into());
    match tilegraph_e2e::context(o) {
        Err(tilegraph_vk::VkError::DeviceNotFound { wanted, available }) => {
            assert_eq!(wanted, "no such gpu 9000");
            assert!(!available.is_empty());
        }
        Err(e) => panic!("expected DeviceNotFound, got {e}"),
        Ok(_) => panic!("expected DeviceNotFound, got a device"),
    }
}

/// Proves synchronization validation is on: two unsynchronized writes to one buffer.
#[test]
fn a_deliberate_sync_hazard_is_caught() {
    let g = gpu(None).unwrap();
    let b = g
        .create_buffer(
            "hazard",
            256,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryUse::GpuOnly,
        )
        .unwrap();
    g.submit_and_wait(|cb| {
        // SAFETY: deliberately racing writes (WAW) for the layer to catch; valid otherwise.
        unsafe {
            g.device.cmd_fill_buffer(cb, b.raw, 0, 256, 1);
            g.device.cmd_fill_buffer(cb, b.raw, 0, 256, 2);
        }
        Ok(())
    })
    .unwrap();
    g.destroy_buffer(b);
    let messages = g.take_validation_messages();
    assert!(
        messages
            .iter()
            .any(|m| m.contains("SYNC-HAZARD-WRITE-AFTER-WRITE")),
        "synchronization validation did not report the WAW hazard: {messages:?}"
    );
}

/// Host writes go through `write_mapped`, which copies and flushes (non-coherent memory); it
/// refuses a write past the end and a buffer the host cannot see, and the bytes read back.
#[test]
fn mapped_writes_are_bounded_and_reach_the_buffer() {
    let g = gpu(Some("lavapipe")).unwrap();
    let mut staging = g
        .create_buffer(
            "staging",
            64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryUse::Staging,
        )
        .unwrap();
    g.write_mapped(&mut staging, 16, &[7u8; 16]).unwrap();
    assert_eq!(&staging.mapped().unwrap()[16..32], &[7u8; 16]);
    assert!(g.write_mapped(&mut staging, 60, &[0u8; 8]).is_err());
    assert!(g.write_mapped(&mut staging, usize::MAX, &[0u8; 1]).is_err());
    let mut device_only = g
        .create_buffer(
            "device only",
            64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryUse::GpuOnly,
        )
        .unwrap();
    if device_only.mapped().is_none() {
        assert!(g.write_mapped(&mut device_only, 0, &[1u8; 4]).is_err());
    }
    g.destroy_buffer(staging);
    g.destroy_buffer(device_only);
}
