//! Loading the profile set and matching a device against it.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{DeviceIdentity, DeviceType, MemoryUse, Profile, ProfileError};

include!(concat!(env!("OUT_DIR"), "/embedded_profiles.rs"));

/// Environment variable that forces a profile by name.
pub const PROFILE_ENV: &str = "TILEGRAPH_PROFILE";
/// Environment variable naming a directory whose `*.toml` profiles override the embedded ones.
pub const PROFILE_DIR_ENV: &str = "TILEGRAPH_PROFILE_DIR";

/// Which devices a profile claims, from the most to the least specific evidence.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatchRule {
    /// PCI vendor IDs; empty = any vendor.
    #[serde(default)]
    pub vendor_ids: Vec<u32>,
    /// `VkDriverId`s that, with a vendor match, identify the family when no name pattern does.
    #[serde(default)]
    pub driver_ids: Vec<u32>,
    /// Device-name globs (`*` any run, `?` one character), e.g. `"Adreno (TM) 7*"`.
    #[serde(default)]
    pub device_names: Vec<String>,
    /// This profile takes the vendor's devices that no name pattern claims (newest family).
    #[serde(default)]
    pub vendor_default: bool,
    /// Last-resort fallback by device type.
    #[serde(default)]
    pub device_types: Vec<DeviceType>,
}

/// Why a profile was chosen.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum MatchedBy {
    /// Named by `by`: `TILEGRAPH_PROFILE` (what [`ProfileSet::select`] assumes), or what the
    /// caller says forced it (`--profile`). A caller's request takes precedence over the
    /// variable.
    Forced { name: String, by: String },
    /// The device name matched one of the profile's patterns (and the vendor, if listed).
    DeviceName { pattern: String },
    /// Vendor and driver ID matched a vendor-default profile.
    VendorAndDriver { vendor_id: u32, driver_id: u32 },
    /// Only the vendor matched a vendor-default profile.
    Vendor { vendor_id: u32 },
    /// Nothing specific matched; chosen by device type.
    DeviceType { device_type: DeviceType },
}

impl std::fmt::Display for MatchedBy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MatchedBy::Forced { name, by } if by == PROFILE_ENV => {
                write!(f, "forced by {PROFILE_ENV}={name}")
            }
            MatchedBy::Forced { name, by } => write!(f, "forced by {by} {name}"),
            MatchedBy::DeviceName { pattern } => write!(f, "device name matches {pattern:?}"),
            MatchedBy::VendorAndDriver {
                vendor_id,
                driver_id,
            } => {
                write!(f, "vendor {vendor_id:#x} with driver id {driver_id}")
            }
            MatchedBy::Vendor { vendor_id } => write!(f, "vendor {vendor_id:#x}"),
            MatchedBy::DeviceType { device_type } => {
                write!(f, "fallback for device type {}", device_type.as_str())
            }
        }
    }
}

/// The outcome of selection.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    pub profile: Profile,
    pub matched_by: MatchedBy,
    /// Where the profile came from: `embedded:<file>` or a path.
    pub source: String,
}

/// All known profiles: the embedded ones, optionally overridden from a directory.
#[derive(Debug, Clone)]
pub struct ProfileSet {
    entries: Vec<(String, Profile)>,
}

impl ProfileSet {
    /// The profiles compiled into the binary from `config/profiles/`.
    pub fn embedded() -> Result<Self, ProfileError> {
        let mut set = ProfileSet {
            entries: Vec::new(),
        };
        for (file, text) in EMBEDDED {
            set.insert(
                format!("embedded:{file}"),
                parse_profile(text, file)?,
                false,
            )?;
        }
        Ok(set)
    }

    /// The embedded profiles, overridden by `$TILEGRAPH_PROFILE_DIR` when it is set.
    pub fn from_env() -> Result<Self, ProfileError> {
        let set = Self::embedded()?;
        match std::env::var_os(PROFILE_DIR_ENV) {
            Some(dir) if !dir.is_empty() => set.with_dir(Path::new(&dir)),
            _ => Ok(set),
        }
    }

