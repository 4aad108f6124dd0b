//! The bench matrix: what the options (or the TOML file) ask for, checked, and expanded into
//! settings — one per combination, knob axes only where the knob means something.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use serde::{Deserialize, Serialize};
use tilegraph_passes::cull::Culling;
use tilegraph_passes::{SceneContent, Technique};
use tilegraph_profile::knobs::{spec, Applies, KnobSettings, KnobValue};
use tilegraph_scene::Scene;

use super::BenchArgs;
use crate::CliError;

/// `--culling profile` / `--shading profile`: whatever the profile's knob says (how a tuned
/// profile is re-measured).
pub const PROFILE_CHOICE: &str = "profile";

/// The matrix as a TOML file writes it.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct MatrixFile {
    #[serde(default)]
    scenes: Vec<String>,
    #[serde(default)]
    culling: Vec<String>,
    #[serde(default)]
    shading: Vec<String>,
    #[serde(default)]
    profiles: Vec<String>,
    #[serde(default)]
    sizes: Vec<String>,
    #[serde(default)]
    camera_paths: Vec<String>,
    frames: Option<u32>,
    /// One axis per knob.
    #[serde(default)]
    set: BTreeMap<String, Vec<KnobValue>>,
}

/// The checked matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    pub scenes: Vec<String>,
    pub culling: Vec<String>,
    pub shading: Vec<String>,
    /// `None`: the device's own profile.
    pub profiles: Vec<Option<String>>,
    pub sizes: Vec<[u32; 2]>,
    /// `None`: the scene's own path.
    pub camera_paths: Vec<Option<String>>,
    /// Knob axes, in the order given.
    pub axes: Vec<(String, Vec<KnobValue>)>,
    pub frames: u32,
}

/// One run of the matrix.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Setting {
    pub scene: String,
    pub profile: Option<String>,
    pub size: [u32; 2],
    pub camera_path: Option<String>,
    pub shading: String,
    pub culling: String,
    pub knobs: BTreeMap<String, KnobValue>,
}

impl Setting {
    /// What identifies the run in results.json (a resumed bench skips keys it has).
    pub fn key(&self) -> String {
        let knobs: Vec<String> = self.knobs.iter().map(|(k, v)| format!("{k}={v}")).collect();
        format!(
            "{}|{}|{}x{}|{}|{}|{}|{}",
            self.scene,
            self.profile.as_deref().unwrap_or("device"),
            self.size[0],
            self.size[1],
            self.camera_path.as_deref().unwrap_or("own"),
            self.shading,
            self.culling,
            knobs.join(",")
        )
    }

    pub fn camera_path_key(&self) -> String {
        format!(
            "{}|{}",
            self.scene,
            self.camera_path.as_deref().unwrap_or("own")
        )
    }
}

fn pick(cli: &[String], file: Vec<String>) -> Vec<String> {
    if cli.is_empty() {
        file
    } else {
        cli.to_vec()
    }
}

