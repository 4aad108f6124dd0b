//! `tilegraph tune`: on the device at hand (or a forced profile), sweep the knobs the profile
//! exposes for one scene, pick the fastest setting (GPU frame time plus the CPU culling the
//! frame waits for: software occlusion's) that meets the accuracy constraint, check it
//! on a camera path it did not see, and write the profile back with the pick as its `[knobs]`,
//! the evidence in its comments.
//!
//! The sweep is in two stages (coordinate descent): every culling (unless `--culling` names
//! them: the standard ones, and the cluster techniques on a scene `auto` would try them on) with
//! its own knobs (`hiz_npot`, `hiz_resolution`, `cull_bounds`, `oq_group`, `occlusion_recheck`,
//! `raster_occlusion_scale`, `software_resolution`, `software_occluder_triangles`,
//! `software_threads`; the cluster techniques' `cluster_early` × `cluster_gap` ×
//! `triangle_culling` as a coordinate
//! of their own, their other knobs at the profile's values) under
//! the profile's shading and draw order; then, with the best of those fixed, every shading ×
//! draw order (× alpha pre-pass where the scene has alpha-tested geometry; × caster culling
//! where the profile has shadows). Both stages' runs are kept in `results.json`, so an
//! interrupted tune resumes, and `report.md` and the plots are written as `bench` writes them.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use tilegraph_passes::cull::Culling;
use tilegraph_profile::knobs::{KnobSettings, KnobValue, KNOBS};
use tilegraph_profile::{ProfileSet, PROFILE_DIR_ENV};
use tilegraph_scene::CameraPath;
use tilegraph_vk::{Context, ContextOptions};

use crate::bench::matrix::{Labels, Matrix, Setting};
use crate::bench::results::{write_atomically, Results, RunRecord, TotalsRecord};
use crate::CliError;

#[derive(clap::Args, Debug, Clone)]
pub struct TuneArgs {
    /// The scene to tune for (a spec, as every command takes).
    #[arg(long)]
    pub scene: String,
    /// The camera path to tune on: a JSON file, or `walk[:SEED]` (at eye height through the
    /// scene, sweeping the view, with cuts); the scene's own when absent.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// Accept settings whose FN / visible over the path is at most this (default: no false
    /// negative on any frame).
    #[arg(long)]
    pub max_fn_rate: Option<f64>,
    #[arg(long, value_parser = crate::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Tune this profile (forced) instead of the device's own.
    #[arg(long)]
    pub profile: Option<String>,
    /// Only these culling techniques (comma-separated; default: every one).
    #[arg(long, value_delimiter = ',')]
    pub culling: Vec<String>,
    /// Frames of each path (default 24).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,
    /// Where results, report, plots and the tuned profile go.
    #[arg(long)]
    pub out: PathBuf,
}

/// One measured setting, as the selection sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub key: String,
    pub label: String,
    pub frame_gpu_ms: f64,
    /// Culling work on the render thread's CPU that the frame waits for (software occlusion's
    /// rasterizer and box tests; 0 for GPU culling).
    pub cpu_culling_ms: f64,
    pub false_negatives: usize,
    pub fn_rate: f64,
    pub fp_rate: f64,
    /// Knobs set differently from the profile's values (fewer wins a tie: the simpler change).
    pub changes: usize,
}

impl Candidate {
    /// What the setting costs a frame: its GPU time and the CPU culling it waits for (the
    /// render thread builds the draw lists before it records).
    pub fn cost_ms(&self) -> f64 {
        self.frame_gpu_ms + self.cpu_culling_ms
    }
}

/// Why no setting could be picked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TuneError {
    #[error("no setting met the accuracy constraint ({constraint}); the best FN reached was {best_fn} (FN rate {best_rate:.4}) by {best}")]
    Infeasible {
        constraint: String,
        best_fn: usize,
        best_rate: f64,
        best: String,
    },
    #[error("nothing was measured (every run failed)")]
    Nothing,
}

/// The constraint in words.
pub fn constraint_text(max_fn_rate: Option<f64>) -> String {
    match max_fn_rate {
        Some(r) => format!("FN rate at most {r}"),
        None => "no false negative on any frame".into(),
    }
}

