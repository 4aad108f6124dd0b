//! Frame setup: from what the scene holds and what the profile says, which passes this frame
//! has — and, for every pass left out, why. DESIGN.md: "a pass such as the alpha-tested pre-pass
//! exists only when the scene has something for it to do".

use serde::Serialize;
use tilegraph_profile::{DepthPrepass, Profile};
use tilegraph_scene::Scene;

/// How the frame decides what gets shaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Technique {
    /// Forward colour passes only; the depth pre-pass follows the profile.
    Forward,
    /// Forward with a depth pre-pass, whatever the profile says (forced).
    Prepass,
    /// Visibility buffer: id pass, then resolve.
    Visbuf,
    /// Deferred texturing (seed 000): a G-buffer of material, packed normal, UV and UV
    /// derivatives (128 bits beside the depth, on chip on tilers), then one full-screen pass
    /// that samples the textures and shades each pixel once.
    DeferredTexturing,
}

impl Technique {
    pub fn parse(s: &str) -> Option<Technique> {
        match s {
            "forward" => Some(Technique::Forward),
            "prepass" => Some(Technique::Prepass),
            "visbuf" => Some(Technique::Visbuf),
            "deferred-texturing" => Some(Technique::DeferredTexturing),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Technique::Forward => "forward",
            Technique::Prepass => "prepass",
            Technique::Visbuf => "visbuf",
            Technique::DeferredTexturing => "deferred-texturing",
        }
    }

    /// Whether the frame shades in screen space after its geometry passes (an id or G-buffer
    /// pass, then a full-screen resolve): no depth pre-pass, no forward opaque colour.
    pub fn screen_space(self) -> bool {
        matches!(self, Technique::Visbuf | Technique::DeferredTexturing)
    }
}

/// How the visibility buffer's resolve covers the scene's materials (knob `visbuf_resolve`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum VisbufResolve {
    /// One full-screen pass shading every material (one shader; tilers keep it a subpass of
    /// the id pass, the ids never leaving tile memory).
    Uber,
    /// One full-screen pass per material, each discarding the other materials' pixels: what
    /// classification is measured against.
    PerMaterial,
    /// A compute pass sorts the screen's tiles by the materials they show; each material's
    /// resolve draws its own tiles only (indirect). The ids are stored for it.
    Classified,
}

impl VisbufResolve {
    pub fn parse(s: &str) -> Option<VisbufResolve> {
        match s {
            "uber" => Some(VisbufResolve::Uber),
            "per-material" => Some(VisbufResolve::PerMaterial),
            "classified" => Some(VisbufResolve::Classified),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            VisbufResolve::Uber => "uber",
            VisbufResolve::PerMaterial => "per-material",
            VisbufResolve::Classified => "classified",
        }
    }
}

/// Which culling a frame runs before drawing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Culling {
    /// Everything is drawn (the CPU draw lists).
    None,
    /// GPU frustum culling.
    Frustum,
    /// Frustum + HiZ against the previous frame's pyramid with the previous matrices: cheap,
    /// but wrong for a frame after a cut or a fast turn (false negatives, measured).
    Hiz,
    /// Two-phase occlusion culling: last frame's visible set, pyramid from that depth, then the
    /// rest; no dependence on the previous camera.
    HizTwoPhase,
    /// Hardware occlusion queries on bounding boxes against this frame's depth, read back the
    /// next frame without waiting: the drawn set lags one frame (false negatives when objects
    /// appear, measured).
    Oq,
    /// The same queries in the same frame, against a depth pre-pass: results copied to a buffer
    /// on the GPU, each instance drawn under `VK_EXT_conditional_rendering` on its result.
    /// Conservative: no false negatives, the unculled image.
    OqConditional,
    /// Bounding boxes rasterized against the depth pre-pass with early fragment tests; each
    /// surviving fragment flags its instance, the culling shader turns flags into indirect
    /// draws. Conservative: no false negatives, the unculled image.
    RasterOcclusion,
    /// Frustum culling of instances, then of their clusters (box against the frustum,
    /// back-facing normal cone): one indirect command per run of surviving clusters. Needs the
    /// scene's clusters (`Scene::attach_clusters`).
    FrustumClusters,
    /// Frustum + HiZ against last frame's depth reprojected into this frame's view (seed 000):
    /// one phase, this frame's matrices; not conservative (point samples, disocclusion),
    /// measured.
    Reproject,
    /// Two-phase occlusion culling of instances and of their clusters: last frame's visible
    /// clusters first, then every cluster of a visible instance against the pyramid of that
    /// depth. Needs the scene's clusters.
    HizTwoPhaseClusters,
    /// Software occlusion (seed 002): the frame's large opaque instances rasterized on the CPU
    /// into a low-resolution depth buffer, every instance in the frustum tested against it, the
    /// CPU lists drawn. Same frame, no GPU work; conservative.
    SoftwareOcclusion,
    /// A precomputed visible set (`RenderOptions::pvs`, baked by `tilegraph pvs`): the camera
    /// cell's instances (with `pvs_dilation`, its neighbours' too) that the frustum holds, on
    /// the CPU lists. Exact only at its baked viewpoints: misses measured, not conservative.
    Pvs,
}

