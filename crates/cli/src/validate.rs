//! `tilegraph validate DIR`: a game's scenes checked in its CI, on lavapipe or any device.
//!
//! `DIR/validate.toml` names the scenes (glTF files in the directory, or built-in specs), their
//! camera paths, and the matrix: profiles (forced, so every vendor's runs on one device),
//! shading and culling. For each scene × profile × shading, the unculled frame at the end of
//! the path is compared with its golden (`DIR/goldens/<scene>-<profile>-<shading>.png`,
//! written by `--bless`) and its first frame is linted against the profile's state rules; for
//! each culling, the frames along the path are checked against the exact oracle (no visible
//! instance, cluster or shadow caster culled; the image equal to the unculled one). Every
//! case runs with the validation layer and synchronization validation on: a message fails the
//! case that caused it.
//!
//! Written to `--out` (default `DIR/validate-out`): `junit.xml` (one test case per check, what
//! CI systems read), `summary.json`, `report.md`, and the images of what failed (the frame,
//! and a diff: red where it differs from the golden). The exit status says pass or fail; bad
//! input (a missing file, an unreadable scene, a golden of another size) names the file.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use tilegraph_passes::cullcheck::{cull_check_options, CheckExtras};
use tilegraph_passes::{RenderError, RenderOptions, SceneRenderer};
use tilegraph_profile::knobs::{KnobSettings, KnobValue};
use tilegraph_profile::ProfileSet;
use tilegraph_scene::{CameraPath, Scene};
use tilegraph_vk::readback::RgbaImage;
use tilegraph_vk::{Context, Validation};

use crate::image_io::{read_png, write_png};
use crate::markup::escape;
use crate::run::{auto_inputs, load_scene, named_camera_path, with_every_culling_feature};
use crate::CliError;

