//! Why the plan is what it is: every merge (or split) of raster passes into render passes, every
//! attachment's load and store op, every barrier's hazard, and each attachment's memory traffic
//! against the naive plan (load and store everything). `tilegraph graph` prints it; it answers
//! the question a render-graph viewer exists for — why are these two passes not one render pass?

use std::fmt;

use crate::declare::{InitialContent, Origin, ResourceId};
use crate::plan::{MergeReason, Plan, Queue, Step, StepIndex, WaitReason};
use crate::types::{LoadOp, StoreOp};

/// What a line explains.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topic {
    Merge,
    Load,
    Store,
    Barrier,
    Traffic,
    /// Which queue an async-capable pass runs on.
    Queue,
    /// A submission's wait on the other queue.
    Wait,
}

impl Topic {
    pub const fn name(self) -> &'static str {
        match self {
            Topic::Merge => "merge",
            Topic::Load => "load",
            Topic::Store => "store",
            Topic::Barrier => "barrier",
            Topic::Traffic => "traffic",
            Topic::Queue => "queue",
            Topic::Wait => "wait",
        }
    }
}

/// One decision and its reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reason {
    /// The step it is about (the render pass or barrier batch).
    pub step: Option<StepIndex>,
    pub topic: Topic,
    /// What the decision is about: a pass, or a resource.
    pub subject: String,
    /// The decision: `joins opaque`, `CLEAR`, `DONT_CARE`, `ReadAfterWrite`, `1.2 MiB of 2.3 MiB`.
    pub decision: String,
    pub why: String,
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.step {
            Some(s) => write!(f, "step {:>3} ", s.0)?,
            None => f.write_str("         ")?,
        }
        write!(
            f,
            "{:<8} {:<24} {:<26} {}",
            self.topic.name(),
            self.subject,
            self.decision,
            self.why
        )
    }
}

fn load_name(op: LoadOp) -> &'static str {
    match op {
        LoadOp::Load => "LOAD",
        LoadOp::Clear => "CLEAR",
        LoadOp::DontCare => "DONT_CARE",
    }
}

fn store_name(op: StoreOp) -> &'static str {
    match op {
        StoreOp::Store => "STORE",
        StoreOp::DontCare => "DONT_CARE",
        StoreOp::None => "NONE",
    }
}

fn mib(bytes: u64) -> String {
    format!("{:.2} MiB", bytes as f64 / f64::from(1u32 << 20))
}

impl Plan {
    /// The surviving passes that use `r` in a step before (`before = true`) or after `step`,
    /// nearest first.
    fn users(&self, r: ResourceId, step: StepIndex, before: bool) -> Vec<(&str, bool)> {
        let mut found: Vec<(StepIndex, &str, bool)> = self
            .passes
            .iter()
            .filter(|p| {
                if before {
                    p.step.0 < step.0
                } else {
                    p.step.0 > step.0
                }
            })
            .filter_map(|p| {
                p.uses
                    .iter()
                    .find(|u| u.resource == r)
                    .map(|u| (p.step, p.name.as_str(), u.kind.writes()))
            })
            .collect();
        found.sort_by_key(|(s, _, _)| if before { u32::MAX - s.0 } else { s.0 });
        found.into_iter().map(|(_, n, w)| (n, w)).collect()
    }

