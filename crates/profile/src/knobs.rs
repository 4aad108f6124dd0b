//! Knobs: every choice that trades speed for accuracy or memory, by name, with its domain.
//!
//! A profile's `[knobs]` table sets what that GPU family ships with; a run overrides any of them
//! (`tilegraph … --set oq_group=16`), and `tilegraph tune` writes the winners back as a profile.
//! This module is the registry — names, domains, defaults, which runs a knob means something to —
//! and validation. What a value *does* is `tilegraph-passes`' business (`knobs::Resolved`); a test
//! there parses every value of every domain, so the two cannot drift apart.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

/// What a knob may be set to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Domain {
    /// One of these names.
    Choice(&'static [&'static str]),
    /// One of these integers.
    Integers(&'static [u32]),
}

impl Domain {
    /// Whether `value` (as written on the command line or in TOML) is in the domain; the value
    /// normalized (`"16"` and `16` are the same integer).
    pub fn check(&self, value: &KnobValue) -> Option<KnobValue> {
        match (self, value) {
            (Domain::Choice(names), KnobValue::Name(n)) => names
                .contains(&n.as_str())
                .then(|| KnobValue::Name(n.clone())),
            (Domain::Integers(ints), KnobValue::Integer(i)) => {
                ints.contains(i).then_some(KnobValue::Integer(*i))
            }
            (Domain::Integers(ints), KnobValue::Name(n)) => n
                .parse::<u32>()
                .ok()
                .filter(|i| ints.contains(i))
                .map(KnobValue::Integer),
            // A number among the names ("1" of 0, 0.5, 1, 2) as the name.
            (Domain::Choice(names), KnobValue::Integer(i)) => {
                let n = i.to_string();
                names.contains(&n.as_str()).then_some(KnobValue::Name(n))
            }
        }
    }

    /// Every value of the domain, in order.
    pub fn values(&self) -> Vec<KnobValue> {
        match self {
            Domain::Choice(names) => names
                .iter()
                .map(|n| KnobValue::Name(n.to_string()))
                .collect(),
            Domain::Integers(ints) => ints.iter().map(|&i| KnobValue::Integer(i)).collect(),
        }
    }
}

impl fmt::Display for Domain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Domain::Choice(names) => f.write_str(&names.join(", ")),
            Domain::Integers(ints) => {
                let v: Vec<String> = ints.iter().map(u32::to_string).collect();
                f.write_str(&v.join(", "))
            }
        }
    }
}

/// When a knob means something; elsewhere setting it is an error, not silently ignored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applies {
    Always,
    /// Only with these culling techniques.
    WithCulling(&'static [&'static str]),
    /// Only for scenes with alpha-tested geometry.
    AlphaTestedScene,
    /// Only with these shading techniques.
    WithShading(&'static [&'static str]),
}

/// One knob.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KnobSpec {
    pub name: &'static str,
    pub domain: Domain,
    /// The value when neither the profile nor the run sets it.
    pub default: DefaultValue,
    pub applies: Applies,
    /// What it trades, in one line.
    pub help: &'static str,
}

/// A knob's built-in default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DefaultValue {
    Name(&'static str),
    Integer(u32),
}

impl From<DefaultValue> for KnobValue {
    fn from(d: DefaultValue) -> Self {
        match d {
            DefaultValue::Name(n) => KnobValue::Name(n.to_string()),
            DefaultValue::Integer(i) => KnobValue::Integer(i),
        }
    }
}

/// The culling techniques, as the `culling` knob names them (`auto` picks one per scene).
pub const CULLING_NAMES: &[&str] = &[
    "auto",
    "none",
    "frustum",
    "hiz",
    "hiz-2phase",
    "oq",
    "oq-conditional",
    "raster-occlusion",
    "reproject",
    "frustum-clusters",
    "hiz-2phase-clusters",
    "software-occlusion",
    "pvs",
];