#[derive(clap::Args, Debug, Clone)]
pub struct ValidateArgs {
    /// The directory: `validate.toml`, the scenes and camera paths it names, `goldens/`.
    pub dir: PathBuf,
    /// Write the goldens (each scene's unculled frame per profile and shading) instead of
    /// comparing with them; the other checks still run.
    #[arg(long)]
    pub bless: bool,
    /// Where `junit.xml`, `summary.json`, `report.md` and the failed frames' images go
    /// (default `DIR/validate-out`).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `validate.toml`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Config {
    /// WxH of every frame (small: the CI's lavapipe renders on the CPU).
    #[serde(default = "default_size")]
    size: String,
    /// Frames of each camera path checked (from its start).
    #[serde(default = "default_frames")]
    frames: usize,
    /// Profiles to force, one after the other (empty: every shipped profile).
    #[serde(default)]
    profiles: Vec<String>,
    #[serde(default = "default_shading")]
    shading: Vec<String>,
    #[serde(default = "default_culling")]
    culling: Vec<String>,
    #[serde(rename = "scene")]
    scenes: Vec<SceneEntry>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneEntry {
    /// The name in reports and golden files (default: the file's stem, or the spec).
    name: Option<String>,
    /// A glTF file, relative to the directory.
    file: Option<String>,
    /// Or a built-in scene spec (`city:300`, `interior`).
    spec: Option<String>,
    /// A camera path JSON relative to the directory, or `walk[:SEED]` (default: the scene's
    /// own path).
    camera_path: Option<String>,
    /// Pixels of the frame allowed to differ from its golden (any channel by more than 1).
    #[serde(default)]
    tolerance: usize,
    /// Visible instances a culling may miss over the path (0: every culling exact).
    #[serde(default)]
    max_false_negatives: usize,
}

fn default_size() -> String {
    "160x90".into()
}
fn default_frames() -> usize {
    4
}
fn default_shading() -> Vec<String> {
    vec!["forward".into()]
}
fn default_culling() -> Vec<String> {
    vec!["hiz-2phase".into()]
}

/// One check's outcome: a JUnit test case.
#[derive(Debug, Clone, Serialize)]
pub struct Case {
    /// `scene`, and `profile/shading[/culling]/check`.
    pub suite: String,
    pub name: String,
    pub seconds: f64,
    /// Why it failed (empty: passed).
    pub failures: Vec<String>,
    /// Why it did not run (a culling the shading cannot take), if so.
    pub skipped: Option<String>,
    /// What it measured (FN, pixels, findings...).
    pub details: String,
}

/// A scene ready to check.
struct Loaded {
    name: String,
    scene: Scene,
    path: CameraPath,
    entry: SceneEntry,
}

pub fn run(a: &ValidateArgs) -> Result<(), CliError> {
    let config_path = a.dir.join("validate.toml");
    let text = std::fs::read_to_string(&config_path)
        .map_err(|e| CliError::Usage(format!("{}: {e}", config_path.display())))?;
    let config: Config = toml::from_str(&text)
        .map_err(|e| CliError::Usage(format!("{}: {e}", config_path.display())))?;
    let size = crate::parse_size(&config.size)
        .map_err(|e| CliError::Usage(format!("{}: size: {e}", config_path.display())))?;
    if config.scenes.is_empty() || config.frames == 0 {
        return Err(CliError::Usage(format!(
            "{}: name at least one [[scene]] and frames >= 1",
            config_path.display()
        )));
    }
    let profiles = match config.profiles.is_empty() {
        true => ProfileSet::from_env()?
            .names()
            .into_iter()
            .map(str::to_string)
            .collect(),
        false => config.profiles.clone(),
    };
    let clusters = config.culling.iter().any(|c| c.contains("clusters"));
    let scenes = config
        .scenes
        .into_iter()
        .map(|entry| load(&a.dir, entry, clusters))
        .collect::<Result<Vec<_>, _>>()?;
    let out = a.out.clone().unwrap_or_else(|| a.dir.join("validate-out"));
    std::fs::create_dir_all(&out).map_err(|e| CliError::Write {
        path: out.clone(),
        reason: e.to_string(),
    })?;
    let goldens = a.dir.join("goldens");
    let mut cases = Vec::new();
    for profile in &profiles {
        let mut options = tilegraph_vk::ContextOptions::from_env();
        options.force_profile(profile, "validate.toml");
        options.validation = Validation::Required;
        options.features = crate::cullcheck::oracle_features();
        let options = with_every_culling_feature(options);
        let ctx = Context::new(options)?;
        let run = Matrix {
            ctx: &ctx,
            profile,
            size,
            frames: config.frames,
            goldens: &goldens,
            out: &out,
            bless: a.bless,
        };
        for s in &scenes {
            for shading in &config.shading {
                cases.push(run.golden_case(s, shading)?);
                for culling in &config.culling {
                    cases.push(run.culling_case(s, shading, culling)?);
                }
            }
        }
        // What only the teardown sees (objects left alive) fails a case of its own.
        let started = Instant::now();
        let teardown = ctx.destroy_checked();
        cases.push(Case {
            suite: "teardown".into(),
            name: format!("{profile}/teardown"),
            seconds: started.elapsed().as_secs_f64(),
            failures: teardown.err().map(|e| e.to_string()).into_iter().collect(),
            skipped: None,
            details: String::new(),
        });
    }
    write_reports(&out, &cases)?;
    let failed = cases.iter().filter(|c| !c.failures.is_empty()).count();
    outln!(
        "validate: {} checks, {failed} failed; {} (junit.xml, summary.json, report.md)",
        cases.len(),
        out.display()
    )?;
    match failed {
        0 => Ok(()),
        n => Err(CliError::Usage(format!(
            "validate: {n} of {} checks failed (see {})",
            cases.len(),
            out.join("report.md").display()
        ))),
    }
}

/// Loads a scene entry: its scene (with clusters if a culling culls them) and its path.
fn load(dir: &Path, entry: SceneEntry, clusters: bool) -> Result<Loaded, CliError> {
    let (spec, name) = match (&entry.file, &entry.spec) {
        (Some(file), None) => {
            let path = dir.join(file);
            if !path.is_file() {
                return Err(CliError::Usage(format!(
                    "scene file {} does not exist",
                    path.display()
                )));
            }
            let stem = path
                .file_stem()
                .map_or_else(|| file.clone(), |s| s.to_string_lossy().into_owned());
            (path.to_string_lossy().into_owned(), stem)
        }
        (None, Some(spec)) => (spec.clone(), spec.replace([':', '/', '@'], "-")),
        _ => {
            return Err(CliError::Usage(
                "a [[scene]] names either `file` or `spec`".into(),
            ))
        }
    };
    let name = entry.name.clone().unwrap_or(name);
    let scene =
        load_scene(&spec, clusters).map_err(|e| CliError::Usage(format!("scene {spec}: {e}")))?;
    let path = match &entry.camera_path {
        Some(p) if crate::run::walk_seed(p)?.is_some() => named_camera_path(p, &scene)?,
        Some(p) => {
            let file = dir.join(p);
            named_camera_path(&file.to_string_lossy(), &scene)
                .map_err(|e| CliError::Usage(format!("camera path {}: {e}", file.display())))?
        }
        None => scene.camera_path().clone(),
    };
    if path.is_empty() {
        return Err(CliError::Usage(format!(
            "scene {name}: its camera path is empty"
        )));
    }
    Ok(Loaded {
        name,
        scene,
        path,
        entry,
    })
}

/// One profile's runs.
struct Matrix<'a> {
    ctx: &'a Context,
    profile: &'a str,
    size: (u32, u32),
    frames: usize,
    goldens: &'a Path,
    out: &'a Path,
    bless: bool,
}

