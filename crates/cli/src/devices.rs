//! `tilegraph devices`: what Vulkan sees, which profile each device gets and why, and the
//! memory type each use of memory lands in.

use std::collections::BTreeMap;

use serde::Serialize;
use tilegraph_profile::{select_memory_type, MemoryUse, ProfileSet};
use tilegraph_vk::{Instance, Validation};

use crate::CliError;

#[derive(Serialize)]
struct MemoryEntry {
    type_index: u32,
    flags: u32,
    flag_names: Vec<&'static str>,
    heap_index: u32,
}

#[derive(Serialize)]
struct DeviceReport {
    index: usize,
    name: String,
    vendor_id: u32,
    device_id: u32,
    driver_id: u32,
    driver_name: String,
    driver_info: String,
    device_type: &'static str,
    api_version: String,
    profile: String,
    matched_by: String,
    forced: bool,
    memory: BTreeMap<&'static str, MemoryEntry>,
    /// The profile's pass and render-pass policies (their sources: docs/PROFILES.md).
    passes: tilegraph_profile::PassPolicy,
    render_pass: tilegraph_profile::RenderPassPolicy,
    /// The state rules `tilegraph lint` applies, each with its source.
    state_rules: Vec<tilegraph_profile::StateRule>,
}

pub fn run(json: bool) -> Result<(), CliError> {
    let instance = Instance::new("tilegraph devices", Validation::Off)?;
    let profiles = ProfileSet::from_env()?;
    let forced = std::env::var(tilegraph_profile::PROFILE_ENV).ok();
    let mut reports = Vec::new();
    for pd in instance.physical_devices()? {
        let sel = profiles.select(&pd.identity, forced.as_deref())?;
        let mut memory = BTreeMap::new();
        for use_ in MemoryUse::ALL {
            if let Ok(c) = select_memory_type(
                &sel.profile.memory,
                &pd.identity.memory_types,
                u32::MAX,
                use_,
            ) {
                let heap_index = pd
                    .identity
                    .memory_types
                    .get(c.type_index as usize)
                    .map_or(0, |t| t.heap_index);
                memory.insert(
                    use_.name(),
                    MemoryEntry {
                        type_index: c.type_index,
                        flags: c.flags.bits(),
                        flag_names: c.flags.names(),
                        heap_index,
                    },
                );
            }
        }
        reports.push(DeviceReport {
            index: pd.index,
            name: pd.identity.device_name.clone(),
            vendor_id: pd.identity.vendor_id,
            device_id: pd.identity.device_id,
            driver_id: pd.identity.driver_id,
            driver_name: pd.driver_name.clone(),
            driver_info: pd.driver_info.clone(),
            device_type: pd.identity.device_type.as_str(),
            api_version: pd.identity.api_version_string(),
            forced: matches!(sel.matched_by, tilegraph_profile::MatchedBy::Forced { .. }),
            matched_by: sel.matched_by.to_string(),
            passes: sel.profile.passes.clone(),
            render_pass: sel.profile.render_pass,
            state_rules: sel.profile.state_rules.clone(),
            profile: sel.profile.name,
            memory,
        });
    }
    if json {
        outln!("{}", serde_json::to_string_pretty(&reports)?)?;
        return Ok(());
    }
    for r in &reports {
        outln!("device {}: {}", r.index, r.name)?;
        outln!(
            "  vendor {:#06x}  device {:#x}  driver id {} ({} {})  type {}  Vulkan {}",
            r.vendor_id,
            r.device_id,
            r.driver_id,
            r.driver_name,
            r.driver_info,
            r.device_type,
            r.api_version
        )?;
        outln!("  profile {}  ({})", r.profile, r.matched_by)?;
        outln!("  memory type per use:")?;
        for (use_, m) in &r.memory {
            outln!(
                "    {use_:<22} type {:>2} (heap {})  {:#06x} {}",
                m.type_index,
                m.heap_index,
                m.flags,
                m.flag_names.join(" | ")
            )?;
        }
    }
    if reports.is_empty() {
        outln!("no Vulkan devices")?;
    }
    Ok(())
}