    /// Adds every `*.toml` of `dir`; a profile with the name of an existing one replaces it.
    pub fn with_dir(mut self, dir: &Path) -> Result<Self, ProfileError> {
        let io = |source| ProfileError::Io {
            path: dir.to_path_buf(),
            source,
        };
        let mut files: Vec<_> = std::fs::read_dir(dir)
            .map_err(io)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        // A file here replaces an embedded profile of its name, but two files naming one
        // profile are a mistake (which one wins would depend on file names).
        let mut loaded: Vec<(String, String)> = Vec::new();
        for path in files {
            let text = std::fs::read_to_string(&path).map_err(|source| ProfileError::Io {
                path: path.clone(),
                source,
            })?;
            let shown = path.display().to_string();
            let profile = parse_profile(&text, &shown)?;
            log::info!("profile {} loaded from {shown}", profile.name);
            if let Some((_, first)) = loaded.iter().find(|(name, _)| *name == profile.name) {
                return Err(ProfileError::DuplicateName {
                    name: profile.name,
                    first: first.clone(),
                    second: shown,
                });
            }
            loaded.push((profile.name.clone(), shown.clone()));
            self.insert(shown, profile, true)?;
        }
        Ok(self)
    }

    fn insert(
        &mut self,
        source: String,
        profile: Profile,
        replace: bool,
    ) -> Result<(), ProfileError> {
        if let Some(slot) = self
            .entries
            .iter_mut()
            .find(|(_, p)| p.name == profile.name)
        {
            if !replace {
                return Err(ProfileError::DuplicateName {
                    name: profile.name,
                    first: slot.0.clone(),
                    second: source,
                });
            }
            *slot = (source, profile);
        } else {
            self.entries.push((source, profile));
        }
        self.entries.sort_by(|a, b| a.1.name.cmp(&b.1.name));
        Ok(())
    }

    pub fn profiles(&self) -> impl Iterator<Item = &Profile> {
        self.entries.iter().map(|(_, p)| p)
    }

    pub fn names(&self) -> Vec<&str> {
        self.entries.iter().map(|(_, p)| p.name.as_str()).collect()
    }

    pub fn get(&self, name: &str) -> Result<&Profile, ProfileError> {
        self.entries
            .iter()
            .find(|(_, p)| p.name == name)
            .map(|(_, p)| p)
            .ok_or_else(|| ProfileError::UnknownProfile {
                name: name.to_string(),
                available: self.names().join(", "),
            })
    }

    /// Chooses the profile for a device. `forced` (normally `$TILEGRAPH_PROFILE`) wins outright;
    /// otherwise the most specific match: device-name pattern > vendor+driver > vendor > type.
    pub fn select(
        &self,
        device: &DeviceIdentity,
        forced: Option<&str>,
    ) -> Result<Selection, ProfileError> {
        if let Some(name) = forced.filter(|n| !n.is_empty()) {
            let (source, profile) = self
                .entries
                .iter()
                .find(|(_, p)| p.name == name)
                .ok_or_else(|| ProfileError::UnknownProfile {
                    name: name.to_string(),
                    available: self.names().join(", "),
                })?;
            return Ok(Selection {
                profile: profile.clone(),
                matched_by: MatchedBy::Forced {
                    name: name.to_string(),
                    by: PROFILE_ENV.to_string(),
                },
                source: source.clone(),
            });
        }
        let mut best: Option<(u32, &String, &Profile, MatchedBy)> = None;
        for (source, profile) in &self.entries {
            if let Some((score, why)) = match_score(&profile.matching, device) {
                // Entries are sorted by name, so on a tie the first name wins: deterministic.
                if best.as_ref().is_none_or(|(s, ..)| score > *s) {
                    best = Some((score, source, profile, why));
                }
            }
        }
        match best {
            Some((_, source, profile, matched_by)) => Ok(Selection {
                profile: profile.clone(),
                matched_by,
                source: source.clone(),
            }),
            None => Err(ProfileError::NoMatch {
                device: device.device_name.clone(),
                device_type: device.device_type.as_str().to_string(),
            }),
        }
    }

    /// [`ProfileSet::select`] with `$TILEGRAPH_PROFILE` as the forced name.
    pub fn select_from_env(&self, device: &DeviceIdentity) -> Result<Selection, ProfileError> {
        let forced = std::env::var(PROFILE_ENV).ok();
        self.select(device, forced.as_deref())
    }
}

fn match_score(rule: &MatchRule, d: &DeviceIdentity) -> Option<(u32, MatchedBy)> {
    let vendor_ok = rule.vendor_ids.is_empty() || rule.vendor_ids.contains(&d.vendor_id);
    // A listed driver vouches for the name too: Mesa's drivers for other vendors' GPUs
    // (Honeykrisp on Apple silicon) report Mesa's vendor id.
    let driver_ok = rule.driver_ids.contains(&d.driver_id);
    if vendor_ok || driver_ok {
        if let Some(p) = rule
            .device_names
            .iter()
            .find(|p| glob_match(p, &d.device_name))
        {
            return Some((3, MatchedBy::DeviceName { pattern: p.clone() }));
        }
    }
    if rule.vendor_default && !rule.vendor_ids.is_empty() && vendor_ok {
        if rule.driver_ids.contains(&d.driver_id) {
            return Some((
                2,
                MatchedBy::VendorAndDriver {
                    vendor_id: d.vendor_id,
                    driver_id: d.driver_id,
                },
            ));
        }
        return Some((
            1,
            MatchedBy::Vendor {
                vendor_id: d.vendor_id,
            },
        ));
    }
    if rule.device_types.contains(&d.device_type) {
        return Some((
            0,
            MatchedBy::DeviceType {
                device_type: d.device_type,
            },
        ));
    }
    None
}

