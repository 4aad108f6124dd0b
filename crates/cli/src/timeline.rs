//! Where each pass ran in the frame, per queue: the median start and end of every pass since the
//! frame's first timestamp, over the frames `render` timed per pass, and how much of the async
//! compute queue's work ran beside the graphics queue's. Timestamps of the two queues are read
//! on one clock (the device's; true of the desktop drivers measured, not promised by Vulkan).

use std::collections::BTreeMap;

use serde::Serialize;
use tilegraph_graph::{Plan, Queue};
use tilegraph_vk::queries::FrameTimings;

/// One pass's place in the frame: medians, milliseconds since the frame's first timestamp.
#[derive(Debug, Clone, Serialize)]
pub struct PassSpan {
    pub pass: String,
    pub queue: &'static str,
    pub start_ms: f64,
    pub end_ms: f64,
}

/// The frames' pass spans, gathered one collected frame at a time.
#[derive(Default)]
pub struct Timeline {
    /// The last frame gathered (a frame is collected once, but seen after several renders).
    last_frame: Option<u64>,
    starts: BTreeMap<String, Vec<f64>>,
    ends: BTreeMap<String, Vec<f64>>,
    /// Pass names in the order of the first frame gathered.
    order: Vec<String>,
}

impl Timeline {
    /// Adds `timings` (the latest collected frame) unless it was added already.
    /// `period_ns`: nanoseconds per timestamp tick.
    pub fn gather(&mut self, timings: Option<&FrameTimings>, period_ns: f64) {
        let Some(t) = timings else { return };
        if self.last_frame == Some(t.frame) || t.passes.is_empty() {
            return;
        }
        self.last_frame = Some(t.frame);
        let Some(origin) = t.passes.iter().map(|p| p.begin_ticks).min() else {
            return;
        };
        let ms = |ticks: u64| ticks.saturating_sub(origin) as f64 * period_ns / 1e6;
        for p in &t.passes {
            if !self.starts.contains_key(&p.name) {
                self.order.push(p.name.clone());
            }
            self.starts
                .entry(p.name.clone())
                .or_default()
                .push(ms(p.begin_ticks));
            self.ends
                .entry(p.name.clone())
                .or_default()
                .push(ms(p.end_ticks));
        }
    }

    /// The medians, each pass with the queue `plan` ran it on.
    pub fn spans(&self, plan: Option<&Plan>) -> Vec<PassSpan> {
        self.order
            .iter()
            .filter_map(|name| {
                let queue = plan
                    .and_then(|p| p.pass_by_name(name))
                    .map_or(Queue::Graphics, |p| p.queue);
                Some(PassSpan {
                    pass: name.clone(),
                    queue: queue.name(),
                    start_ms: median(self.starts.get(name)?)?,
                    end_ms: median(self.ends.get(name)?)?,
                })
            })
            .collect()
    }
}

fn median(samples: &[f64]) -> Option<f64> {
    let mut v = samples.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

/// Where the async compute queue's passes ran against the graphics queue's (milliseconds).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Overlap {
    /// The async queue's passes, their union.
    pub busy_ms: f64,
    /// Of it, while a graphics pass ran.
    pub beside_passes_ms: f64,
    /// Of it, between two graphics passes: while the graphics queue ran its barriers, clears
    /// and load/store operations, or waited.
    pub between_passes_ms: f64,
}

/// The async compute queue's busy time against the graphics queue's passes (the union of each
/// queue's spans, then their intersections). `None` when no pass ran on the async queue.
pub fn overlap(spans: &[PassSpan]) -> Option<Overlap> {
    let busy = |queue: Queue| union(spans.iter().filter(|s| s.queue == queue.name()));
    let compute = busy(Queue::AsyncCompute);
    if compute.is_empty() {
        return None;
    }
    let graphics = busy(Queue::Graphics);
    let intersect = |x: &[(f64, f64)], y: &[(f64, f64)]| {
        let mut sum = 0.0;
        for &(a, b) in x {
            for &(c, d) in y {
                sum += (b.min(d) - a.max(c)).max(0.0);
            }
        }
        sum
    };
    let beside = intersect(&compute, &graphics);
    let frame = match (graphics.first(), graphics.last()) {
        (Some(first), Some(last)) => vec![(first.0, last.1)],
        _ => Vec::new(),
    };
    Some(Overlap {
        busy_ms: compute.iter().map(|(a, b)| b - a).sum(),
        beside_passes_ms: beside,
        between_passes_ms: (intersect(&compute, &frame) - beside).max(0.0),
    })
}

/// Disjoint intervals covering the spans, in order.
fn union<'a>(spans: impl Iterator<Item = &'a PassSpan>) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = spans
        .map(|s| (s.start_ms, s.end_ms.max(s.start_ms)))
        .collect();
    v.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(v.len());
    for (a, b) in v {
        match out.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(queue: Queue, start_ms: f64, end_ms: f64) -> PassSpan {
        PassSpan {
            pass: String::new(),
            queue: queue.name(),
            start_ms,
            end_ms,
        }
    }

    #[test]
    fn overlap_splits_the_async_time_by_what_the_graphics_queue_did() {
        let spans = [
            span(Queue::Graphics, 0.0, 1.0),
            span(Queue::Graphics, 0.5, 1.5),
            span(Queue::Graphics, 3.0, 4.0),
            span(Queue::AsyncCompute, 1.0, 2.0),
            span(Queue::AsyncCompute, 1.2, 1.4),
            span(Queue::AsyncCompute, 2.5, 3.5),
        ];
        let o = overlap(&spans).unwrap_or_default();
        assert!((o.busy_ms - 2.0).abs() < 1e-9, "{o:?}");
        assert!((o.beside_passes_ms - 1.0).abs() < 1e-9, "{o:?}");
        // [1.5, 2.0] and [2.5, 3.0] lie between graphics passes.
        assert!((o.between_passes_ms - 1.0).abs() < 1e-9, "{o:?}");
        assert!(overlap(&spans[..3]).is_none());
    }
}