fn feasible(c: &Candidate, max_fn_rate: Option<f64>) -> bool {
    match max_fn_rate {
        Some(r) => c.fn_rate <= r,
        None => c.false_negatives == 0,
    }
}

/// The selection rule: among the settings that meet the constraint, the fastest
/// ([`Candidate::cost_ms`]: GPU frame and CPU culling, added: the render thread culls before it
/// records); a tie (equal time) goes to the lower FP rate, then to fewer changes from the
/// profile, then to the key (so the pick is deterministic). Returns the candidates in that
/// order, pick first.
pub fn select(
    candidates: &[Candidate],
    max_fn_rate: Option<f64>,
) -> Result<Vec<Candidate>, TuneError> {
    if candidates.is_empty() {
        return Err(TuneError::Nothing);
    }
    let mut ok: Vec<Candidate> = candidates
        .iter()
        .filter(|c| feasible(c, max_fn_rate))
        .cloned()
        .collect();
    if ok.is_empty() {
        let best = candidates
            .iter()
            .min_by(|a, b| {
                a.fn_rate
                    .total_cmp(&b.fn_rate)
                    .then(a.cost_ms().total_cmp(&b.cost_ms()))
            })
            .ok_or(TuneError::Nothing)?;
        return Err(TuneError::Infeasible {
            constraint: constraint_text(max_fn_rate),
            best_fn: best.false_negatives,
            best_rate: best.fn_rate,
            best: best.label.clone(),
        });
    }
    ok.sort_by(|a, b| {
        a.cost_ms()
            .total_cmp(&b.cost_ms())
            .then(a.fp_rate.total_cmp(&b.fp_rate))
            .then(a.changes.cmp(&b.changes))
            .then(a.key.cmp(&b.key))
    });
    Ok(ok)
}

pub fn run(a: &TuneArgs) -> Result<(), CliError> {
    let mut check = KnobSettings::default();
    for c in &a.culling {
        check.set("culling", KnobValue::Name(c.clone()))?;
    }
    if let Some(r) = a.max_fn_rate.filter(|r| !(0.0..=1.0).contains(r)) {
        return Err(CliError::Usage(format!(
            "tune: --max-fn-rate {r} is outside 0..=1"
        )));
    }
    let clusters = if a.culling.is_empty() {
        crate::run::Clusters::ForAuto
    } else {
        a.culling
            .iter()
            .any(|c| Culling::parse(c).is_some_and(Culling::clusters))
            .into()
    };
    let scene = crate::run::load_scene(&a.scene, clusters)?;
    let size = a.size.unwrap_or((320, 180));
    let frames = a.frames.unwrap_or(24);
    let tune_path = match &a.camera_path {
        Some(p) => crate::run::named_camera_path(&p.to_string_lossy(), &scene)?,
        None => scene.camera_path().clone(),
    };
    let held_out = CameraPath::held_out(&scene.bounds(), frames as usize);
    std::fs::create_dir_all(&a.out).map_err(|e| CliError::Write {
        path: a.out.clone(),
        reason: e.to_string(),
    })?;
    let mut options = ContextOptions::from_env();
    if let Some(p) = &a.profile {
        options.force_profile(p, "--profile");
    }
    options.features = crate::cullcheck::oracle_features();
    crate::run::on_context(crate::run::with_every_culling_feature(options), |ctx| {
        tune_on(ctx, a, &scene, size, frames, tune_path, held_out)
    })
}

/// What `tune` sweeps unless `--culling` names it: every standard culling, and the cluster
/// techniques where the scene has its clusters (loaded where `auto` would try them,
/// `knobs::auto_wants_clusters`).
fn default_cullings(scene: &tilegraph_scene::Scene) -> Vec<String> {
    let clusters = [Culling::FrustumClusters, Culling::HizTwoPhaseClusters];
    crate::run::ALL_CULLINGS
        .iter()
        .chain(clusters.iter().filter(|_| scene.clusters().is_some()))
        .map(|c| c.name().to_string())
        .collect()
}