impl Matrix<'_> {
    /// The options of `shading` with `culling` on this profile, as the profile's knobs and
    /// `tilegraph render` resolve them.
    fn options(&self, s: &Loaded, shading: &str, culling: &str) -> Result<RenderOptions, CliError> {
        let mut knobs = KnobSettings::default();
        knobs.set("shading", KnobValue::Name(shading.into()))?;
        knobs.set("culling", KnobValue::Name(culling.into()))?;
        let mut o = RenderOptions {
            width: self.size.0,
            height: self.size.1,
            ..Default::default()
        };
        let resolved = tilegraph_passes::knobs::resolve(
            self.ctx.profile(),
            &knobs,
            &s.scene,
            auto_inputs(self.ctx, &s.scene, None),
        )?;
        resolved.apply(&mut o);
        Ok(o)
    }

    fn frames(&self, s: &Loaded) -> usize {
        self.frames.min(s.path.len())
    }

    /// The unculled frame at the end of the path against its golden, and the lint of the
    /// first frame.
    fn golden_case(&self, s: &Loaded, shading: &str) -> Result<Case, CliError> {
        let started = Instant::now();
        let mut case = Case {
            suite: s.name.clone(),
            name: format!("{}/{shading}/golden-and-lint", self.profile),
            seconds: 0.0,
            failures: Vec::new(),
            skipped: None,
            details: String::new(),
        };
        let stem = format!("{}-{}-{shading}", s.name, self.profile);
        match self.render_unculled(s, shading) {
            Ok((image, lint)) => {
                if let Some((open, summary)) = lint {
                    if open > 0 {
                        case.failures
                            .push(format!("lint: {open} open finding(s): {summary}"));
                    }
                    case.details = summary;
                }
                let golden = self.goldens.join(format!("{stem}.png"));
                if self.bless {
                    write_png(&golden, &image)?;
                } else if let Err(why) = self.compare(&golden, &image, s.entry.tolerance, &stem)? {
                    case.failures.push(why);
                }
            }
            Err(e) => case.failures.push(format!("error: {e}")),
        }
        self.validation(&mut case);
        case.seconds = started.elapsed().as_secs_f64();
        Ok(case)
    }

    /// Renders the path's frames unculled; returns the last image and the first frame's lint:
    /// its open findings and its summary.
    fn render_unculled(
        &self,
        s: &Loaded,
        shading: &str,
    ) -> Result<(RgbaImage, Option<(usize, String)>), CliError> {
        let options = self.options(s, shading, "none")?;
        let aspect = options.width as f32 / options.height as f32;
        let mut r = SceneRenderer::new(self.ctx, &s.scene, options)?;
        r.lint_next_frame();
        let mut lint = None;
        let rendered = (|| {
            for i in 0..self.frames(s) {
                let Some(frame) = s.path.frame(i, aspect) else {
                    break;
                };
                let report = r.render_frame(self.ctx, &s.scene, &frame)?;
                if let Some(l) = &report.lint {
                    lint = Some((l.findings.len() - l.accepted_count(), l.summary()));
                }
            }
            r.read_image(self.ctx)
        })();
        r.destroy(self.ctx);
        Ok((rendered?, lint))
    }

    /// `image` against `golden`: `Ok(Err(why))` when it differs by more than `tolerance`
    /// pixels (the frame and a diff written to the output), `Err` for a golden that cannot be
    /// read or has another size.
    fn compare(
        &self,
        golden: &Path,
        image: &RgbaImage,
        tolerance: usize,
        stem: &str,
    ) -> Result<Result<(), String>, CliError> {
        if !golden.is_file() {
            return Ok(Err(format!(
                "golden: {} does not exist (run `tilegraph validate --bless` to write it)",
                golden.display()
            )));
        }
        let want = read_png(golden)?;
        if (want.width, want.height) != (image.width, image.height) {
            return Err(CliError::Usage(format!(
                "golden {} is {}x{}, the frame {}x{} (bless again after changing the size)",
                golden.display(),
                want.width,
                want.height,
                image.width,
                image.height
            )));
        }
        let mut diff = image.clone();
        let mut differing = 0usize;
        for (d, (a, b)) in diff.pixels.chunks_exact_mut(4).zip(
            image
                .pixels
                .chunks_exact(4)
                .zip(want.pixels.chunks_exact(4)),
        ) {
            let worst = (0..4).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0);
            if worst > 1 {
                differing += 1;
                d.copy_from_slice(&[255, 0, 0, 255]);
            } else {
                d.copy_from_slice(&[a[0] / 3, a[1] / 3, a[2] / 3, 255]);
            }
        }
        if differing <= tolerance {
            return Ok(Ok(()));
        }
        write_png(&self.out.join(format!("{stem}.png")), image)?;
        write_png(&self.out.join(format!("{stem}-diff.png")), &diff)?;
        Ok(Err(format!(
            "golden: {differing} pixels differ from {} (tolerance {tolerance}); frame {stem}.png, diff {stem}-diff.png",
            golden.display()
        )))
    }

    /// `culling` along the path against the oracle.
    fn culling_case(&self, s: &Loaded, shading: &str, culling: &str) -> Result<Case, CliError> {
        let started = Instant::now();
        let mut case = Case {
            suite: s.name.clone(),
            name: format!("{}/{shading}/{culling}/exact", self.profile),
            seconds: 0.0,
            failures: Vec::new(),
            skipped: None,
            details: String::new(),
        };
        let options = self.options(s, shading, culling)?;
        let checked = cull_check_options(
            self.ctx,
            &s.scene,
            options,
            &s.path,
            Some(self.frames(s)),
            CheckExtras::default(),
        );
        match checked {
            Ok(check) => {
                let t = &check.totals;
                let missed = t.false_negatives
                    + t.cluster_false_negatives
                    + t.shadow_caster_false_negatives.unwrap_or(0) as usize;
                case.details = format!(
                    "{}: FN {} (clusters {}), images equal {}/{}",
                    check.technique,
                    t.false_negatives,
                    t.cluster_false_negatives,
                    t.frames_image_equal,
                    t.frames
                );
                if missed > s.entry.max_false_negatives {
                    let frames: Vec<String> = check
                        .frames
                        .iter()
                        .filter(|f| f.false_negatives > 0)
                        .map(|f| format!("{} ({:?})", f.frame, f.false_negative_ids))
                        .collect();
                    case.failures.push(format!(
                        "culling: {missed} visible culled (allowed {}); frames (instances): {}",
                        s.entry.max_false_negatives,
                        frames.join(", ")
                    ));
                } else if s.entry.max_false_negatives == 0 && t.frames_image_equal < t.frames {
                    case.failures.push(format!(
                        "culling: the image differs from the unculled one in {} of {} frames, {} pixels ({} of them depth ties: the same depth, another surface at it drawn first — depth precision; {} stray: a degenerate triangle's, drawn off its own depth or covered differently from draw to draw — a mesh to clean; docs/ACCURACY.md)",
                        t.frames - t.frames_image_equal,
                        t.frames,
                        t.image_diff_pixels,
                        t.image_diff_pixels_depth_tie,
                        t.image_diff_pixels_stray
                    ));
                }
            }
            // A combination the technique cannot take is not the game's failure.
            Err(e @ RenderError::UnsupportedCulling { .. }) => case.skipped = Some(e.to_string()),
            Err(e) => case.failures.push(format!("error: {e}")),
        }
        self.validation(&mut case);
        case.seconds = started.elapsed().as_secs_f64();
        Ok(case)
    }

    /// The validation messages the case caused fail it.
    fn validation(&self, case: &mut Case) {
        let messages = self.ctx.take_validation_messages();
        if !messages.is_empty() {
            let shown: Vec<&str> = messages.iter().take(5).map(String::as_str).collect();
            case.failures.push(format!(
                "validation: {} message(s): {}",
                messages.len(),
                shown.join(" | ")
            ));
        }
    }
}

