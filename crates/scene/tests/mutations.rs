//! The stable stand-in for the fuzz target: thousands of truncated and byte-flipped versions of
//! each shipped scene, of a GLB generated here, and of the validator's files. The loader must
//! return `Ok` (a scene whose invariants hold) or an error, never panic.

mod common;

use std::path::Path;
use std::time::Instant;

use tilegraph_scene::{
    export, generate, load_gltf_bytes, Limits, MemoryResources, NoResources, ProceduralKind,
    ProceduralParams, ResourceResolver, Scene,
};

/// xorshift64*: a fixed, dependency-free stream so failures reproduce.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// One mutation of `input`: a truncation, 1-4 byte flips, or (for text) a digit replaced by
/// another digit or grown by up to 19 more, which keeps JSON valid and so reaches the checks
/// behind the parser (huge offsets and counts included).
fn mutate(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut v = input.to_vec();
    match rng.below(5) {
        4 => {
            let digits: Vec<usize> = (0..v.len()).filter(|&i| v[i].is_ascii_digit()).collect();
            if !digits.is_empty() {
                let at = digits[rng.below(digits.len())];
                let grow: Vec<u8> = (0..1 + rng.below(19))
                    .map(|_| b'0' + rng.below(10) as u8)
                    .collect();
                v.splice(at..at, grow);
            }
        }
        0 => v.truncate(rng.below(v.len())),
        1 => {
            for _ in 0..1 + rng.below(4) {
                let i = rng.below(v.len());
                v[i] ^= 1 + rng.below(255) as u8;
            }
        }
        _ => {
            let digits: Vec<usize> = (0..v.len()).filter(|&i| v[i].is_ascii_digit()).collect();
            if digits.is_empty() {
                let i = rng.below(v.len());
                v[i] ^= 0x20;
            } else {
                for _ in 0..1 + rng.below(2) {
                    let i = digits[rng.below(digits.len())];
                    v[i] = b'0' + rng.below(10) as u8;
                }
            }
        }
    }
    v
}

/// What an `Ok` scene must satisfy whatever the input was.
fn check_invariants(s: &Scene, what: &str) {
    for m in s.meshes() {
        let first = m.first_index as usize;
        let idx = &s.indices()[first..first + m.index_count as usize];
        assert!(
            idx.iter().all(|&i| i < m.vertex_count),
            "{what}: index past its mesh"
        );
        assert!(
            m.vertex_offset >= 0
                && (m.vertex_offset as usize + m.vertex_count as usize) <= s.vertices().len()
        );
        assert!((m.material.0 as usize) < s.materials().len(), "{what}");
    }
    for i in s.instances() {
        assert!((i.mesh.0 as usize) < s.meshes().len(), "{what}");
        assert!(
            i.bounds.center.is_finite() && i.bounds.radius.is_finite(),
            "{what}"
        );
    }
    let b = s.bounds();
    assert!(b.min.is_finite() && b.max.is_finite(), "{what}");
}

struct Stats {
    ok: usize,
    err: usize,
}

fn run(
    name: &str,
    input: &[u8],
    resolver: &dyn ResourceResolver,
    n: usize,
    seed: u64,
    stats: &mut Stats,
) {
    let mut rng = Rng(seed);
    let mut panics = Vec::new();
    for k in 0..n {
        let bytes = mutate(input, &mut rng);
        match common::no_panic(|| load_gltf_bytes(&bytes, name, resolver, &Limits::default())) {
            Ok(Ok(scene)) => {
                check_invariants(&scene, &format!("{name} mutation {k}"));
                stats.ok += 1;
            }
            Ok(Err(_)) => stats.err += 1,
            Err(msg) => panics.push(format!("{name} mutation {k} (seed {seed}): {msg}")),
        }
    }
    assert!(panics.is_empty(), "panics:\n{}", panics.join("\n"));
}