impl Culling {
    /// Every culling technique, in the order the docs list them.
    pub const ALL: [Culling; 12] = [
        Culling::None,
        Culling::Frustum,
        Culling::Hiz,
        Culling::HizTwoPhase,
        Culling::Oq,
        Culling::OqConditional,
        Culling::RasterOcclusion,
        Culling::Reproject,
        Culling::FrustumClusters,
        Culling::HizTwoPhaseClusters,
        Culling::SoftwareOcclusion,
        Culling::Pvs,
    ];

    /// What the tools run when no technique is named, and the Android sample cycles through:
    /// [`Culling::ALL`] but the cluster techniques (which need the scene's clusters) and
    /// `reproject` (a measurement of seed 000's idea, run by name).
    pub const STANDARD: [Culling; 8] = [
        Culling::None,
        Culling::Frustum,
        Culling::Hiz,
        Culling::HizTwoPhase,
        Culling::Oq,
        Culling::OqConditional,
        Culling::RasterOcclusion,
        Culling::SoftwareOcclusion,
    ];

    /// The instance-level technique a cluster technique starts from (itself for the others):
    /// its passes, phases and buffers are that technique's, plus the cluster stage.
    pub fn base(self) -> Culling {
        match self {
            Culling::FrustumClusters => Culling::Frustum,
            Culling::HizTwoPhaseClusters => Culling::HizTwoPhase,
            c => c,
        }
    }

    /// Whether the technique culls clusters after instances.
    pub fn clusters(self) -> bool {
        self != self.base()
    }

    pub fn parse(s: &str) -> Option<Culling> {
        match s {
            "none" => Some(Culling::None),
            "frustum" => Some(Culling::Frustum),
            "hiz" => Some(Culling::Hiz),
            "hiz-2phase" => Some(Culling::HizTwoPhase),
            "reproject" => Some(Culling::Reproject),
            "oq" => Some(Culling::Oq),
            "oq-conditional" => Some(Culling::OqConditional),
            "raster-occlusion" => Some(Culling::RasterOcclusion),
            "frustum-clusters" => Some(Culling::FrustumClusters),
            "hiz-2phase-clusters" => Some(Culling::HizTwoPhaseClusters),
            "software-occlusion" => Some(Culling::SoftwareOcclusion),
            "pvs" => Some(Culling::Pvs),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Culling::None => "none",
            Culling::Frustum => "frustum",
            Culling::Hiz => "hiz",
            Culling::HizTwoPhase => "hiz-2phase",
            Culling::Reproject => "reproject",
            Culling::Oq => "oq",
            Culling::OqConditional => "oq-conditional",
            Culling::RasterOcclusion => "raster-occlusion",
            Culling::FrustumClusters => "frustum-clusters",
            Culling::HizTwoPhaseClusters => "hiz-2phase-clusters",
            Culling::SoftwareOcclusion => "software-occlusion",
            Culling::Pvs => "pvs",
        }
    }

