//! `tilegraph knobs`: every knob, its domain and default, a profile's value, and whether a scene
//! is offered it. Needs no device.

use serde::Serialize;
use tilegraph_passes::knobs::offered;
use tilegraph_passes::SceneContent;
use tilegraph_profile::knobs::{KnobValue, KNOBS};
use tilegraph_profile::ProfileSet;

use crate::CliError;

#[derive(Serialize)]
struct KnobJson {
    name: &'static str,
    domain: Vec<KnobValue>,
    default: KnobValue,
    profile: Option<KnobValue>,
    offered: bool,
    help: &'static str,
}

pub fn run(profile: Option<&str>, scene: Option<&str>, json: bool) -> Result<(), CliError> {
    let set = ProfileSet::from_env()?;
    let profile = profile.map(|p| set.get(p)).transpose()?;
    let content = scene
        .map(|s| crate::run::load_scene(s, false))
        .transpose()?
        .map(|s| SceneContent::of(&s));
    let rows: Vec<KnobJson> = KNOBS
        .iter()
        .map(|k| KnobJson {
            name: k.name,
            domain: k.domain.values(),
            default: k.default.into(),
            profile: profile.and_then(|p| p.knobs.get(k.name).cloned()),
            offered: content.is_none_or(|c| offered(c).any(|o| o.name == k.name)),
            help: k.help,
        })
        .collect();
    if json {
        outln!("{}", serde_json::to_string(&rows)?)?;
        return Ok(());
    }
    for r in rows.iter().filter(|r| r.offered) {
        let domain: Vec<String> = r.domain.iter().map(ToString::to_string).collect();
        outln!("{} = {}", r.name, r.profile.as_ref().unwrap_or(&r.default))?;
        outln!(
            "    {}; one of {} (default {}{})",
            r.help,
            domain.join(", "),
            r.default,
            match (&r.profile, profile) {
                (Some(_), Some(p)) => format!(", set by profile {}", p.name),
                _ => String::new(),
            }
        )?;
    }
    for r in rows.iter().filter(|r| !r.offered) {
        outln!("{}: not offered (the scene cannot use it)", r.name)?;
    }
    Ok(())
}
