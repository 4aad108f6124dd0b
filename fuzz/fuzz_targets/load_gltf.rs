//! Feeds arbitrary bytes to the scene loader's from-bytes entry point. Any panic, overflow or
//! out-of-bounds access is a bug: every input must give a scene or a typed error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use tilegraph_scene::{load_gltf_bytes, Limits, NoResources};

/// Small limits: the fuzzer should find logic errors, not spend its time allocating gigabytes
/// for inputs that ask for them legitimately.
const LIMITS: Limits = Limits {
    max_vertices: 1 << 20,
    max_indices: 1 << 22,
    max_instances: 1 << 20,
    max_texture_pixels: 1 << 20,
    max_texture_pixels_total: 1 << 22,
};

fuzz_target!(|data: &[u8]| {
    // Both names: ".glb" forces the GLB container path even without the magic.
    for name in ["fuzz.gltf", "fuzz.glb"] {
        if let Ok(scene) = load_gltf_bytes(data, name, &NoResources, &LIMITS) {
            // Exercise what a renderer does first with a loaded scene.
            let _ = scene.info();
            let _ = scene.gpu_instances(scene.bounds().center());
        }
    }
});