#[test]
fn generated_glb_survives_mutation() {
    let scene = generate(ProceduralKind::City, ProceduralParams { size: 64, seed: 5 }).unwrap();
    let glb = export::to_glb(&scene);
    let start = Instant::now();
    let mut stats = Stats { ok: 0, err: 0 };
    run(
        "city.glb",
        &glb,
        &NoResources,
        3_000,
        0x5EED_0001,
        &mut stats,
    );
    // Every truncation of a GLB must fail (its header declares the full length).
    for n in (0..glb.len()).step_by(7) {
        assert!(load_gltf_bytes(&glb[..n], "city.glb", &NoResources, &Limits::default()).is_err());
    }
    println!(
        "city.glb ({} bytes): {} ok, {} errors in {:?}",
        glb.len(),
        stats.ok,
        stats.err,
        start.elapsed()
    );
    assert!(
        stats.ok > 0 && stats.err > 0,
        "mutations should reach both outcomes"
    );
}

#[test]
fn shipped_scenes_survive_mutation() {
    let Some(root) = common::test_data("scenes") else {
        return;
    };
    let mut dirs: Vec<_> = std::fs::read_dir(&root)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    dirs.sort();
    for dir in dirs.iter().filter(|d| d.is_dir()) {
        for file in std::fs::read_dir(dir).unwrap().flatten().map(|e| e.path()) {
            let ext = file.extension().and_then(|e| e.to_str()).unwrap_or("");
            if ext != "gltf" && ext != "glb" {
                continue;
            }
            mutate_scene_file(dir, &file);
        }
    }
}

fn mutate_scene_file(dir: &Path, file: &Path) {
    let start = Instant::now();
    let name = file.file_name().unwrap().to_string_lossy().to_string();
    let bytes = std::fs::read(file).unwrap();
    // External files held in memory, so mutating them costs no disk I/O.
    let mut res = MemoryResources::default();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p != file && p.is_file() {
            res.files.insert(
                p.file_name().unwrap().to_string_lossy().to_string(),
                std::fs::read(&p).unwrap(),
            );
        }
    }
    let mut stats = Stats { ok: 0, err: 0 };
    run(&name, &bytes, &res, 2_500, 0x5EED_0002, &mut stats);
    // Mutate each external buffer too (fewer: an intact one loads the whole scene).
    let buffers: Vec<(String, Vec<u8>)> = res
        .files
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let mut rng = Rng(0x5EED_0003);
    let mut panics = Vec::new();
    for (key, data) in &buffers {
        for k in 0..60 {
            let mut r = res.clone();
            let mutated = if k % 3 == 0 {
                data[..rng.below(data.len())].to_vec()
            } else {
                mutate(data, &mut rng)
            };
            r.files.insert(key.clone(), mutated);
            match common::no_panic(|| load_gltf_bytes(&bytes, &name, &r, &Limits::default())) {
                Ok(Ok(scene)) => {
                    check_invariants(&scene, &format!("{key} mutation {k}"));
                    stats.ok += 1;
                }
                Ok(Err(_)) => stats.err += 1,
                Err(msg) => panics.push(format!("{key} mutation {k}: {msg}")),
            }
        }
    }
    assert!(panics.is_empty(), "panics:\n{}", panics.join("\n"));
    println!(
        "{name}: {} ok, {} errors in {:?}",
        stats.ok,
        stats.err,
        start.elapsed()
    );
}

#[test]
fn validator_files_survive_mutation() {
    let Some(root) = common::test_data("gltf-validator") else {
        return;
    };
    let start = Instant::now();
    let mut stats = Stats { ok: 0, err: 0 };
    let mut stack = vec![root];
    let mut files = Vec::new();
    while let Some(d) = stack.pop() {
        for p in std::fs::read_dir(&d).unwrap().flatten().map(|e| e.path()) {
            if p.is_dir() {
                stack.push(p);
            } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
                files.push(p);
            }
        }
    }
    files.sort();
    for (i, f) in files.iter().enumerate() {
        let bytes = std::fs::read(f).unwrap();
        if bytes.is_empty() {
            continue;
        }
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        run(
            &name,
            &bytes,
            &NoResources,
            20,
            0x5EED_1000 + i as u64,
            &mut stats,
        );
    }
    println!(
        "validator files: {} ok, {} errors in {:?}",
        stats.ok,
        stats.err,
        start.elapsed()
    );
}