    /// Whether the technique draws opaque and alpha-tested geometry through the culling
    /// shader's indirect lists (the others select the CPU draw lists).
    pub fn uses_gpu_lists(self) -> bool {
        matches!(
            self.base(),
            Culling::Frustum
                | Culling::Hiz
                | Culling::HizTwoPhase
                | Culling::RasterOcclusion
                | Culling::Reproject
        )
    }

    /// Whether the CPU decides which opaque and alpha-tested instances are drawn (the frustum's
    /// instances, narrowed by queries, software occlusion or a precomputed visible set; raster
    /// occlusion's pre-pass).
    pub fn cpu_lists(self) -> bool {
        self.uses_queries()
            || matches!(
                self,
                Culling::RasterOcclusion | Culling::SoftwareOcclusion | Culling::Pvs
            )
    }

    /// Whether the technique issues hardware occlusion queries.
    pub fn uses_queries(self) -> bool {
        matches!(self, Culling::Oq | Culling::OqConditional)
    }

    /// Whether colour draws are predicated on this frame's query results on the GPU.
    pub fn conditional(self) -> bool {
        self == Culling::OqConditional
    }

    /// Whether the technique needs a depth pre-pass whatever the profile says.
    pub fn needs_prepass(self) -> bool {
        matches!(
            self.base(),
            Culling::HizTwoPhase | Culling::OqConditional | Culling::RasterOcclusion
        )
    }

    /// Whether the technique never culls a visible instance by construction (`tests/e2e`
    /// holds each to FN 0 and equal images); the others trade misses for speed (single-phase
    /// HiZ after a cut, next-frame queries as objects appear, reprojected depth).
    pub fn conservative(self) -> bool {
        !matches!(
            self,
            Culling::Hiz | Culling::Oq | Culling::Reproject | Culling::Pvs
        )
    }

    /// Why this culling cannot run with `technique`, or `None` when it can.
    pub fn unsupported_with(self, technique: Technique) -> Option<&'static str> {
        if !technique.screen_space() {
            return None;
        }
        if matches!(self, Culling::OqConditional | Culling::RasterOcclusion) {
            // Both test boxes against a depth pre-pass before colour; the visibility buffer
            // and the G-buffer have no pre-pass to test against.
            Some("it needs a depth pre-pass before colour")
        } else {
            None
        }
    }

    pub fn uses_pyramid(self) -> bool {
        matches!(
            self.base(),
            Culling::Hiz | Culling::HizTwoPhase | Culling::Reproject
        )
    }
}

/// Every pass the frame setup knows about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PassKind {
    DepthPrepassOpaque,
    DepthPrepassAlpha,
    Opaque,
    AlphaTested,
    Transparent,
    VisbufWrite,
    VisbufResolve,
    GbufferWrite,
    GbufferResolve,
}

impl PassKind {
    pub fn name(self) -> &'static str {
        match self {
            PassKind::DepthPrepassOpaque => "depth-prepass",
            PassKind::DepthPrepassAlpha => "depth-prepass-alpha",
            PassKind::Opaque => "opaque",
            PassKind::AlphaTested => "alpha-tested",
            PassKind::Transparent => "transparent",
            PassKind::VisbufWrite => "visbuf-write",
            PassKind::VisbufResolve => "visbuf-resolve",
            PassKind::GbufferWrite => "gbuffer",
            PassKind::GbufferResolve => "gbuffer-resolve",
        }
    }

    /// The screen-space technique whose pass this is (`None`: a forward or pre-pass pass).
    fn screen_space_technique(self) -> Option<Technique> {
        match self {
            PassKind::VisbufWrite | PassKind::VisbufResolve => Some(Technique::Visbuf),
            PassKind::GbufferWrite | PassKind::GbufferResolve => Some(Technique::DeferredTexturing),
            _ => None,
        }
    }
}