/// Every knob. Order is the order `tilegraph` prints and `tune` sweeps them.
pub const KNOBS: &[KnobSpec] = &[
    KnobSpec {
        name: "culling",
        domain: Domain::Choice(CULLING_NAMES),
        default: DefaultValue::Name("auto"),
        applies: Applies::Always,
        help: "what decides which instances are drawn: auto picks from what the scene holds",
    },
    KnobSpec {
        name: "shading",
        domain: Domain::Choice(&["forward", "prepass", "visbuf", "deferred-texturing"]),
        default: DefaultValue::Name("forward"),
        applies: Applies::Always,
        help: "forward (pre-pass as the profile says), forward with a forced depth pre-pass, visibility buffer, or deferred texturing (G-buffer of material, normal, UV and derivatives, then one shading pass)",
    },
    KnobSpec {
        name: "opaque_sort",
        domain: Domain::Choice(&["profile", "front-to-back", "back-to-front", "by-state", "none"]),
        default: DefaultValue::Name("profile"),
        applies: Applies::Always,
        help: "opaque draw order: front to back helps early-Z and LRZ, by state helps HSR GPUs",
    },
    KnobSpec {
        name: "depth_format",
        domain: Domain::Choice(&["d32", "d16"]),
        default: DefaultValue::Name("d32"),
        applies: Applies::Always,
        help: "depth buffer format: D16 halves depth bandwidth (Adreno's guide prefers it where precision allows), D32 keeps float precision",
    },
    KnobSpec {
        name: "depth_prepass",
        domain: Domain::Choice(&["profile", "on", "off"]),
        default: DefaultValue::Name("profile"),
        applies: Applies::Always,
        help: "a depth pre-pass before forward shading: fewer shaded fragments for a second vertex pass (off on HSR GPUs)",
    },
    KnobSpec {
        name: "alpha_prepass",
        domain: Domain::Choice(&["profile", "on", "off"]),
        default: DefaultValue::Name("profile"),
        applies: Applies::AlphaTestedScene,
        help: "alpha-tested geometry's own depth pre-pass: discard once, colour tests EQUAL",
    },
    KnobSpec {
        name: "hiz_npot",
        domain: Domain::Choice(&["edge-aware", "pad-to-pow2"]),
        default: DefaultValue::Name("edge-aware"),
        applies: Applies::WithCulling(&["hiz", "hiz-2phase", "hiz-2phase-clusters", "reproject"]),
        help: "HiZ pyramid of a non-power-of-two target: edge-aware reduction or a padded pyramid",
    },
    KnobSpec {
        name: "hiz_resolution",
        domain: Domain::Choice(&["full", "half", "quarter"]),
        default: DefaultValue::Name("full"),
        applies: Applies::WithCulling(&["hiz", "hiz-2phase", "hiz-2phase-clusters"]),
        help: "finest HiZ level at the depth's full, half or quarter resolution: 1/4 or 1/16 of level 0's memory and build writes, small objects tested against coarser texels (more drawn)",
    },
    KnobSpec {
        name: "cull_bounds",
        domain: Domain::Choice(&["aabb", "sphere"]),
        default: DefaultValue::Name("aabb"),
        applies: Applies::WithCulling(&[
            "frustum",
            "hiz",
            "hiz-2phase",
            "reproject",
            "frustum-clusters",
            "hiz-2phase-clusters",
        ]),
        help: "what GPU culling tests: the world AABB (8 projected corners) or the bounding sphere (fewer instructions; looser for boxes, tighter for rotated thin objects)",
    },
    KnobSpec {
        name: "cluster_early",
        domain: Domain::Choice(&["instances", "clusters"]),
        default: DefaultValue::Name("instances"),
        applies: Applies::WithCulling(&["hiz-2phase-clusters"]),
        help: "what hiz-2phase-clusters' early phase draws of an instance visible last frame: the whole instance (hiz-2phase's early phase: never more colour triangles than hiz-2phase), or its clusters in the frustum, not back-facing and not found occluded last frame (less early work where large instances are mostly hidden; can draw more after a turn or a cut)",
    },
    KnobSpec {
        name: "cluster_gap",
        domain: Domain::Integers(&[0, 1, 2, 4, 8]),
        default: DefaultValue::Integer(0),
        applies: Applies::WithCulling(&["frustum-clusters", "hiz-2phase-clusters"]),
        help: "the longest gap of culled clusters (within a chunk of 64) one indirect command draws through: fewer commands for a few more triangles (0 draws exactly the surviving clusters)",
    },
    KnobSpec {
        name: "triangle_culling",
        domain: Domain::Choice(&["off", "on"]),
        default: DefaultValue::Name("off"),
        applies: Applies::WithCulling(&["frustum-clusters", "hiz-2phase-clusters"]),
        help: "per-triangle culling after the clusters (seed 000, Wihlidal 2016): every surviving cluster's triangles tested (clip volume, back-facing, zero-area, no sample covered, the late phase's pyramid) and packed by a prefix sum into a reserved index-buffer tail; exact, three dispatches per phase, for fewer triangles set up and rasterized",
    },
    KnobSpec {
        name: "lod_error_px",
        domain: Domain::Choice(&["0", "0.5", "1", "2", "4", "8"]),
        default: DefaultValue::Name("0"),
        applies: Applies::WithCulling(&["frustum", "hiz", "hiz-2phase", "reproject"]),
        help: "level of detail by screen error: each instance drawn with the coarsest of its mesh's simplified levels (meshoptimizer, kept with the clusters) whose error projects to at most this many pixels; fewer triangles for image error (cull-check reports it against the full-detail frame; 0: full detail)",
    },
    KnobSpec {
        name: "lod_hysteresis",
        domain: Domain::Choice(&["0", "0.1", "0.2", "0.3", "0.5"]),
        default: DefaultValue::Name("0.2"),
        applies: Applies::WithCulling(&["frustum", "hiz", "hiz-2phase", "reproject"]),
        help: "level of detail's switching band: an instance moves to a coarser level than last frame's only once that level's error projects to at most lod_error_px * (1 - this), back to a finer one as soon as its level's exceeds lod_error_px; no flipping between levels near a threshold, the bound kept (0: no band)",
    },
    KnobSpec {
        name: "oq_group",
        domain: Domain::Integers(&[1, 2, 4, 8, 16, 32, 64]),
        default: DefaultValue::Integer(16),
        applies: Applies::WithCulling(&["oq", "oq-conditional"]),
        help: "instances per occlusion query (a union box): fewer queries, more drawn",
    },
    KnobSpec {
        name: "occlusion_recheck",
        domain: Domain::Integers(&[1, 2, 4, 8, 16, 32]),
        default: DefaultValue::Integer(8),
        applies: Applies::WithCulling(&["oq", "oq-conditional", "raster-occlusion"]),
        help: "frames between tests of what was visible: a box found visible is drawn untested until its turn comes (1 in N frames); hidden boxes are tested every frame (1: every box, every frame)",
    },
    KnobSpec {
        name: "raster_occlusion_scale",
        domain: Domain::Integers(&[1, 2, 4]),
        default: DefaultValue::Integer(1),
        applies: Applies::WithCulling(&["raster-occlusion"]),
        help: "raster occlusion against a conservative 1/N-resolution depth: cheaper, more drawn",
    },
    KnobSpec {
        name: "software_resolution",
        domain: Domain::Choice(&["128x64", "256x128", "512x256"]),
        default: DefaultValue::Name("256x128"),
        applies: Applies::WithCulling(&["software-occlusion"]),
        help: "software occlusion's depth buffer in tiles across x down (coverage stays exact at the frame's pixels): finer tiles hide more, cost more CPU",
    },
    KnobSpec {
        name: "software_threads",
        domain: Domain::Integers(&[1, 2, 4, 8]),
        default: DefaultValue::Integer(1),
        applies: Applies::WithCulling(&["software-occlusion"]),
        help: "threads rasterizing software occlusion's occluders (bands of tiles; the result does not depend on it)",
    },
    KnobSpec {
        name: "software_occluder_triangles",
        domain: Domain::Integers(&[2048, 4096, 16384, 65536]),
        default: DefaultValue::Integer(16384),
        applies: Applies::WithCulling(&["software-occlusion"]),
        help: "software occlusion's occluder triangles per frame at most (the largest opaque instances, nearest first)",
    },
    KnobSpec {
        name: "pvs_dilation",
        domain: Domain::Integers(&[0, 1, 2]),
        default: DefaultValue::Integer(1),
        applies: Applies::WithCulling(&["pvs"]),
        help: "cells around the camera's whose precomputed visible sets are drawn too: fewer misses between baked viewpoints, more drawn",
    },
    KnobSpec {
        name: "visbuf_resolve",
        domain: Domain::Choice(&["uber", "per-material", "classified"]),
        default: DefaultValue::Name("uber"),
        applies: Applies::WithShading(&["visbuf"]),
        help: "the visibility buffer's resolve: one shader for every material, one full-screen pass per material discarding the others' pixels, or per material over the screen tiles classification found it in (the ids leave tile memory)",
    },
    KnobSpec {
        name: "classify_tile",
        domain: Domain::Integers(&[8, 16, 32]),
        default: DefaultValue::Integer(16),
        applies: Applies::WithShading(&["visbuf"]),
        help: "side in pixels of the screen tiles material classification sorts: smaller tiles shade fewer other materials' pixels, cost more classification work and tile quads",
    },
    KnobSpec {
        name: "shadow_cascades",
        domain: Domain::Integers(&[0, 1, 2, 3, 4]),
        default: DefaultValue::Integer(0),
        applies: Applies::Always,
        help: "cascaded shadow maps of the directional light: 0 (none) to 4 cascades in one depth atlas",
    },
    KnobSpec {
        name: "shadow_resolution",
        domain: Domain::Integers(&[256, 512, 1024, 2048]),
        default: DefaultValue::Integer(1024),
        applies: Applies::Always,
        help: "texels on a side of each cascade: sharper shadows for more depth writes and memory",
    },
    KnobSpec {
        name: "shadow_distance",
        domain: Domain::Integers(&[0, 50, 100, 200, 400, 1000]),
        default: DefaultValue::Integer(0),
        applies: Applies::Always,
        help: "metres from the eye that receive shadows (0: the scene's extent): shorter puts the cascades' texels on what is near",
    },
    KnobSpec {
        name: "shadow_pcf",
        domain: Domain::Integers(&[0, 1, 2]),
        default: DefaultValue::Integer(1),
        applies: Applies::Always,
        help: "texels either side of a shadow lookup that its filter weighs: 0 one bilinear compare (2x2 texels), 1 the 3x3 around it (4 taps), 2 the 5x5 (16 taps)",
    },
    KnobSpec {
        name: "shadow_format",
        domain: Domain::Choice(&["profile", "d16", "d32"]),
        default: DefaultValue::Name("profile"),
        applies: Applies::Always,
        help: "the shadow atlas's depth format: D16 halves its bandwidth and tile memory (the default on tilers), D32 keeps float precision",
    },
    KnobSpec {
        name: "shadow_culling",
        domain: Domain::Choice(&["none", "cascade", "receivers", "receivers-hiz"]),
        default: DefaultValue::Name("receivers"),
        applies: Applies::Always,
        help: "which casters each cascade draws: all, those in its box, those whose shadow can reach the camera's view slice, or of those the ones whose shadow falls on something the camera sees (this frame's pyramid: two-phase culling with a pre-pass or the visibility buffer); all exact",
    },
];