    /// Every merge, load and store op, barrier and attachment's traffic, with its reason, in
    /// step order (merges first).
    pub fn explain(&self) -> Vec<Reason> {
        let mut out = Vec::new();
        for m in &self.merges {
            let step = self.pass(m.pass).map(|p| p.step);
            let after = self.pass_name(m.after).to_string();
            let (decision, why) = match m.reason {
                MergeReason::SharesAttachment(r) => (
                    format!("joins {after}"),
                    format!(
                        "same render area, and both use {} as an attachment at the same pixel: it stays on chip between them",
                        self.resource_name(r)
                    ),
                ),
                MergeReason::NotAdjacent => (
                    "new render pass".into(),
                    format!("a compute or transfer step lies between it and {after}"),
                ),
                MergeReason::MergingOff => (
                    "new render pass".into(),
                    format!("profile {} never merges subpasses", self.profile),
                ),
                MergeReason::RenderArea => (
                    "new render pass".into(),
                    format!("its render area differs from {after}'s"),
                ),
                MergeReason::QueriesApart => (
                    "new render pass".into(),
                    format!(
                        "profile {} keeps occlusion-query passes in a render pass of their own",
                        self.profile
                    ),
                ),
                MergeReason::Clears(r) => (
                    "new render pass".into(),
                    format!(
                        "it clears {}, which the render pass already uses: a clear is only a render pass's load op",
                        self.resource_name(r)
                    ),
                ),
                MergeReason::DescriptorAccess(r) => (
                    "new render pass".into(),
                    format!(
                        "{} is read through a descriptor on one side and an attachment (or written) on the other: outside the subpass dependencies",
                        self.resource_name(r)
                    ),
                ),
                MergeReason::NothingShared => (
                    "new render pass".into(),
                    format!(
                        "it shares no attachment with {after}: merging would only grow the tile footprint"
                    ),
                ),
            };
            out.push(Reason {
                step,
                topic: Topic::Merge,
                subject: self.pass_name(m.pass).to_string(),
                decision,
                why,
            });
        }
        for (i, step) in self.steps.iter().enumerate() {
            let at = StepIndex(i as u32);
            match step {
                Step::RenderPass(rp) => {
                    let px = u64::from(rp.render_area_px.width_px)
                        * u64::from(rp.render_area_px.height_px);
                    for a in &rp.attachments {
                        self.explain_attachment(&mut out, at, rp, a, px);
                    }
                }
                Step::Barriers(batch) => {
                    let image = batch.images.iter().map(|b| {
                        let layouts = if b.old_layout == b.new_layout {
                            format!("{:?}", b.new_layout)
                        } else {
                            format!("{:?} -> {:?}", b.old_layout, b.new_layout)
                        };
                        (b.resource, b.hazard, layouts)
                    });
                    let buffer = batch
                        .buffers
                        .iter()
                        .map(|b| (b.resource, b.hazard, String::new()));
                    for (r, hazard, layouts) in image.chain(buffer) {
                        let prev = self.users(r, at, true).first().map(|(n, _)| n.to_string());
                        let next = self.users(r, at, false).first().map(|(n, _)| n.to_string());
                        let why = match (hazard, prev, next) {
                            (crate::Hazard::Release, Some(p), _) => format!(
                                "after {p}: leaves it in the state its import asks for {layouts}"
                            ),
                            (crate::Hazard::Aliasing, _, Some(n)) => format!(
                                "{n} is the first use of memory an earlier resource used {layouts}"
                            ),
                            (_, Some(p), Some(n)) => format!("{p} -> {n} {layouts}"),
                            (_, None, Some(n)) => {
                                format!("before {n}: from the state it was imported in {layouts}")
                            }
                            (_, Some(p), None) => format!("after {p} {layouts}"),
                            (_, None, None) => layouts,
                        };
                        out.push(Reason {
                            step: Some(at),
                            topic: Topic::Barrier,
                            subject: self.resource_name(r).to_string(),
                            decision: hazard.name().to_string(),
                            why: why.trim_end().to_string(),
                        });
                    }
                }
                Step::Compute { .. } | Step::Transfer { .. } | Step::Flush(_) => {}
            }
        }
        self.explain_queues(&mut out);
        out
    }

    /// Where each async-capable pass runs, and why each submission waits on the other queue.
    fn explain_queues(&self, out: &mut Vec<Reason>) {
        for p in self.passes.iter().filter(|p| p.async_capable) {
            let why = if p.queue == Queue::AsyncCompute {
                "declared async-capable, and async compute is on (the profile's `[queues]`, or the context's override): it runs beside the raster work".to_string()
            } else if self.async_compute {
                "declared async-capable and async compute is on, but every raster pass waits on it, comes before it or (exclusive sharing) takes turns with it on an image: on the async queue it would only add waits".to_string()
            } else {
                format!(
                    "declared async-capable, but async compute is off (profile {}, or a device without a second queue)",
                    self.profile
                )
            };
            out.push(Reason {
                step: Some(p.step),
                topic: Topic::Queue,
                subject: p.name.clone(),
                decision: p.queue.name().to_string(),
                why,
            });
        }
        if self.submissions.len() < 2 {
            return;
        }
        for (k, s) in self.submissions.iter().enumerate() {
            for w in &s.waits {
                let other = self
                    .submissions
                    .get(w.submission.index())
                    .map_or("other", |o| o.queue.name());
                for r in &w.reasons {
                    let why = match r {
                        WaitReason::Resource {
                            resource,
                            hazard,
                            transfer,
                        } => format!(
                            "{} of {}: the {other} queue used it last{}",
                            hazard.name(),
                            self.resource_name(*resource),
                            if *transfer {
                                "; its content moves to this queue's family (exclusive sharing)"
                            } else {
                                ""
                            }
                        ),
                        WaitReason::FrameStart => "the async queue starts after the frame began on the graphics queue: earlier frames' use of the same memory and the imports' producers are behind it".into(),
                        WaitReason::Join => "the frame ends on the graphics queue after the async queue's last work: one fence covers both".into(),
                    };
                    out.push(Reason {
                        step: (s.first != s.end).then_some(s.first),
                        topic: Topic::Wait,
                        subject: format!("submission {k} ({})", s.queue.name()),
                        decision: format!("waits for {} at {}", w.submission.0, w.dst_stages),
                        why,
                    });
                }
            }
        }
    }