/// `junit.xml`, `summary.json` and `report.md` of `cases`.
fn write_reports(out: &Path, cases: &[Case]) -> Result<(), CliError> {
    let write = |name: &str, text: String| {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| CliError::Write {
            path,
            reason: e.to_string(),
        })
    };
    write("junit.xml", junit(cases))?;
    write(
        "summary.json",
        serde_json::to_string_pretty(&Summary::of(cases))?,
    )?;
    write("report.md", markdown(cases))
}

#[derive(Serialize)]
struct Summary<'a> {
    checks: usize,
    failed: usize,
    cases: &'a [Case],
}

impl<'a> Summary<'a> {
    fn of(cases: &'a [Case]) -> Self {
        Summary {
            checks: cases.len(),
            failed: cases.iter().filter(|c| !c.failures.is_empty()).count(),
            cases,
        }
    }
}

/// JUnit XML: a test suite per scene (and the teardowns), a test case per check, a
/// `<failure>` per reason.
pub fn junit(cases: &[Case]) -> String {
    let mut suites: Vec<&str> = cases.iter().map(|c| c.suite.as_str()).collect();
    suites.dedup();
    suites.sort_unstable();
    suites.dedup();
    let failed = |c: &&Case| !c.failures.is_empty();
    let mut x = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        x,
        "<testsuites name=\"tilegraph validate\" tests=\"{}\" failures=\"{}\" skipped=\"{}\">",
        cases.len(),
        cases.iter().filter(failed).count(),
        cases.iter().filter(|c| c.skipped.is_some()).count()
    );
    for suite in suites {
        let of: Vec<&Case> = cases.iter().filter(|c| c.suite == suite).collect();
        let _ = writeln!(
            x,
            "  <testsuite name=\"{}\" tests=\"{}\" failures=\"{}\" time=\"{:.3}\">",
            escape(suite),
            of.len(),
            of.iter().filter(|c| !c.failures.is_empty()).count(),
            of.iter().map(|c| c.seconds).sum::<f64>()
        );
        for c in of {
            let _ = write!(
                x,
                "    <testcase classname=\"{}\" name=\"{}\" time=\"{:.3}\"",
                escape(suite),
                escape(&c.name),
                c.seconds
            );
            if c.failures.is_empty() && c.details.is_empty() && c.skipped.is_none() {
                x.push_str("/>\n");
                continue;
            }
            x.push_str(">\n");
            for f in &c.failures {
                let kind = f.split(':').next().unwrap_or("failure");
                let _ = writeln!(
                    x,
                    "      <failure type=\"{}\" message=\"{}\"/>",
                    escape(kind),
                    escape(f)
                );
            }
            if let Some(why) = &c.skipped {
                let _ = writeln!(x, "      <skipped message=\"{}\"/>", escape(why));
            }
            if !c.details.is_empty() {
                let _ = writeln!(x, "      <system-out>{}</system-out>", escape(&c.details));
            }
            x.push_str("    </testcase>\n");
        }
        x.push_str("  </testsuite>\n");
    }
    x.push_str("</testsuites>\n");
    x
}