/// The knob named `name`.
pub fn spec(name: &str) -> Option<&'static KnobSpec> {
    KNOBS.iter().find(|k| k.name == name)
}

/// A knob's value: a name or an integer (TOML writes `oq_group = 16`, the command line `16`).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(untagged)]
pub enum KnobValue {
    Integer(u32),
    Name(String),
}

impl KnobValue {
    pub fn as_name(&self) -> Option<&str> {
        match self {
            KnobValue::Name(n) => Some(n),
            KnobValue::Integer(_) => None,
        }
    }

    pub fn as_integer(&self) -> Option<u32> {
        match self {
            KnobValue::Integer(i) => Some(*i),
            KnobValue::Name(_) => None,
        }
    }
}

impl fmt::Display for KnobValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KnobValue::Integer(i) => write!(f, "{i}"),
            KnobValue::Name(n) => f.write_str(n),
        }
    }
}

/// Why a knob setting was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum KnobError {
    #[error("unknown knob {name:?} (knobs: {known})")]
    Unknown { name: String, known: String },
    #[error("knob {name}: {value:?} is outside its domain ({domain})")]
    OutOfDomain {
        name: String,
        value: String,
        domain: String,
    },
    #[error("`--set {0}` is not of the form knob=value")]
    Syntax(String),
}