/// One decision of the frame setup.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct PassDecision {
    pub pass: PassKind,
    pub included: bool,
    pub reason: String,
}

/// What the scene holds, by material class (instances, not materials: a material nobody uses
/// needs no pass).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SceneContent {
    pub opaque: usize,
    pub alpha_tested: usize,
    pub blended: usize,
}

impl SceneContent {
    /// The drawn instances of `scene` per class (kept by the scene: no walk over instances).
    pub fn of(scene: &Scene) -> Self {
        let c = scene.drawn_by_class();
        SceneContent {
            opaque: c.opaque as usize,
            alpha_tested: c.alpha_tested as usize,
            blended: c.blended as usize,
        }
    }

    /// Which classes the scene draws at all: what the frame's passes depend on.
    pub fn presence(&self) -> [bool; 3] {
        [self.opaque > 0, self.alpha_tested > 0, self.blended > 0]
    }
}

/// The frame setup's verdict: the passes in the order the profile recommends, with reasons.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FrameSetup {
    pub technique: Technique,
    pub decisions: Vec<PassDecision>,
}

impl FrameSetup {
    pub fn includes(&self, pass: PassKind) -> bool {
        self.decisions.iter().any(|d| d.pass == pass && d.included)
    }

    pub fn included(&self) -> impl Iterator<Item = PassKind> + '_ {
        self.decisions.iter().filter(|d| d.included).map(|d| d.pass)
    }

    /// Adjusts the setup for a culling technique: two-phase occlusion culling draws geometry in
    /// two phases with a pyramid build between them, so the depth pre-pass is left out (it
    /// would need two phases of its own to stay exact).
    pub fn with_culling(mut self, culling: Culling) -> FrameSetup {
        if !culling.needs_prepass() || self.technique.screen_space() {
            return self;
        }
        // Two-phase culling draws depth twice (last frame's visible set, then the newly visible)
        // and colour once, EQUAL, in the unculled draw order: the pre-pass is part of the
        // technique, whatever the profile says.
        let opaque = self.includes(PassKind::Opaque);
        let alpha = self.includes(PassKind::AlphaTested);
        for d in &mut self.decisions {
            let wanted = match d.pass {
                PassKind::DepthPrepassOpaque => opaque,
                PassKind::DepthPrepassAlpha => alpha,
                _ => continue,
            };
            if wanted && !d.included {
                d.included = true;
                d.reason = match culling {
                    Culling::OqConditional => "conditional occlusion queries: depth of last frame's visible set (predicated on last frame's results), boxes tested against it, colour predicated on this frame's results",
                    Culling::RasterOcclusion => "raster occlusion: boxes rasterized against the pre-pass depth flag the instances the colour passes draw",
                    _ => "two-phase occlusion culling: depth of last frame's visible set, the pyramid, then the newly visible; colour once",
                }
                .into();
            }
        }
        self
    }

    /// Whether a depth pre-pass writes the depth of instances of material `class` (0 opaque,
    /// 1 alpha-tested): their colour pass then tests EQUAL without writing depth. Per class: a
    /// profile may pre-pass opaque geometry and leave alpha-tested geometry to its colour pass.
    pub fn prepassed(&self, class: u32) -> bool {
        match class {
            0 => self.includes(PassKind::DepthPrepassOpaque),
            1 => self.includes(PassKind::DepthPrepassAlpha),
            _ => false,
        }
    }

    pub fn has_prepass(&self) -> bool {
        self.includes(PassKind::DepthPrepassOpaque) || self.includes(PassKind::DepthPrepassAlpha)
    }
}

/// The pre-pass knobs of a renderer (`depth_prepass`, `alpha_prepass`): `None` follows the
/// profile.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PrepassKnobs {
    pub depth: Option<bool>,
    pub alpha: Option<bool>,
}

