//! Memory-type selection on real memory tables, and gpu-allocator-free checks of the rules.

mod common;

use common::*;
use tilegraph_profile::{select_memory_type, DeviceIdentity, MemoryUse, ProfileSet};

fn choose(profile: &str, d: &DeviceIdentity, use_: MemoryUse) -> u32 {
    let set = ProfileSet::embedded().unwrap();
    let p = set.get(profile).unwrap();
    select_memory_type(&p.memory, &d.memory_types, u32::MAX, use_)
        .unwrap()
        .type_index
}

#[test]
fn lavapipe_single_type_serves_every_use() {
    for u in MemoryUse::ALL {
        assert_eq!(choose("lavapipe", &lavapipe(), u), 0, "{u:?}");
    }
}

#[test]
fn adreno_one_versus_fifteen() {
    // seed 001: static data in type 1 (flags 1), per-frame CPU-written data in type 15.
    let d = adreno_740();
    assert_eq!(d.memory_types[0].flags.bits(), 1);
    assert_eq!(d.memory_types[1].flags.bits(), 15);
    assert_eq!(choose("adreno-7xx", &d, MemoryUse::StaticGeometry), 0);
    assert_eq!(choose("adreno-7xx", &d, MemoryUse::GpuOnly), 0);
    assert_eq!(choose("adreno-7xx", &d, MemoryUse::Streaming), 1);
    assert_eq!(choose("adreno-7xx", &d, MemoryUse::Readback), 1);
    assert_eq!(choose("adreno-7xx", &d, MemoryUse::Staging), 1);
    // No lazily allocated type: transient attachments take plain device-local memory.
    assert_eq!(choose("adreno-7xx", &d, MemoryUse::TransientAttachment), 0);
}

#[test]
fn mali_transients_are_lazily_allocated() {
    let d = mali_g710();
    assert_eq!(
        choose("mali-valhall", &d, MemoryUse::TransientAttachment),
        2
    );
    assert_eq!(choose("mali-valhall", &d, MemoryUse::Streaming), 1);
    // Lazily allocated memory never backs anything else, protected memory never anything.
    for u in MemoryUse::ALL {
        let i = choose("mali-valhall", &d, u);
        assert_ne!(i, 3, "{u:?} took protected memory");
        if u != MemoryUse::TransientAttachment {
            assert_ne!(i, 2, "{u:?} took lazily allocated memory");
        }
    }
}

#[test]
fn nvidia_desktop_table() {
    let d = nvidia_rtx();
    let p = "desktop-nvidia";
    assert_eq!(choose(p, &d, MemoryUse::StaticGeometry), 7, "VRAM");
    assert_eq!(choose(p, &d, MemoryUse::GpuOnly), 7, "VRAM");
    assert_eq!(
        choose(p, &d, MemoryUse::Streaming),
        10,
        "the device-local host-visible BAR window"
    );
    assert_eq!(choose(p, &d, MemoryUse::Readback), 9, "host cached");
    assert_eq!(
        choose(p, &d, MemoryUse::Staging),
        8,
        "host coherent, uncached"
    );
    assert_eq!(choose(p, &d, MemoryUse::TransientAttachment), 7);
}

#[test]
fn type_bits_narrow_the_choice() {
    let set = ProfileSet::embedded().unwrap();
    let p = set.get("adreno-7xx").unwrap();
    let d = adreno_740();
    // A resource that can only live in type 1 gets type 1 even for static data.
    let c =
        select_memory_type(&p.memory, &d.memory_types, 0b10, MemoryUse::StaticGeometry).unwrap();
    assert_eq!(c.type_index, 1);
    // Host access is a hard requirement: type 0 alone cannot serve streaming.
    assert!(select_memory_type(&p.memory, &d.memory_types, 0b01, MemoryUse::Streaming).is_err());
}

mod props {
    use super::*;
    use proptest::prelude::*;
    use tilegraph_profile::{MemoryFlags, MemoryType};

    proptest! {
        /// Whatever the table, the choice is an allowed type, never protected, host-visible
        /// when the CPU maps it, and lazily allocated only for transient attachments.
        #[test]
        fn choices_respect_hard_rules(flags in proptest::collection::vec(0u32..64, 1..12), bits in any::<u32>()) {
            let set = ProfileSet::embedded().unwrap();
            let types: Vec<MemoryType> = flags.iter().map(|&f| MemoryType { flags: MemoryFlags(f), heap_index: 0 }).collect();
            for p in set.profiles() {
                for u in MemoryUse::ALL {
                    if let Ok(c) = select_memory_type(&p.memory, &types, bits, u) {
                        let i = c.type_index as usize;
                        prop_assert!(bits & (1 << i) != 0);
                        let f = types[i].flags;
                        prop_assert!(!f.contains(MemoryFlags::PROTECTED));
                        if u.host_access() { prop_assert!(f.contains(MemoryFlags::HOST_VISIBLE)); }
                        if u != MemoryUse::TransientAttachment { prop_assert!(!f.contains(MemoryFlags::LAZILY_ALLOCATED)); }
                    }
                }
            }
        }
    }
}