/// Knob values by name, each checked against its domain: a profile's `[knobs]` table, or a
/// run's `--set` overrides.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(
    try_from = "BTreeMap<String, KnobValue>",
    into = "BTreeMap<String, KnobValue>"
)]
pub struct KnobSettings(BTreeMap<String, KnobValue>);

impl KnobSettings {
    /// Sets `name` to `value` after checking both.
    pub fn set(&mut self, name: &str, value: KnobValue) -> Result<(), KnobError> {
        let spec = spec(name).ok_or_else(|| KnobError::Unknown {
            name: name.to_string(),
            known: KNOBS.iter().map(|k| k.name).collect::<Vec<_>>().join(", "),
        })?;
        let v = spec
            .domain
            .check(&value)
            .ok_or_else(|| KnobError::OutOfDomain {
                name: name.to_string(),
                value: value.to_string(),
                domain: spec.domain.to_string(),
            })?;
        self.0.insert(name.to_string(), v);
        Ok(())
    }

    /// Parses `knob=value` (as `--set` takes it) and sets it.
    pub fn set_assignment(&mut self, assignment: &str) -> Result<(), KnobError> {
        let (name, value) = assignment
            .split_once('=')
            .filter(|(n, v)| !n.trim().is_empty() && !v.trim().is_empty())
            .ok_or_else(|| KnobError::Syntax(assignment.to_string()))?;
        self.set(name.trim(), KnobValue::Name(value.trim().to_string()))
    }