/// [`decide`] for a renderer: the pre-pass knobs over the profile's choices — the frame setup
/// saying when a knob, not the profile, decided — then the culling's own needs
/// ([`FrameSetup::with_culling`]).
pub fn decide_for(
    content: SceneContent,
    base: &Profile,
    technique: Technique,
    culling: Culling,
    knobs: PrepassKnobs,
) -> FrameSetup {
    let mut profile = std::borrow::Cow::Borrowed(base);
    if let Some(a) = knobs.alpha {
        profile.to_mut().passes.alpha_tested_prepass = a;
    }
    if let Some(d) = knobs.depth {
        profile.to_mut().passes.depth_prepass = if d {
            tilegraph_profile::DepthPrepass::Recommended
        } else {
            tilegraph_profile::DepthPrepass::NotNeeded
        };
    }
    let mut setup = decide(content, &profile, technique);
    // Say when a knob, not the profile, decided the pre-pass.
    let own = &base.passes;
    for (knob, value, profile_says, pass) in [
        (
            "depth_prepass",
            knobs.depth,
            own.depth_prepass == tilegraph_profile::DepthPrepass::Recommended,
            PassKind::DepthPrepassOpaque,
        ),
        (
            "alpha_prepass",
            knobs.alpha,
            own.alpha_tested_prepass,
            PassKind::DepthPrepassAlpha,
        ),
    ] {
        let Some(v) = value.filter(|v| *v != profile_says) else {
            continue;
        };
        // Where the scene has nothing for the pass, that stays the reason.
        for d in setup
            .decisions
            .iter_mut()
            .filter(|d| d.pass == pass && d.included == v)
        {
            d.reason = format!(
                "knob {knob} = {}, over profile {}'s choice",
                if v { "on" } else { "off" },
                base.name
            );
        }
    }
    setup.with_culling(culling)
}