fn tune_on(
    ctx: &Context,
    a: &TuneArgs,
    scene: &tilegraph_scene::Scene,
    size: (u32, u32),
    frames: u32,
    tune_path: CameraPath,
    held_out: CameraPath,
) -> Result<(), CliError> {
    let profile = ctx.profile().clone();
    let path_name = a.camera_path.as_ref().map(|p| p.display().to_string());
    let mut paths = HashMap::new();
    let path_key = |p: &str| format!("{}|{p}", a.scene);
    paths.insert(
        path_key(path_name.as_deref().unwrap_or("own")),
        tune_path.clone(),
    );
    paths.insert(path_key("held-out"), held_out.clone());
    let results_path = a.out.join("results.json");
    let mut results = Results::load_or_new(&results_path)?;
    let profile_value = |k: &str| {
        profile
            .knobs
            .get(k)
            .cloned()
            .or_else(|| tilegraph_profile::knobs::spec(k).map(|s| s.default.into()))
    };
    let name_of = |k: &str| profile_value(k).map(|v| v.to_string()).unwrap_or_default();
    let base = Matrix {
        scenes: vec![a.scene.clone()],
        culling: if a.culling.is_empty() {
            default_cullings(scene)
        } else {
            a.culling.clone()
        },
        shading: vec![name_of("shading")],
        profiles: vec![a.profile.clone()],
        sizes: vec![[size.0, size.1]],
        camera_paths: vec![path_name.clone()],
        axes: [
            "hiz_npot",
            "hiz_resolution",
            "cull_bounds",
            "oq_group",
            "occlusion_recheck",
            "raster_occlusion_scale",
            "software_resolution",
            "software_occluder_triangles",
            "software_threads",
        ]
        .iter()
        .filter_map(|k| tilegraph_profile::knobs::spec(k))
        .map(|k| (k.name.to_string(), k.domain.values()))
        .collect(),
        frames,
    };
    let lookup = |s: &str| (s == a.scene).then_some(scene);
    // The cluster techniques' own knobs as one more coordinate: crossed with each other, the
    // technique's other knobs at the profile's values (crossed with those too, they would
    // multiply the cluster settings tenfold).
    let cluster_knobs = Matrix {
        culling: (base.culling.iter())
            .filter(|c| Culling::parse(c).is_some_and(Culling::clusters))
            .cloned()
            .collect(),
        axes: ["cluster_early", "cluster_gap", "triangle_culling"]
            .iter()
            .filter_map(|k| tilegraph_profile::knobs::spec(k))
            .map(|k| (k.name.to_string(), k.domain.values()))
            .collect(),
        ..base.clone()
    };
    let mut stage1 = base.expand(lookup)?;
    if !cluster_knobs.culling.is_empty() {
        for s in cluster_knobs.expand(lookup)? {
            if !stage1.iter().any(|t| t.key() == s.key()) {
                stage1.push(s);
            }
        }
    }
    let measure = |settings: &[Setting],
                   results: &mut Results,
                   paths: &mut HashMap<String, CameraPath>|
     -> Result<(), CliError> {
        let bar = indicatif::ProgressBar::new(settings.len() as u64);
        for s in settings {
            bar.set_message(s.key());
            if !results.is_done(&s.key()) {
                results.insert(crate::bench::run_or_record_failure(
                    ctx,
                    scene,
                    s,
                    frames,
                    paths,
                    Some(&a.out),
                )?);
                results.save(&results_path)?;
            }
            bar.inc(1);
        }
        bar.finish_and_clear();
        Ok(())
    };
    measure(&stage1, &mut results, &mut paths)?;
    let candidates = |settings: &[Setting], results: &Results, labels: &Labels| -> Vec<Candidate> {
        settings
            .iter()
            .filter_map(|s| {
                let r = results.get(&s.key())?;
                let t = r.totals.as_ref()?;
                let changes = s
                    .knobs
                    .iter()
                    .filter(|(k, v)| profile_value(k).as_ref() != Some(*v))
                    .count()
                    + usize::from(s.culling != name_of("culling"))
                    + usize::from(s.shading != name_of("shading"));
                Some(Candidate {
                    key: s.key(),
                    label: labels.label(s),
                    frame_gpu_ms: t.frame_gpu_ms,
                    cpu_culling_ms: t.software_cpu_ms.unwrap_or(0.0),
                    // A caster culled where the image differs is a false negative too.
                    false_negatives: t.false_negatives
                        + t.shadow_caster_false_negatives.unwrap_or(0) as usize,
                    fn_rate: t.fn_rate,
                    fp_rate: t.fp_rate,
                    changes,
                })
            })
            .collect()
    };
    let labels1 = Labels::new(&stage1);
    let first = select(&candidates(&stage1, &results, &labels1), a.max_fn_rate)
        .map_err(|e| CliError::Usage(format!("tune: {e}")))?;
    // The held-out path: a setting that meets the constraint on the tuning path but not there
    // is overfit. Stage 2 starts from the fastest stage-1 setting that holds there, so that it
    // does not tune shading for a culling that is then thrown out.
    let mut held_out = HeldOut::new(a.max_fn_rate);
    let mut best1 = None;
    for c in &first {
        let Some(s) = stage1.iter().find(|s| s.key() == c.key) else {
            continue;
        };
        if held_out.check(c, s, |h| {
            crate::bench::run_one(ctx, scene, h, frames, &mut paths, Some(&a.out))
        })? {
            best1 = Some(s.clone());
            break;
        }
    }
    let best1 = best1.ok_or_else(|| held_out.nothing_holds())?;
    // Stage 2: shading × draw order (× alpha pre-pass), the culling and its knobs fixed.
    let mut stage2 = Vec::new();
    let mut axes: Vec<(String, Vec<KnobValue>)> = vec![(
        "opaque_sort".into(),
        tilegraph_profile::knobs::spec("opaque_sort").map_or(Vec::new(), |k| k.domain.values()),
    )];
    for name in ["depth_prepass", "alpha_prepass"] {
        if let Some(k) = tilegraph_profile::knobs::spec(name) {
            axes.push((k.name.into(), k.domain.values()));
        }
    }
    // With shadows (the profile's `shadow_cascades`), every caster culling: each is held to
    // the image of every caster (and its FN counted), so the fastest that holds wins.
    if profile_value("shadow_cascades").is_some_and(|v| v.to_string() != "0") {
        if let Some(k) = tilegraph_profile::knobs::spec("shadow_culling") {
            axes.push((k.name.into(), k.domain.values()));
        }
    }
    let m2 = Matrix {
        culling: vec![best1.culling.clone()],
        shading: ["forward", "prepass", "visbuf", "deferred-texturing"]
            .map(String::from)
            .into(),
        axes,
        ..base.clone()
    };
    for mut s in m2.expand(lookup)? {
        s.knobs.extend(best1.knobs.clone());
        if !stage2.iter().any(|o: &Setting| o.key() == s.key()) {
            stage2.push(s);
        }
    }
    measure(&stage2, &mut results, &mut paths)?;
    let all: Vec<Setting> = stage1.iter().chain(&stage2).cloned().collect();
    let labels = Labels::new(&all);
    let ranked = select(&candidates(&all, &results, &labels), a.max_fn_rate)
        .map_err(|e| CliError::Usage(format!("tune: {e}")))?;
    // The pick: the first of the ranked settings that still meets the constraint on the
    // held-out path (those culled like an earlier one are not run again).
    let setting_of = |c: &Candidate| all.iter().find(|s| s.key() == c.key).cloned();
    let mut chosen = None;
    for c in &ranked {
        let Some(s) = setting_of(c) else { continue };
        if held_out.check(c, &s, |h| {
            crate::bench::run_one(ctx, scene, h, frames, &mut paths, Some(&a.out))
        })? {
            let totals = held_out.totals_of(&s);
            chosen = totals.map(|t| (c.clone(), s, t));
            break;
        }
    }
    let Some((pick_c, pick, held_totals)) = chosen else {
        return Err(held_out.nothing_holds());
    };
    let overfit = held_out.overfit.clone();
    let pick_c = &pick_c;
    // The pick's spread: two more runs of it (the first is in results.json).
    let mut times = vec![pick_c.cost_ms()];
    for _ in 0..2 {
        let r = crate::bench::run_one(ctx, scene, &pick, frames, &mut paths, None)?;
        if let Some(t) = r.totals {
            times.push(t.frame_gpu_ms + t.software_cpu_ms.unwrap_or(0.0));
        }
    }
    let spread = (
        times.iter().copied().fold(f64::INFINITY, f64::min),
        times.iter().copied().fold(0.0f64, f64::max),
    );
    crate::bench::write_outputs(&a.out, &results, &all)?;

    // The tuned profile: the profile as loaded, its [knobs] the pick.
    let mut tuned = profile.clone();
    let mut knobs = KnobSettings::default();
    knobs.set("culling", KnobValue::Name(pick.culling.clone()))?;
    knobs.set("shading", KnobValue::Name(pick.shading.clone()))?;
    for (k, v) in &pick.knobs {
        if KNOBS.iter().any(|s| s.name == k) {
            knobs.set(k, v.clone())?;
        }
    }
    tuned.knobs = knobs;
    let body = toml::to_string(&tuned)
        .map_err(|e| CliError::Usage(format!("tune: writing the profile: {e}")))?;
    let device = &ctx.physical;
    let mut header = String::new();
    let _ = writeln!(
        header,
        "# Tuned by `tilegraph tune` ({}) for scene {:?} at {}x{}, {} frames of camera path {}.",
        env!("CARGO_PKG_VERSION"),
        a.scene,
        size.0,
        size.1,
        frames,
        path_name.as_deref().unwrap_or("(the scene's own)")
    );
    let _ = writeln!(
        header,
        "# Device: {} ({} {}, Vulkan {}); base profile {} ({}).",
        device.identity.device_name,
        device.driver_name,
        device.driver_info,
        device.identity.api_version_string(),
        profile.name,
        ctx.selection.matched_by
    );
    let _ = writeln!(
        header,
        "# Constraint: {}. {} settings measured (results.json, report.md beside this directory).",
        constraint_text(a.max_fn_rate),
        all.len()
    );
    let _ = writeln!(
        header,
        "# Pick: {} — frame {:.3} ms (spread {:.3}..{:.3} over {} runs; GPU frame and CPU culling), FN {}, FP rate {:.3}.",
        pick_c.label,
        pick_c.cost_ms(),
        spread.0,
        spread.1,
        times.len(),
        pick_c.false_negatives,
        pick_c.fp_rate
    );
    // Runners-up: settings that cull like none that failed held out.
    let held_up = |c: &&Candidate| setting_of(c).is_some_and(|s| !held_out.failed(&s));
    for c in ranked
        .iter()
        .filter(|c| c.key != pick_c.key)
        .filter(held_up)
        .take(3)
    {
        let _ = writeln!(
            header,
            "# Runner-up: {} — frame {:.3} ms, FN {}, FP rate {:.3}.",
            c.label,
            c.cost_ms(),
            c.false_negatives,
            c.fp_rate
        );
    }
    if overfit.len() > 6 {
        let _ = writeln!(
            header,
            "# Overfit: {} settings, the fastest six below (the rest culled like one of them).",
            overfit.len()
        );
    }
    for (c, fneg) in overfit.iter().take(6) {
        let _ = writeln!(
            header,
            "# Overfit: {} — frame {:.3} ms, FN 0 on the tuning path but {fneg} on the held-out path; not picked.",
            c.label,
            c.cost_ms()
        );
    }
    let _ = writeln!(
        header,
        "# Held-out path (generated from the scene's bounds, not tuned on): the pick's FN {} ({} frames), FP rate {:.3}.",
        held_totals.false_negatives, held_totals.frames_with_false_negatives, held_totals.fp_rate
    );
    let dir = a.out.join("profiles");
    std::fs::create_dir_all(&dir).map_err(|e| CliError::Write {
        path: dir.clone(),
        reason: e.to_string(),
    })?;
    let file = dir.join(format!("{}.toml", tuned.name));
    write_atomically(&file, format!("{header}\n{body}").as_bytes())?;
    // It must load as the profile it replaces.
    let loaded = ProfileSet::embedded()?.with_dir(&dir)?;
    if loaded.get(&tuned.name)?.knobs != tuned.knobs {
        return Err(CliError::Usage(format!(
            "tune: {} does not load back with its knobs",
            file.display()
        )));
    }
    outln!("{}", header.trim_end())?;
    outln!(
        "wrote {}: use it with {PROFILE_DIR_ENV}={}",
        file.display(),
        dir.display()
    )?;
    Ok(())
}

