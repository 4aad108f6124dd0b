//! The CPU cost of software occlusion (docs/BENCHMARKS.md, "Software occlusion on the CPU"):
//! along a scene's camera path (or an eye-height walk), each frame's frustum culling on the
//! CPU and then `SoftwareCull::cull` — choosing occluders, rasterizing, testing every box — at
//! each buffer resolution and thread count, timed alone (no GPU). Prints the median and 95th
//! percentile milliseconds, and the instances in the frustum and hidden per frame.
//!
//! `cargo run --release -p tilegraph-passes --example software_cost -- SCENE [WxH] [FRAMES] [path|walk:SEED] [OCCLUDER_TRIANGLES]`

use tilegraph_passes::cull::cpu_frustum_visible_by_cell;
use tilegraph_passes::occlusion::{SoftwareCull, SoftwareOptions, SoftwareTarget};
use tilegraph_passes::RenderOptions;
use tilegraph_scene::{CameraPath, LooseGrid, MaterialClass};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene_name = args.next().unwrap_or_else(|| "city:100000".into());
    let (w, h) = args
        .next()
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or((1920u32, 1080u32));
    let frames: usize = args.next().map_or(Ok(48), |a| a.parse())?;
    let scene = tilegraph_scene::load(&scene_name)?;
    let path = match args.next().as_deref().and_then(|s| s.strip_prefix("walk")) {
        Some(seed) => {
            let seed = seed.trim_start_matches(':').parse().unwrap_or(1);
            CameraPath::eye_height_walk(&scene.bounds(), 240, seed)
        }
        None => scene.camera_path().clone(),
    };
    let budget: u32 = args
        .next()
        .map_or(Ok(SoftwareOptions::default().occluder_triangles), |a| {
            a.parse()
        })?;
    let mut grid = LooseGrid::new(scene.bounds(), scene.instances().len());
    for (i, inst) in scene.instances().iter().enumerate() {
        let blended = scene
            .instance_material(inst)
            .is_some_and(|m| m.class == MaterialClass::Blended);
        if inst.flags.is_drawn() && !blended {
            grid.insert(i as u32, inst.mesh.0, &inst.bounds);
        }
    }
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "{scene_name}, {w}x{h}, {} frames of its path, {threads} hardware threads, {budget} occluder triangles at most",
        frames.min(path.len())
    );
    println!(
        "| resolution | threads | median ms | p95 ms | in frustum | hidden | occluder triangles |"
    );
    println!("|---|---|---|---|---|---|---|");
    let aspect = w as f32 / h as f32;
    let mut visible = Vec::new();
    let mut cells = Vec::new();
    for resolution in [(256, 128), (512, 256)] {
        for t in [1, threads] {
            // The device's subpixel precision on lavapipe and desktop GPUs: 8 bits.
            let target = SoftwareTarget {
                size: (w, h),
                format: RenderOptions::default().depth_format,
                knobs: SoftwareOptions {
                    resolution,
                    threads: t,
                    occluder_triangles: budget,
                },
                subpixel_bits: 8,
            };
            let mut cull = SoftwareCull::default();
            let (mut ms, mut tested, mut hidden, mut triangles) = (Vec::new(), 0u64, 0u64, 0u64);
            for index in 0..frames.min(path.len()) {
                let Some(frame) = path.frame(index, aspect) else {
                    break;
                };
                cpu_frustum_visible_by_cell(&grid, &frame.current, &mut visible, &mut cells)?;
                cull.cull(&scene, &frame, &target, &cells, &mut visible)?;
                ms.push(cull.last.cpu_ms);
                tested += u64::from(cull.last.tested);
                hidden += u64::from(cull.last.culled);
                triangles += u64::from(cull.last.raster.triangles);
            }
            let n = ms.len().max(1) as u64;
            ms.sort_by(f64::total_cmp);
            let at = |q: f64| {
                ms.get(((ms.len() as f64 - 1.0) * q).round() as usize)
                    .copied()
            };
            println!(
                "| {}x{} | {t} | {:.3} | {:.3} | {} | {} | {} |",
                resolution.0,
                resolution.1,
                at(0.5).unwrap_or(0.0),
                at(0.95).unwrap_or(0.0),
                tested / n,
                hidden / n,
                triangles / n
            );
        }
    }
    Ok(())
}