    fn explain_attachment(
        &self,
        out: &mut Vec<Reason>,
        at: StepIndex,
        rp: &crate::plan::RenderPass,
        a: &crate::plan::Attachment,
        px: u64,
    ) {
        let name = self.resource_name(a.resource).to_string();
        let resource = self.resources.get(a.resource.index());
        let preserved_import = resource.is_some_and(
            |r| matches!(&r.origin, Origin::Imported(i) if i.content == InitialContent::Preserve),
        );
        let first_user = rp
            .subpasses
            .iter()
            .find(|s| {
                s.colors
                    .iter()
                    .chain(s.depth_stencil.iter())
                    .chain(s.inputs.iter())
                    .chain(s.resolves.iter().flatten())
                    .any(|r| rp.attachments.get(r.attachment.0 as usize) == Some(a))
            })
            .map_or_else(String::new, |s| self.pass_name(s.pass).to_string());
        let before = self.users(a.resource, at, true);
        let after = self.users(a.resource, at, false);
        let load_why = match a.load_op {
            LoadOp::Clear => format!("{first_user} clears it at its first use"),
            LoadOp::Load => match before.iter().find(|(_, w)| *w) {
                Some((w, _)) => {
                    format!("{first_user} needs what {w} wrote before this render pass")
                }
                None => "imported with its content, which this render pass needs".into(),
            },
            LoadOp::DontCare => {
                if preserved_import || before.iter().any(|(_, w)| *w) {
                    format!("{first_user} overwrites every pixel before reading any: the old content is not needed")
                } else {
                    "nothing before this render pass wrote it: no content to load".into()
                }
            }
        };
        out.push(Reason {
            step: Some(at),
            topic: Topic::Load,
            subject: name.clone(),
            decision: load_name(a.load_op).into(),
            why: load_why,
        });
        let exported = resource.is_some_and(|r| matches!(r.origin, Origin::Imported(_)));
        let store_why = match a.store_op {
            StoreOp::Store => match after.first() {
                Some((n, _)) => format!("{n} uses it after this render pass"),
                None if exported => {
                    "the frame hands it on (exported or imported): its content must reach memory"
                        .into()
                }
                None => "its content is needed after the frame".into(),
            },
            StoreOp::None => {
                "this render pass only read it: kept without a write-back (STORE_OP_NONE)".into()
            }
            StoreOp::DontCare => {
                "nothing after this render pass reads it: dropped in tile memory".into()
            }
        };
        out.push(Reason {
            step: Some(at),
            topic: Topic::Store,
            subject: name.clone(),
            decision: store_name(a.store_op).into(),
            why: store_why,
        });
        let bytes = px * u64::from(a.format.bytes_per_pixel()) * u64::from(a.samples.count());
        let planned = bytes
            * (u64::from(a.load_op == LoadOp::Load) + u64::from(a.store_op == StoreOp::Store));
        out.push(Reason {
            step: Some(at),
            topic: Topic::Traffic,
            subject: name,
            decision: format!("{} of {}", mib(planned), mib(2 * bytes)),
            why: format!(
                "{} / {} of {} px x {} B: {} moved; loading and storing it every render pass would move {}",
                load_name(a.load_op),
                store_name(a.store_op),
                px,
                a.format.bytes_per_pixel() * a.samples.count(),
                mib(planned),
                mib(2 * bytes)
            ),
        });
    }
}