/// The held-out check of `tune`: runs a setting on the path it was not tuned on and remembers
/// the result per way of culling. Which instances a setting draws depends on its culling and
/// the culling's own knobs, not on shading or draw order, so a setting culled like one already
/// run takes that run's verdict. At most [`HeldOut::MAX_RUNS`] ways of culling that can miss
/// are run; a conservative culling (FN 0 by construction) is always run, so that the fastest
/// of those is reached however many faster ones overfit.
struct HeldOut {
    max_fn_rate: Option<f64>,
    /// Per way of culling: its held-out totals and whether they meet the constraint.
    runs: Vec<(String, TotalsRecord, bool)>,
    /// Settings that met the constraint on the tuning path but not here, with their FN.
    overfit: Vec<(Candidate, usize)>,
}

impl HeldOut {
    const MAX_RUNS: usize = 12;

    fn new(max_fn_rate: Option<f64>) -> Self {
        HeldOut {
            max_fn_rate,
            runs: Vec::new(),
            overfit: Vec::new(),
        }
    }

    fn culled_like(s: &Setting) -> String {
        let own: Vec<String> = s
            .knobs
            .iter()
            .filter(|(k, _)| {
                matches!(
                    tilegraph_profile::knobs::spec(k).map(|k| k.applies),
                    Some(tilegraph_profile::knobs::Applies::WithCulling(_))
                )
            })
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        format!("{} {}", s.culling, own.join(","))
    }