    pub fn get(&self, name: &str) -> Option<&KnobValue> {
        self.0.get(name)
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, &KnobValue)> {
        self.0.iter().map(|(k, v)| (k.as_str(), v))
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// `self` with `over`'s values taking precedence.
    pub fn overridden_by(&self, over: &KnobSettings) -> KnobSettings {
        let mut out = self.clone();
        out.0
            .extend(over.0.iter().map(|(k, v)| (k.clone(), v.clone())));
        out
    }
}

impl TryFrom<BTreeMap<String, KnobValue>> for KnobSettings {
    type Error = KnobError;

    fn try_from(map: BTreeMap<String, KnobValue>) -> Result<Self, KnobError> {
        let mut s = KnobSettings::default();
        for (k, v) in map {
            s.set(&k, v)?;
        }
        Ok(s)
    }
}

impl From<KnobSettings> for BTreeMap<String, KnobValue> {
    fn from(s: KnobSettings) -> Self {
        s.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_default_is_in_its_domain_and_names_are_unique() {
        for k in KNOBS {
            assert!(
                k.domain.check(&k.default.into()).is_some(),
                "{}: default outside domain",
                k.name
            );
            assert_eq!(KNOBS.iter().filter(|o| o.name == k.name).count(), 1);
        }
    }

    #[test]
    fn settings_refuse_unknown_knobs_and_values_outside_the_domain() {
        let mut s = KnobSettings::default();
        assert!(matches!(
            s.set_assignment("oq_groop=4"),
            Err(KnobError::Unknown { name, .. }) if name == "oq_groop"
        ));
        let e = s.set_assignment("raster_occlusion_scale=3").unwrap_err();
        assert_eq!(
            e.to_string(),
            "knob raster_occlusion_scale: \"3\" is outside its domain (1, 2, 4)"
        );
        assert!(matches!(
            s.set_assignment("oq_group"),
            Err(KnobError::Syntax(_))
        ));
        assert!(matches!(
            s.set_assignment("culling=hiz-3phase"),
            Err(KnobError::OutOfDomain { .. })
        ));
        s.set_assignment("oq_group=16").unwrap();
        assert_eq!(s.get("oq_group"), Some(&KnobValue::Integer(16)));
        s.set_assignment(" culling = hiz-2phase ").unwrap();
        assert_eq!(
            s.get("culling"),
            Some(&KnobValue::Name("hiz-2phase".into()))
        );
    }

    #[test]
    fn toml_tables_load_through_the_same_checks() {
        let ok: KnobSettings =
            toml::from_str("oq_group = 16\nculling = \"oq-conditional\"").unwrap();
        assert_eq!(ok.get("oq_group"), Some(&KnobValue::Integer(16)));
        let bad = toml::from_str::<KnobSettings>("oq_group = 3").unwrap_err();
        assert!(bad.to_string().contains("outside its domain"), "{bad}");
        let over = KnobSettings::try_from(BTreeMap::from([(
            "oq_group".to_string(),
            KnobValue::Integer(4),
        )]))
        .unwrap();
        assert_eq!(
            ok.overridden_by(&over).get("oq_group"),
            Some(&KnobValue::Integer(4))
        );
        assert_eq!(
            ok.overridden_by(&over).get("culling"),
            Some(&KnobValue::Name("oq-conditional".into()))
        );
    }
}