impl Matrix {
    pub fn from_args(args: &BenchArgs) -> Result<Matrix, CliError> {
        let file = match &args.config {
            Some(p) => read_file(p)?,
            None => MatrixFile::default(),
        };
        let usage = |m: String| CliError::Usage(format!("bench: {m}"));
        let scenes = pick(&args.scenes, file.scenes);
        if scenes.is_empty() {
            return Err(usage(
                "no scenes: give --scenes (or scenes in --config)".into(),
            ));
        }
        let mut check = KnobSettings::default();
        let mut culling = pick(&args.culling, file.culling);
        if culling.is_empty() {
            culling = crate::run::ALL_CULLINGS
                .iter()
                .map(|c| c.name().to_string())
                .collect();
        }
        for c in culling.iter().filter(|c| *c != PROFILE_CHOICE) {
            check.set("culling", KnobValue::Name(c.clone()))?;
        }
        let mut shading = pick(&args.shading, file.shading);
        if shading.is_empty() {
            shading = vec!["forward".into()];
        }
        for s in shading.iter().filter(|s| *s != PROFILE_CHOICE) {
            check.set("shading", KnobValue::Name(s.clone()))?;
        }
        let profiles = pick(&args.profiles, file.profiles);
        let profiles = if profiles.is_empty() {
            vec![None]
        } else {
            profiles.into_iter().map(Some).collect()
        };
        let mut sizes = Vec::new();
        for s in pick(&args.sizes, file.sizes) {
            let (w, h) = crate::parse_size(&s).map_err(|e| usage(format!("--sizes: {e}")))?;
            sizes.push([w, h]);
        }
        if sizes.is_empty() {
            sizes.push([320, 180]);
        }
        let paths = pick(&args.camera_paths, file.camera_paths);
        let mut camera_paths: Vec<Option<String>> = paths
            .into_iter()
            .map(|p| (p != "own").then_some(p))
            .collect();
        if camera_paths.is_empty() {
            camera_paths.push(None);
        }
        for p in camera_paths.iter().flatten() {
            // Parsed now, so a bad file or walk stops the bench before it starts.
            if crate::run::walk_seed(p)?.is_none() {
                tilegraph_scene::CameraPath::load_json(Path::new(p))?;
            }
        }
        let mut axes: Vec<(String, Vec<KnobValue>)> = Vec::new();
        let from_cli = !args.set.is_empty();
        let raw: Vec<(String, Vec<KnobValue>)> = if from_cli {
            let mut v = Vec::new();
            for a in &args.set {
                let (k, vals) = a
                    .split_once('=')
                    .ok_or_else(|| usage(format!("--set {a}: expected knob=value1,value2")))?;
                v.push((
                    k.trim().to_string(),
                    vals.split(',')
                        .map(|x| KnobValue::Name(x.trim().to_string()))
                        .collect(),
                ));
            }
            v
        } else {
            file.set.into_iter().collect()
        };
        for (k, vals) in raw {
            if k == "culling" || k == "shading" {
                return Err(usage(format!("knob {k} is an axis of its own: use --{k}")));
            }
            if axes.iter().any(|(a, _)| *a == k) {
                return Err(usage(format!("knob {k} is given twice")));
            }
            let mut checked = Vec::new();
            for v in vals {
                let mut one = KnobSettings::default();
                one.set(&k, v)?;
                if let Some(v) = one.get(&k) {
                    if !checked.contains(v) {
                        checked.push(v.clone());
                    }
                }
            }
            axes.push((k, checked));
        }
        Ok(Matrix {
            scenes,
            culling,
            shading,
            profiles,
            sizes,
            camera_paths,
            axes,
            frames: args.frames.or(file.frames).unwrap_or(24),
        })
    }