    /// Whether `s` (ranked as `c`) meets the constraint on the held-out path, running it with
    /// `run` unless a setting culled like it ran already. `Ok(false)` also for a culling that
    /// can miss once [`HeldOut::MAX_RUNS`] ways of culling have run.
    fn check(
        &mut self,
        c: &Candidate,
        s: &Setting,
        run: impl FnOnce(&Setting) -> Result<RunRecord, CliError>,
    ) -> Result<bool, CliError> {
        let like = Self::culled_like(s);
        let holds = match self.runs.iter().find(|(l, _, _)| *l == like) {
            Some((_, _, holds)) => *holds,
            None if self.runs.len() >= Self::MAX_RUNS
                && !Culling::parse(&s.culling).is_some_and(Culling::conservative) =>
            {
                return Ok(false)
            }
            None => {
                let held = Setting {
                    camera_path: Some("held-out".into()),
                    ..s.clone()
                };
                let Some(t) = run(&held)?.totals else {
                    return Ok(false);
                };
                let holds = match self.max_fn_rate {
                    Some(r) => t.fn_rate <= r,
                    None => t.false_negatives == 0,
                };
                self.runs.push((like.clone(), t, holds));
                holds
            }
        };
        if !holds && !self.overfit.iter().any(|(o, _)| o.key == c.key) {
            let fneg = self.totals_of(s).map_or(0, |t| t.false_negatives);
            self.overfit.push((c.clone(), fneg));
        }
        Ok(holds)
    }