fn markdown(cases: &[Case]) -> String {
    let failed: Vec<&Case> = cases.iter().filter(|c| !c.failures.is_empty()).collect();
    let mut md = format!(
        "# tilegraph validate\n\n{} checks, {} failed.\n\n",
        cases.len(),
        failed.len()
    );
    if !failed.is_empty() {
        md.push_str("## Failed\n\n");
        for c in &failed {
            let _ = writeln!(md, "### {} {}\n", c.suite, c.name);
            for f in &c.failures {
                let _ = writeln!(md, "- {f}");
            }
            md.push('\n');
        }
    }
    md.push_str(
        "## Every check\n\n| scene | check | result | details | s |\n|---|---|---|---|---:|\n",
    );
    for c in cases {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.1} |",
            c.suite,
            c.name,
            match (&c.skipped, c.failures.is_empty()) {
                (Some(_), _) => "skipped",
                (None, true) => "pass",
                (None, false) => "**fail**",
            },
            c.skipped.as_ref().unwrap_or(&c.details).replace('|', "\\|"),
            c.seconds
        );
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn junit_escapes_and_counts_failures_per_suite() {
        let cases = vec![
            Case {
                suite: "arena".into(),
                name: "mali-valhall/forward/golden-and-lint".into(),
                seconds: 0.5,
                failures: vec!["golden: 3 pixels differ <&\"'>".into()],
                skipped: None,
                details: "clean".into(),
            },
            Case {
                suite: "arena".into(),
                name: "mali-valhall/forward/hiz-2phase/exact".into(),
                seconds: 0.25,
                failures: Vec::new(),
                skipped: None,
                details: String::new(),
            },
        ];
        let x = junit(&cases);
        assert!(x.contains("tests=\"2\" failures=\"1\""), "{x}");
        assert!(x.contains("type=\"golden\""), "{x}");
        assert!(x.contains("&lt;&amp;&quot;&apos;&gt;"), "{x}");
        assert!(
            x.contains("name=\"mali-valhall/forward/hiz-2phase/exact\" time=\"0.250\"/>"),
            "{x}"
        );
    }
}