/// Glob match with `*` (any run, possibly empty) and `?` (exactly one character).
pub fn glob_match(pattern: &str, text: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let t: Vec<char> = text.chars().collect();
    // Iterative matcher with single backtrack point: linear for patterns with few stars.
    let (mut pi, mut ti) = (0usize, 0usize);
    let mut star: Option<(usize, usize)> = None;
    while ti < t.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == t[ti]) {
            pi += 1;
            ti += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some((pi, ti));
            pi += 1;
        } else if let Some((sp, st)) = star {
            pi = sp + 1;
            ti = st + 1;
            star = Some((sp, st + 1));
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|c| *c == '*')
}

/// Parses and validates one profile file. Errors name the file, the line and the key.
pub(crate) fn parse_profile(text: &str, file: &str) -> Result<Profile, ProfileError> {
    let profile: Profile = parse_toml(text, file)?;
    validate(&profile, file)?;
    Ok(profile)
}

/// Parses a TOML file of this crate's; errors name the file, the line and the key.
pub(crate) fn parse_toml<T: serde::de::DeserializeOwned>(
    text: &str,
    file: &str,
) -> Result<T, ProfileError> {
    let de = toml::Deserializer::new(text);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let key = match e.path().to_string() {
            p if p == "." || p.is_empty() => "<root>".to_string(),
            p => p,
        };
        let inner = e.inner();
        let (line, column) = inner
            .span()
            .map(|s| line_col(text, s.start))
            .or_else(|| key_line(text, &key))
            .unwrap_or((1, 1));
        ProfileError::Parse {
            file: file.to_string(),
            line,
            column,
            key,
            message: inner.message().to_string(),
        }
    })
}

fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Best-effort line of the last segment of a dotted key, for errors without a span.
fn key_line(text: &str, key: &str) -> Option<(usize, usize)> {
    let last = key.rsplit('.').next()?;
    text.lines().enumerate().find_map(|(i, l)| {
        let trimmed = l.trim_start();
        (trimmed.starts_with(last) && trimmed[last.len()..].trim_start().starts_with('='))
            .then_some((i + 1, l.len() - trimmed.len() + 1))
    })
}

fn validate(p: &Profile, file: &str) -> Result<(), ProfileError> {
    let invalid = |key: &str, reason: &str| ProfileError::Invalid {
        file: file.to_string(),
        key: key.to_string(),
        reason: reason.to_string(),
    };
    if p.name.is_empty()
        || !p
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-')
    {
        return Err(invalid(
            "name",
            "must be non-empty, ASCII letters, digits and '-'",
        ));
    }
    for (key, px) in [
        ("gpu.tile_width_px", p.gpu.tile_width_px),
        ("gpu.tile_height_px", p.gpu.tile_height_px),
    ] {
        if px == 0 {
            return Err(invalid(key, "tile size must be at least 1x1"));
        }
    }
    if p.render_pass.max_color_attachments == 0 {
        return Err(invalid(
            "render_pass.max_color_attachments",
            "must be at least 1",
        ));
    }
    for u in MemoryUse::ALL {
        if p.memory.rule(u).prefer.is_empty() {
            return Err(invalid(
                &format!("memory.{}.prefer", u.name()),
                "needs at least one tier",
            ));
        }
    }
    for (i, rule) in p.state_rules.iter().enumerate() {
        if rule.source.trim().is_empty() {
            return Err(invalid(
                &format!("state_rules[{i}].source"),
                "name the rule's source (a key of docs/PROFILES.md) or say `unsourced`",
            ));
        }
    }
    let m = &p.matching;
    if m.vendor_default && m.vendor_ids.is_empty() {
        return Err(invalid(
            "match.vendor_default",
            "is the default for the vendors in match.vendor_ids, which is empty",
        ));
    }
    if m.device_names.is_empty() && !m.vendor_default && m.device_types.is_empty() {
        return Err(invalid(
            "match",
            "claims no device: give device_names, vendor_default or device_types",
        ));
    }
    Ok(())
}