    /// Whether the way `s` culls ran on the held-out path and missed the constraint.
    fn failed(&self, s: &Setting) -> bool {
        let like = Self::culled_like(s);
        self.runs.iter().any(|(l, _, holds)| *l == like && !holds)
    }

    /// The held-out totals of the way `s` culls, once it ran.
    fn totals_of(&self, s: &Setting) -> Option<TotalsRecord> {
        let like = Self::culled_like(s);
        self.runs
            .iter()
            .find(|(l, _, _)| *l == like)
            .map(|(_, t, _)| t.clone())
    }

    fn nothing_holds(&self) -> CliError {
        CliError::Usage(format!(
            "tune: none of the {} settings meeting the constraint on the tuning path that were tried meets it on the held-out path: {}",
            self.overfit.len(),
            self.overfit
                .iter()
                .map(|(c, fneg)| format!("{} (FN {fneg})", c.label))
                .collect::<Vec<_>>()
                .join(", ")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(key: &str, ms: f64, fneg: usize, visible: usize, fp: f64, changes: usize) -> Candidate {
        Candidate {
            key: key.into(),
            label: key.into(),
            frame_gpu_ms: ms,
            cpu_culling_ms: 0.0,
            false_negatives: fneg,
            fn_rate: fneg as f64 / visible as f64,
            fp_rate: fp,
            changes,
        }
    }

    #[test]
    fn cluster_techniques_are_tuned_where_the_scene_has_clusters() {
        let names = |clusters: bool| {
            let scene = crate::run::load_scene("interior:200@one-mesh", clusters).unwrap();
            default_cullings(&scene)
        };
        let with = names(true);
        assert!(with.iter().any(|c| c == "frustum-clusters"), "{with:?}");
        assert!(with.iter().any(|c| c == "hiz-2phase-clusters"), "{with:?}");
        let without = names(false);
        assert_eq!(without.len(), crate::run::ALL_CULLINGS.len(), "{without:?}");
        assert!(
            without.iter().all(|c| !c.contains("clusters")),
            "{without:?}"
        );
    }

    #[test]
    fn the_fastest_conservative_setting_wins() {
        let runs = [
            c("none", 1.0, 0, 100, 0.9, 0),
            c("hiz", 0.4, 3, 100, 0.5, 1),
            c("hiz-2phase", 0.5, 0, 100, 0.6, 1),
            c("oq", 0.3, 9, 100, 0.4, 1),
        ];
        let r = select(&runs, None).unwrap();
        assert_eq!(r[0].key, "hiz-2phase");
        assert_eq!(r.len(), 2, "only the conservative ones rank");
        // With an FN budget, single-phase HiZ qualifies and is faster.
        assert_eq!(select(&runs, Some(0.05)).unwrap()[0].key, "hiz");
        assert_eq!(select(&runs, Some(0.1)).unwrap()[0].key, "oq");
    }

    #[test]
    fn cpu_culling_counts_against_its_gpu_saving() {
        // Software occlusion saves GPU time but the frame waits for its rasterizer.
        let software = |cpu: f64| Candidate {
            cpu_culling_ms: cpu,
            ..c("software-occlusion", 0.3, 0, 100, 0.4, 1)
        };
        let gpu = c("hiz-2phase", 0.5, 0, 100, 0.6, 1);
        assert_eq!(
            select(&[software(0.4), gpu.clone()], None).unwrap()[0].key,
            "hiz-2phase"
        );
        assert_eq!(
            select(&[software(0.1), gpu], None).unwrap()[0].key,
            "software-occlusion"
        );
    }

    #[test]
    fn ties_go_to_fewer_false_positives_then_fewer_changes_then_the_key() {
        let r = select(
            &[
                c("b", 0.5, 0, 10, 0.6, 1),
                c("a", 0.5, 0, 10, 0.7, 0),
                c("c", 0.5, 0, 10, 0.6, 0),
            ],
            None,
        )
        .unwrap();
        let keys: Vec<&str> = r.iter().map(|c| c.key.as_str()).collect();
        assert_eq!(keys, ["c", "b", "a"]);
        let r = select(
            &[c("y", 0.5, 0, 10, 0.6, 0), c("x", 0.5, 0, 10, 0.6, 0)],
            None,
        )
        .unwrap();
        assert_eq!(r[0].key, "x");
    }

    fn setting(culling: &str, knobs: &[(&str, &str)]) -> Setting {
        Setting {
            scene: "city".into(),
            profile: None,
            size: [320, 180],
            camera_path: None,
            shading: "forward".into(),
            culling: culling.into(),
            knobs: knobs
                .iter()
                .map(|(k, v)| (k.to_string(), KnobValue::Name(v.to_string())))
                .collect(),
        }
    }

    fn held_out_run(s: &Setting, false_negatives: usize) -> RunRecord {
        RunRecord {
            key: s.key(),
            settings: s.clone(),
            device: crate::bench::results::DeviceRecord {
                build: String::new(),
                name: "test".into(),
                driver: String::new(),
                driver_version: String::new(),
                api: String::new(),
                profile: "lavapipe".into(),
                profile_matched_by: String::new(),
            },
            culling: s.culling.clone(),
            auto_reason: None,
            knobs: Vec::new(),
            error: None,
            wall_s: 0.0,
            totals: Some(TotalsRecord {
                frames: 1,
                visible: 100,
                drawn: 100,
                false_negatives,
                cluster_false_negatives: 0,
                false_positives: 0,
                fn_rate: false_negatives as f64 / 100.0,
                fp_rate: 0.0,
                frames_with_false_negatives: usize::from(false_negatives > 0),
                frames_image_equal: 1,
                image_diff_pixels: 0,
                image_diff_pixels_depth_tie: 0,
                image_rmse: 0.0,
                image_psnr_db: None,
                image_max_channel_diff: 0,
                image_max_depth_rel_diff: None,
                triangles_drawn: 0,
                frame_gpu_ms: 1.0,
                frame_gpu_ms_p95: 1.0,
                ideal_frame_gpu_ms: None,
                passes_gpu_ms: 1.0,
                cull_gpu_ms: 0.0,
                cpu_ms: 0.0,
                software_cpu_ms: None,
                shadow_casters: None,
                shadow_casters_all: None,
                shadow_gpu_ms: 0.0,
                shadow_casters_needed: None,
                shadow_caster_false_positives: None,
                shadow_caster_false_negatives: None,
            }),
            passes: Vec::new(),
            frames: Vec::new(),
            worst_frame: None,
        }
    }

    /// On lavapipe with frames timed whole, the fastest settings with FN 0 on the tuning path
    /// were a dozen single-phase HiZ and next-frame query variants that all miss held out, and
    /// tune gave up before it reached a conservative culling. The cap now spares those.
    #[test]
    fn the_held_out_check_reaches_a_conservative_culling_after_many_overfit() {
        let mut held = HeldOut::new(None);
        let mut ran = 0;
        let mut fast = Vec::new();
        for bounds in ["aabb", "sphere"] {
            for npot in ["edge-aware", "pad-to-pow2"] {
                for res in ["full", "half", "quarter"] {
                    fast.push(setting(
                        "hiz",
                        &[
                            ("cull_bounds", bounds),
                            ("hiz_npot", npot),
                            ("hiz_resolution", res),
                        ],
                    ));
                }
            }
        }
        for group in ["1", "4", "8", "16"] {
            fast.push(setting("oq", &[("oq_group", group)]));
        }
        for s in &fast {
            let holds = held
                .check(&c(&s.key(), 0.4, 0, 100, 0.5, 1), s, |h| {
                    ran += 1;
                    Ok(held_out_run(h, 7))
                })
                .unwrap();
            assert!(!holds);
        }
        assert_eq!(
            ran,
            HeldOut::MAX_RUNS,
            "ways of culling that can miss stop at the cap"
        );
        let two_phase = setting("hiz-2phase", &[]);
        let holds = held
            .check(&c("two", 0.5, 0, 100, 0.6, 1), &two_phase, |h| {
                ran += 1;
                Ok(held_out_run(h, 0))
            })
            .unwrap();
        assert!(holds, "a conservative culling is checked past the cap");
        assert_eq!(ran, HeldOut::MAX_RUNS + 1);
        // Those past the cap never ran: not known to be overfit.
        assert_eq!(held.overfit.len(), HeldOut::MAX_RUNS);
    }

    #[test]
    fn an_infeasible_constraint_names_the_best_fn_reached() {
        let e = select(
            &[c("hiz", 0.4, 3, 100, 0.5, 1), c("oq", 0.3, 9, 100, 0.4, 1)],
            None,
        )
        .unwrap_err();
        assert_eq!(
            e,
            TuneError::Infeasible {
                constraint: "no false negative on any frame".into(),
                best_fn: 3,
                best_rate: 0.03,
                best: "hiz".into()
            }
        );
        assert!(e.to_string().contains("the best FN reached was 3"), "{e}");
        assert_eq!(select(&[], None).unwrap_err(), TuneError::Nothing);
    }
}