    /// Every setting, knob axes only where they apply (the others collapse), without repeats.
    pub fn expand<'a>(
        &self,
        scene: impl Fn(&str) -> Option<&'a Scene>,
    ) -> Result<Vec<Setting>, CliError> {
        let mut out = Vec::new();
        let mut seen = HashSet::new();
        for spec_ in &self.scenes {
            let content = scene(spec_)
                .map(SceneContent::of)
                .ok_or_else(|| CliError::Usage(format!("bench: scene {spec_} was not loaded")))?;
            for profile in &self.profiles {
                for size in &self.sizes {
                    for path in &self.camera_paths {
                        for shading in &self.shading {
                            for culling in &self.culling {
                                let axes: Vec<&(String, Vec<KnobValue>)> = self
                                    .axes
                                    .iter()
                                    .filter(|(k, _)| applies(k, culling, shading, content))
                                    .collect();
                                for knobs in cartesian(&axes) {
                                    let s = Setting {
                                        scene: spec_.clone(),
                                        profile: profile.clone(),
                                        size: *size,
                                        camera_path: path.clone(),
                                        shading: shading.clone(),
                                        culling: culling.clone(),
                                        knobs,
                                    };
                                    if seen.insert(s.key()) {
                                        out.push(s);
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        Ok(out)
    }
}

fn read_file(path: &Path) -> Result<MatrixFile, CliError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::Usage(format!("bench --config {}: {e}", path.display())))?;
    toml::from_str(&text)
        .map_err(|e| CliError::Usage(format!("bench --config {}: {e}", path.display())))
}

/// Whether knob `k` means something for this combination (what `knobs::resolve` would accept).
fn applies(k: &str, culling: &str, shading: &str, content: SceneContent) -> bool {
    let Some(spec) = spec(k) else { return false };
    match spec.applies {
        // A pre-pass knob means nothing where the shading or the culling decides it.
        Applies::Always if k == "depth_prepass" => {
            shading == "forward"
                && culling != PROFILE_CHOICE
                && !Culling::parse(culling).is_some_and(Culling::needs_prepass)
        }
        Applies::Always => true,
        // `auto` decides on the device: its knobs are the profile's.
        Applies::WithCulling(list) => list.contains(&culling),
        Applies::WithShading(list) => list.contains(&shading),
        Applies::AlphaTestedScene => {
            culling != PROFILE_CHOICE
                && shading != PROFILE_CHOICE
                && content.alpha_tested > 0
                && !Technique::parse(shading).is_some_and(Technique::screen_space)
                && !Culling::parse(culling).is_some_and(Culling::needs_prepass)
        }
    }
}

fn cartesian(axes: &[&(String, Vec<KnobValue>)]) -> Vec<BTreeMap<String, KnobValue>> {
    let mut out = vec![BTreeMap::new()];
    for (k, values) in axes {
        out = out
            .into_iter()
            .flat_map(|m| {
                values.iter().map(move |v| {
                    let mut m = m.clone();
                    m.insert(k.clone(), v.clone());
                    m
                })
            })
            .collect();
    }
    out
}

/// How a setting is named in plots and the report: its culling, and whatever else varies in
/// the matrix (knobs, shading, profile, camera path); and a short key (`s12`: the setting's
/// place in the matrix, the same in every scene and size) that the plots print beside their points and the tables key their rows
/// by, so that a plot of 144 settings needs no legend of 144 entries.
pub struct Labels {
    shading: bool,
    profile: bool,
    path: bool,
    keys: HashMap<String, usize>,
    knob_names: Vec<String>,
}

impl Labels {
    pub fn new(settings: &[Setting]) -> Labels {
        let varies = |f: &dyn Fn(&Setting) -> String| {
            settings.iter().map(f).collect::<HashSet<_>>().len() > 1
        };
        let mut keys = HashMap::new();
        for s in settings {
            let next = keys.len() + 1;
            keys.entry(Self::identity(s)).or_insert(next);
        }
        let mut knob_names: Vec<String> = settings
            .iter()
            .flat_map(|s| s.knobs.keys().cloned())
            .collect();
        knob_names.sort();
        knob_names.dedup();
        Labels {
            shading: varies(&|s| s.shading.clone()),
            profile: varies(&|s| s.profile.clone().unwrap_or_default()),
            path: varies(&|s| s.camera_path.clone().unwrap_or_default()),
            keys,
            knob_names,
        }
    }

    /// What a short key names: the setting but its scene and size, so that `s3` is the same
    /// setting in every scene's table and plot.
    fn identity(s: &Setting) -> String {
        Setting {
            scene: String::new(),
            size: [0, 0],
            ..s.clone()
        }
        .key()
    }

    /// The setting's short key, `s` and its 1-based place among the matrix's settings (scene
    /// and size aside; `s?` for a setting the matrix does not hold).
    pub fn short(&self, s: &Setting) -> String {
        self.keys
            .get(&Self::identity(s))
            .map_or_else(|| "s?".into(), |i| format!("s{i}"))
    }

    /// Every knob some setting sets, sorted: the knob columns of the HTML report's tables.
    pub fn knob_names(&self) -> &[String] {
        &self.knob_names
    }

    /// Whether the shading varies over the matrix (a column of its own in the tables).
    pub fn shading_varies(&self) -> bool {
        self.shading
    }

    pub fn label(&self, s: &Setting) -> String {
        let mut parts = vec![s.culling.clone()];
        if self.shading {
            parts.push(s.shading.clone());
        }
        parts.extend(s.knobs.iter().map(|(k, v)| format!("{k}={v}")));
        if self.profile {
            parts.push(s.profile.clone().unwrap_or_else(|| "device".into()));
        }
        if self.path {
            parts.push(format!(
                "path {}",
                s.camera_path
                    .as_deref()
                    .and_then(|p| Path::new(p).file_stem())
                    .map_or("own".into(), |n| n.to_string_lossy().into_owned())
            ));
        }
        parts.join(" ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(set: &[&str], culling: &[&str]) -> BenchArgs {
        BenchArgs {
            scenes: vec!["city:300".into(), "forest:300".into()],
            culling: culling.iter().map(|s| s.to_string()).collect(),
            set: set.iter().map(|s| s.to_string()).collect(),
            out: "unused".into(),
            ..Default::default()
        }
    }

    #[test]
    fn knob_axes_expand_only_where_they_apply() {
        let m = Matrix::from_args(&args(
            &["oq_group=1,16", "alpha_prepass=on,off"],
            &["hiz-2phase", "oq", "none"],
        ))
        .unwrap();
        let city = tilegraph_scene::load("city:300").unwrap();
        let forest = tilegraph_scene::load("forest:300").unwrap();
        let settings = m
            .expand(|s| match s {
                "city:300" => Some(&city),
                "forest:300" => Some(&forest),
                _ => None,
            })
            .unwrap();
        let keys: Vec<String> = settings.iter().map(Setting::key).collect();
        // city: hiz-2phase 1, oq 2 (groups), none 1; forest: hiz-2phase 1 (forces its own
        // alpha pre-pass), oq 2x2, none 2 (alpha on/off).
        assert_eq!(settings.len(), 4 + 7, "{keys:#?}");
        assert!(
            keys.contains(
                &"forest:300|device|320x180|own|forward|oq|alpha_prepass=off,oq_group=16"
                    .to_string()
            ),
            "{keys:#?}"
        );
        assert!(!keys
            .iter()
            .any(|k| k.contains("hiz-2phase") && k.contains("oq_group")));
        assert!(!keys
            .iter()
            .any(|k| k.starts_with("city") && k.contains("alpha_prepass")));
    }

    #[test]
    fn bad_matrices_are_refused_before_anything_runs() {
        for (set, culling, want) in [
            (vec!["oq_group=1,3"], vec![], "outside its domain"),
            (vec!["oq_groop=1"], vec![], "unknown knob"),
            (vec!["culling=hiz"], vec![], "axis of its own"),
            (vec![], vec!["hiz-3phase"], "outside its domain"),
        ] {
            let e = Matrix::from_args(&args(&set, &culling))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{set:?} {culling:?}: {e}");
        }
        let mut a = args(&[], &[]);
        a.scenes.clear();
        assert!(Matrix::from_args(&a)
            .unwrap_err()
            .to_string()
            .contains("no scenes"));
    }

    #[test]
    fn a_toml_matrix_reads_like_the_options() {
        let dir = std::env::temp_dir().join(format!("tilegraph-matrix-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("m.toml");
        std::fs::write(
            &f,
            "scenes = [\"city:300\"]\nculling = [\"oq\"]\nsizes = [\"160x90\"]\nframes = 3\n[set]\noq_group = [1, 16]\n",
        )
        .unwrap();
        let m = Matrix::from_args(&BenchArgs {
            config: Some(f.clone()),
            out: "unused".into(),
            ..Default::default()
        })
        .unwrap();
        assert_eq!(m.sizes, vec![[160, 90]]);
        assert_eq!(m.frames, 3);
        assert_eq!(
            m.axes,
            vec![(
                "oq_group".to_string(),
                vec![KnobValue::Integer(1), KnobValue::Integer(16)]
            )]
        );
        std::fs::write(&f, "scenes = [\"city\"]\nculls = [\"oq\"]\n").unwrap();
        let e = Matrix::from_args(&BenchArgs {
            config: Some(f),
            out: "unused".into(),
            ..Default::default()
        })
        .unwrap_err()
        .to_string();
        std::fs::remove_dir_all(&dir).ok();
        assert!(e.contains("culls"), "{e}");
    }
}
