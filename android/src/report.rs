//! What the sample shows and logs, on any platform (tested on the host): the culling a touch
//! switches to, and the line logged every second.

use std::fmt::Write;

use tilegraph_passes::cull::Culling;
use tilegraph_vk::queries::FrameTimings;

/// The cullings a touch cycles through, in order.
pub const CYCLE: [Culling; 8] = Culling::STANDARD;

/// The culling after `current` among those `available` says the device can run (the first
/// when `current` is the last); `current` itself when no other is available.
pub fn next_culling(current: Culling, available: impl Fn(Culling) -> bool) -> Culling {
    let at = CYCLE.iter().position(|c| *c == current).unwrap_or(0);
    (1..=CYCLE.len())
        .map(|step| CYCLE[(at + step) % CYCLE.len()])
        .find(|c| available(*c))
        .unwrap_or(current)
}

/// One line: the culling, the frame rate over the last second, the CPU draw lists, the
/// instances culled on the GPU (when the technique reports them), and each pass's GPU time.
pub fn stats_line(
    culling: Culling,
    frames_per_second: f64,
    draws: usize,
    gpu_culled: Option<u32>,
    timings: Option<&FrameTimings>,
) -> String {
    let mut line = format!(
        "{} | {frames_per_second:.1} fps | {draws} draws",
        culling.name()
    );
    if let Some(c) = gpu_culled {
        let _ = write!(line, " | {c} culled on the GPU");
    }
    if let Some(t) = timings {
        let total: f64 = t.passes.iter().map(|p| p.gpu_ms).sum();
        let _ = write!(line, " | GPU passes {total:.2} ms:");
        for p in &t.passes {
            let _ = write!(line, " {} {:.2}", p.name, p.gpu_ms);
        }
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilegraph_vk::queries::PassTiming;

    #[test]
    fn a_touch_skips_what_the_device_cannot_run_and_wraps() {
        let no_conditional = |c: Culling| c != Culling::OqConditional;
        assert_eq!(
            next_culling(Culling::None, no_conditional),
            Culling::Frustum
        );
        assert_eq!(
            next_culling(Culling::Oq, no_conditional),
            Culling::RasterOcclusion
        );
        assert_eq!(
            next_culling(Culling::RasterOcclusion, no_conditional),
            Culling::SoftwareOcclusion
        );
        assert_eq!(
            next_culling(Culling::SoftwareOcclusion, no_conditional),
            Culling::None
        );
        assert_eq!(
            next_culling(Culling::Hiz, |c| c == Culling::Hiz),
            Culling::Hiz
        );
    }

    #[test]
    fn the_line_names_the_culling_and_every_pass() {
        let timings = FrameTimings {
            frame: 7,
            passes: vec![
                PassTiming {
                    name: "cull".into(),
                    begin_ticks: 0,
                    end_ticks: 10,
                    gpu_ms: 0.25,
                    vertex_invocations: None,
                    fragment_invocations: None,
                },
                PassTiming {
                    name: "opaque".into(),
                    begin_ticks: 10,
                    end_ticks: 50,
                    gpu_ms: 1.5,
                    vertex_invocations: None,
                    fragment_invocations: None,
                },
            ],
        };
        let line = stats_line(Culling::HizTwoPhase, 59.94, 120, Some(880), Some(&timings));
        assert_eq!(
            line,
            "hiz-2phase | 59.9 fps | 120 draws | 880 culled on the GPU | GPU passes 1.75 ms: cull 0.25 opaque 1.50"
        );
    }
}