/// Decides the passes of a frame. Pure: the same scene content, profile and technique give the
/// same setup.
pub fn decide(content: SceneContent, profile: &Profile, technique: Technique) -> FrameSetup {
    let mut d = Vec::new();
    let mut say = |pass, included, reason: String| {
        d.push(PassDecision {
            pass,
            included,
            reason,
        })
    };
    let any_depth_geometry = content.opaque + content.alpha_tested > 0;
    match technique {
        Technique::Forward | Technique::Prepass => {
            let prepass_wanted = match (technique, profile.passes.depth_prepass) {
                (Technique::Prepass, _) => Some("forced by --technique prepass".to_string()),
                (_, DepthPrepass::Recommended) => Some(format!(
                    "profile {} recommends a depth pre-pass",
                    profile.name
                )),
                (_, DepthPrepass::NotNeeded) => None,
            };
            match (&prepass_wanted, content.opaque) {
                (Some(why), n) if n > 0 => say(PassKind::DepthPrepassOpaque, true, format!("{why}; {n} opaque instances")),
                (Some(_), _) => say(PassKind::DepthPrepassOpaque, false, "no opaque instances".into()),
                (None, _) => say(
                    PassKind::DepthPrepassOpaque,
                    false,
                    format!("profile {} removes hidden surfaces in hardware ({:?}): a pre-pass only adds vertex work", profile.name, profile.gpu.hidden_surface_removal),
                ),
            }
            let alpha_prepass = prepass_wanted.is_some()
                && (profile.passes.alpha_tested_prepass || technique == Technique::Prepass);
            match (alpha_prepass, content.alpha_tested) {
                (true, n) if n > 0 => say(
                    PassKind::DepthPrepassAlpha,
                    true,
                    format!("{n} alpha-tested instances: discard once, in depth only (seed 001)"),
                ),
                (true, _) => say(
                    PassKind::DepthPrepassAlpha,
                    false,
                    "the scene has no alpha-tested instances".into(),
                ),
                (false, 0) => say(
                    PassKind::DepthPrepassAlpha,
                    false,
                    "the scene has no alpha-tested instances".into(),
                ),
                (false, _) => say(
                    PassKind::DepthPrepassAlpha,
                    false,
                    "no depth pre-pass on this profile".into(),
                ),
            }
            if content.opaque > 0 {
                say(
                    PassKind::Opaque,
                    true,
                    format!("{} opaque instances", content.opaque),
                );
            } else {
                say(PassKind::Opaque, false, "no opaque instances".into());
            }
            if content.alpha_tested > 0 {
                say(
                    PassKind::AlphaTested,
                    true,
                    format!("{} alpha-tested instances", content.alpha_tested),
                );
            } else {
                say(
                    PassKind::AlphaTested,
                    false,
                    "the scene has no alpha-tested instances".into(),
                );
            }
        }
        Technique::Visbuf | Technique::DeferredTexturing => {
            for p in [PassKind::DepthPrepassOpaque, PassKind::DepthPrepassAlpha] {
                say(
                    p,
                    false,
                    "the resolve shades each pixel once already".into(),
                );
            }
            for p in [PassKind::Opaque, PassKind::AlphaTested] {
                say(
                    p,
                    false,
                    format!(
                        "opaque and alpha-tested geometry is shaded by the {} resolve",
                        technique.name()
                    ),
                );
            }
        }
    }
    // The screen-space passes: the technique's own, or none.
    let (write, resolve, what) = match technique {
        Technique::DeferredTexturing => (
            PassKind::GbufferWrite,
            PassKind::GbufferResolve,
            "the G-buffer",
        ),
        _ => (PassKind::VisbufWrite, PassKind::VisbufResolve, "the id"),
    };
    for p in [
        PassKind::VisbufWrite,
        PassKind::VisbufResolve,
        PassKind::GbufferWrite,
        PassKind::GbufferResolve,
    ] {
        if p.screen_space_technique() != Some(technique) {
            say(
                p,
                false,
                format!("technique {} does not draw it", technique.name()),
            );
        } else if !any_depth_geometry {
            say(p, false, "no opaque or alpha-tested instances".into());
        } else if p == write {
            let n = content.opaque + content.alpha_tested;
            say(p, true, format!("{n} instances write {what}"));
        } else if p == resolve && profile.is_tiler() {
            say(
                p,
                true,
                format!(
                    "subpass reading {what} as an input attachment: it stays on chip on {}",
                    profile.name
                ),
            );
        } else {
            say(
                p,
                true,
                format!(
                    "full-screen pass sampling {what} ({} is immediate-mode)",
                    profile.name
                ),
            );
        }
    }
    if content.blended > 0 {
        say(
            PassKind::Transparent,
            true,
            format!("{} blended instances, back to front", content.blended),
        );
    } else {
        say(PassKind::Transparent, false, "nothing is blended".into());
    }
    FrameSetup {
        technique,
        decisions: d,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilegraph_profile::ProfileSet;

    fn profile(name: &str) -> Profile {
        ProfileSet::embedded().unwrap().get(name).unwrap().clone()
    }

    const MIXED: SceneContent = SceneContent {
        opaque: 10,
        alpha_tested: 5,
        blended: 2,
    };
    const OPAQUE_ONLY: SceneContent = SceneContent {
        opaque: 10,
        alpha_tested: 0,
        blended: 0,
    };

    /// A profile that pre-passes opaque geometry but not alpha-tested: the alpha-tested colour
    /// pass writes its own depth (an EQUAL test against depth nobody wrote would drop it).
    #[test]
    fn only_the_classes_a_prepass_wrote_test_equal() {
        let mut p = profile("lavapipe");
        p.passes.alpha_tested_prepass = false;
        let s = decide(MIXED, &p, Technique::Forward);
        assert!(s.includes(PassKind::DepthPrepassOpaque));
        assert!(!s.includes(PassKind::DepthPrepassAlpha));
        assert!(s.prepassed(0));
        assert!(!s.prepassed(1));
        assert!(!s.prepassed(2));
        let s = decide(MIXED, &profile("lavapipe"), Technique::Forward);
        assert!(s.prepassed(0) && s.prepassed(1));
    }

    #[test]
    fn powervr_skips_the_prepass_unless_forced() {
        let s = decide(MIXED, &profile("powervr-b"), Technique::Forward);
        assert!(!s.includes(PassKind::DepthPrepassOpaque));
        assert!(!s.includes(PassKind::DepthPrepassAlpha));
        let why = &s
            .decisions
            .iter()
            .find(|d| d.pass == PassKind::DepthPrepassOpaque)
            .unwrap()
            .reason;
        assert!(why.contains("removes hidden surfaces"), "{why}");
        let forced = decide(MIXED, &profile("powervr-b"), Technique::Prepass);
        assert!(
            forced.includes(PassKind::DepthPrepassOpaque)
                && forced.includes(PassKind::DepthPrepassAlpha)
        );
    }

    #[test]
    fn adreno_and_lavapipe_prepass_when_recommended() {
        for p in ["adreno-7xx", "lavapipe"] {
            let s = decide(MIXED, &profile(p), Technique::Forward);
            assert!(s.includes(PassKind::DepthPrepassOpaque), "{p}");
            assert!(s.includes(PassKind::DepthPrepassAlpha), "{p}");
            assert!(s.includes(PassKind::Transparent));
        }
    }

    #[test]
    fn passes_for_absent_content_are_left_out_with_a_reason() {
        let s = decide(OPAQUE_ONLY, &profile("adreno-7xx"), Technique::Forward);
        for p in [
            PassKind::DepthPrepassAlpha,
            PassKind::AlphaTested,
            PassKind::Transparent,
        ] {
            let d = s.decisions.iter().find(|d| d.pass == p).unwrap();
            assert!(!d.included, "{p:?}");
            assert!(!d.reason.is_empty());
        }
    }

    /// Deferred texturing: G-buffer and resolve in place of the pre-pass and colour passes; the
    /// resolve reads the G-buffer as an input attachment on tilers; clusters are fine (no
    /// primitive ids), pre-pass-based cullings are not.
    #[test]
    fn deferred_texturing_replaces_the_colour_passes() {
        let t = Technique::DeferredTexturing;
        assert_eq!(Technique::parse(t.name()), Some(t));
        let s = decide(MIXED, &profile("mali-valhall"), t);
        assert!(s.includes(PassKind::GbufferWrite) && s.includes(PassKind::GbufferResolve));
        assert!(!s.includes(PassKind::VisbufWrite) && !s.includes(PassKind::Opaque));
        assert!(!s.has_prepass() && s.includes(PassKind::Transparent));
        let reason = |s: &FrameSetup| {
            let d = s
                .decisions
                .iter()
                .find(|d| d.pass == PassKind::GbufferResolve);
            d.map(|d| d.reason.clone()).unwrap_or_default()
        };
        assert!(reason(&s).contains("input attachment"), "{}", reason(&s));
        let desktop = decide(MIXED, &profile("desktop-nvidia"), t);
        assert!(
            reason(&desktop).contains("sampling"),
            "{}",
            reason(&desktop)
        );
        let none = SceneContent {
            opaque: 0,
            alpha_tested: 0,
            blended: 3,
        };
        assert!(!decide(none, &profile("mali-valhall"), t).includes(PassKind::GbufferWrite));
        assert_eq!(Culling::HizTwoPhaseClusters.unsupported_with(t), None);
        assert!(Culling::RasterOcclusion.unsupported_with(t).is_some());
        // The visibility buffer's ids count a cluster run's triangles from its first
        // (visbuf.vert's DrawRuns).
        assert_eq!(
            Culling::HizTwoPhaseClusters.unsupported_with(Technique::Visbuf),
            None
        );
        let with = decide(MIXED, &profile("lavapipe"), t).with_culling(Culling::HizTwoPhase);
        assert!(!with.has_prepass());
    }

    #[test]
    fn visbuf_replaces_the_colour_passes() {
        let s = decide(MIXED, &profile("mali-valhall"), Technique::Visbuf);
        assert!(s.includes(PassKind::VisbufWrite) && s.includes(PassKind::VisbufResolve));
        assert!(!s.includes(PassKind::Opaque) && !s.includes(PassKind::DepthPrepassOpaque));
        assert!(s.includes(PassKind::Transparent));
    }
}
