//! Printing a plan as tables a person can read in a terminal (and diff in snapshot tests).

use std::fmt::{self, Write as _};

use crate::declare::{Origin, PassUse, ResourceDesc};
use crate::plan::{
    AttachmentRef, BarrierBatch, Plan, PruneReason, Queue, QueueTransfer, RenderPass, Step,
    StepRange, Subpass, TrafficBreakdown, Usage, WaitReason,
};

/// `1536 B`, `12.0 KiB`, `7.91 MiB`.
pub(crate) fn fmt_bytes(bytes: u64) -> String {
    const KIB: f64 = 1024.0;
    if bytes < 1024 {
        format!("{bytes} B")
    } else if bytes < 1024 * 1024 {
        format!("{:.1} KiB", bytes as f64 / KIB)
    } else {
        format!("{:.2} MiB", bytes as f64 / (KIB * KIB))
    }
}

/// Left-aligned columns separated by two spaces, each row indented.
fn table(f: &mut fmt::Formatter<'_>, indent: &str, rows: &[Vec<String>]) -> fmt::Result {
    let columns = rows.iter().map(Vec::len).max().unwrap_or(0);
    let mut widths = vec![0usize; columns];
    for row in rows {
        for (i, cell) in row.iter().enumerate() {
            widths[i] = widths[i].max(cell.chars().count());
        }
    }
    for row in rows {
        let mut line = String::from(indent);
        for (i, cell) in row.iter().enumerate() {
            if i + 1 == row.len() {
                line.push_str(cell);
            } else {
                let _ = write!(line, "{:<w$}  ", cell, w = widths[i]);
            }
        }
        writeln!(f, "{}", line.trim_end())?;
    }
    Ok(())
}

fn row<const N: usize>(cells: [String; N]) -> Vec<String> {
    cells.into()
}

impl Plan {
    pub(crate) fn resource_name(&self, id: crate::declare::ResourceId) -> &str {
        self.resources
            .get(id.index())
            .map_or("?", |r| r.name.as_str())
    }

    pub(crate) fn pass_name(&self, id: crate::declare::PassId) -> &str {
        self.passes
            .iter()
            .find(|p| p.id == id)
            .map(|p| p.name.as_str())
            .or_else(|| {
                self.pruned
                    .iter()
                    .find(|p| p.id == id)
                    .map(|p| p.name.as_str())
            })
            .unwrap_or("?")
    }

    fn uses_text(&self, uses: &[PassUse]) -> String {
        let mut out = String::new();
        for (i, u) in uses.iter().enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            let _ = write!(out, "{} {}", u.kind.name(), self.resource_name(u.resource));
        }
        out
    }

    fn lifetime_text(life: Option<StepRange>) -> String {
        match life {
            Some(l) if l.first == l.last => format!("{}", l.first.0),
            Some(l) => format!("{}..{}", l.first.0, l.last.0),
            None => "-".into(),
        }
    }

    fn attachment_ref_text(&self, rp: &RenderPass, r: &AttachmentRef) -> String {
        let name = rp
            .attachments
            .get(r.attachment.0 as usize)
            .map_or("?", |a| self.resource_name(a.resource));
        format!("#{} {} ({})", r.attachment.0, name, r.layout)
    }

    fn subpass_text(&self, rp: &RenderPass, s: &Subpass) -> String {
        let mut parts: Vec<String> = Vec::new();
        for (i, c) in s.colors.iter().enumerate() {
            let mut text = format!("color {}", self.attachment_ref_text(rp, c));
            if let Some(Some(r)) = s.resolves.get(i) {
                let _ = write!(text, " resolve-> {}", self.attachment_ref_text(rp, r));
            }
            parts.push(text);
        }
        if let Some(d) = &s.depth_stencil {
            parts.push(format!("depth {}", self.attachment_ref_text(rp, d)));
        }
        for i in &s.inputs {
            parts.push(format!("input {}", self.attachment_ref_text(rp, i)));
        }
        if !s.preserve.is_empty() {
            let list: Vec<String> = s.preserve.iter().map(|p| format!("#{}", p.0)).collect();
            parts.push(format!("preserve {}", list.join(" ")));
        }
        parts.join("; ")
    }

    fn fmt_render_pass(&self, f: &mut fmt::Formatter<'_>, rp: &RenderPass) -> fmt::Result {
        let mut rows = vec![row([
            "#".into(),
            "attachment".into(),
            "format".into(),
            "load".into(),
            "store".into(),
            "stencil".into(),
            "layouts".into(),
            "clear".into(),
            "memory".into(),
        ])];
        for (i, a) in rp.attachments.iter().enumerate() {
            let stencil = if a.format.has_stencil() {
                format!("{}/{}", a.stencil_load_op.name(), a.stencil_store_op.name())
            } else {
                "-".into()
            };
            rows.push(row([
                format!("#{i}"),
                self.resource_name(a.resource).to_string(),
                format!("{} {}", a.format, a.samples),
                a.load_op.name().into(),
                a.store_op.name().into(),
                stencil,
                format!("{} -> {}", a.initial_layout, a.final_layout),
                a.clear.map_or("-".into(), |c| c.to_string()),
                a.residency.name().into(),
            ]));
        }
        table(f, "       ", &rows)?;
        for (i, s) in rp.subpasses.iter().enumerate() {
            writeln!(
                f,
                "       subpass {i} {}: {}",
                self.pass_name(s.pass),
                self.subpass_text(rp, s)
            )?;
        }
        for d in &rp.dependencies {
            writeln!(
                f,
                "       dependency {} -> {}: {} / {} -> {} / {}",
                d.src_subpass.0,
                d.dst_subpass.0,
                d.src_stages,
                d.src_access,
                d.dst_stages,
                d.dst_access
            )?;
        }
        Ok(())
    }

    /// The rows of a barrier batch (a transfer's half named after its hazard).
    fn batch_rows(&self, batch: &BarrierBatch) -> Vec<Vec<String>> {
        let hazard = |h: crate::plan::Hazard, t: Option<QueueTransfer>, release: bool| match t {
            Some(t) if release => format!("{} release to {}", h.name(), t.to.name()),
            Some(t) => format!("{} acquire from {}", h.name(), t.from.name()),
            None => h.name().to_string(),
        };
        let release = batch
            .images
            .iter()
            .map(|b| b.dst_stages)
            .chain(batch.buffers.iter().map(|b| b.dst_stages))
            .all(|s| s.is_empty());
        let mut rows = Vec::new();
        for b in &batch.images {
            rows.push(row([
                self.resource_name(b.resource).to_string(),
                hazard(b.hazard, b.queue_transfer, release),
                format!("{} -> {}", b.old_layout, b.new_layout),
                format!("{} / {}", b.src_stages, b.src_access),
                "->".into(),
                format!("{} / {}", b.dst_stages, b.dst_access),
            ]));
        }
        for b in &batch.buffers {
            rows.push(row([
                self.resource_name(b.resource).to_string(),
                hazard(b.hazard, b.queue_transfer, release),
                "buffer".into(),
                format!("{} / {}", b.src_stages, b.src_access),
                "->".into(),
                format!("{} / {}", b.dst_stages, b.dst_access),
            ]));
        }
        rows
    }

    /// A submission's heading: its queue and what it waits for (plans of two queues).
    fn fmt_submission(&self, f: &mut fmt::Formatter<'_>, k: usize) -> fmt::Result {
        let Some(s) = self.submissions.get(k) else {
            return Ok(());
        };
        writeln!(f, "  submission {k} on the {} queue", s.queue.name())?;
        for w in &s.waits {
            let reasons: Vec<String> = w
                .reasons
                .iter()
                .map(|r| match r {
                    WaitReason::Resource {
                        resource,
                        hazard,
                        transfer,
                    } => format!(
                        "{} {}{}",
                        hazard.name(),
                        self.resource_name(*resource),
                        if *transfer { " (ownership)" } else { "" }
                    ),
                    WaitReason::FrameStart => "frame start".into(),
                    WaitReason::Join => "join".into(),
                })
                .collect();
            writeln!(
                f,
                "       waits for submission {} at {}: {}",
                w.submission.0,
                w.dst_stages,
                reasons.join(", ")
            )?;
        }
        if s.first == s.end && !s.releases.is_empty() {
            writeln!(f, "       releases ({})", s.releases.len())?;
            table(f, "       ", &self.batch_rows(&s.releases))?;
        }
        Ok(())
    }

    fn fmt_steps(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "steps")?;
        let queues = self.submissions.len() > 1;
        let mut next = 0;
        for (i, step) in self.steps.iter().enumerate() {
            while queues
                && self
                    .submissions
                    .get(next)
                    .is_some_and(|s| s.first.index() <= i)
            {
                self.fmt_submission(f, next)?;
                next += 1;
            }
            match step {
                Step::Barriers(batch) => {
                    writeln!(f, "  {i:>3}  barriers ({})", batch.len())?;
                    table(f, "       ", &self.batch_rows(batch))?;
                }
                Step::RenderPass(rp) => {
                    let budget = match self.tile_budget_bytes_per_px {
                        Some(b) if rp.on_chip_bytes_per_px > b => {
                            format!(" of {b}: over the tile budget, the driver shrinks tiles")
                        }
                        Some(b) => format!(" of {b}"),
                        None => String::new(),
                    };
                    writeln!(
                        f,
                        "  {i:>3}  render pass {} px, {} subpass{}, on-chip {} B/px{budget}",
                        rp.render_area_px,
                        rp.subpasses.len(),
                        if rp.subpasses.len() == 1 { "" } else { "es" },
                        rp.on_chip_bytes_per_px
                    )?;
                    self.fmt_render_pass(f, rp)?;
                }
                Step::Compute { pass } => {
                    writeln!(f, "  {i:>3}  compute {}", self.pass_name(*pass))?
                }
                Step::Transfer { pass } => {
                    writeln!(f, "  {i:>3}  transfer {}", self.pass_name(*pass))?
                }
                Step::Flush(_) => writeln!(f, "  {i:>3}  flush (submit before occlusion queries)")?,
            }
            let ending = self
                .submissions
                .iter()
                .filter(|s| queues && s.end.index() == i + 1 && !s.releases.is_empty());
            for s in ending {
                writeln!(
                    f,
                    "       releases at the end of the submission ({})",
                    s.releases.len()
                )?;
                table(f, "       ", &self.batch_rows(&s.releases))?;
            }
        }
        while queues && next < self.submissions.len() {
            self.fmt_submission(f, next)?;
            next += 1;
        }
        Ok(())
    }

    fn fmt_resources(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "resources")?;
        let mut rows = vec![row([
            "name".into(),
            "desc".into(),
            "origin".into(),
            "usage".into(),
            "steps".into(),
            "residency".into(),
            "memory".into(),
        ])];
        for r in &self.resources {
            let desc = match &r.desc {
                ResourceDesc::Image(d) => {
                    let mut s = format!("{} {} {}", d.extent_px, d.format, d.samples);
                    if d.mip_levels > 1 {
                        let _ = write!(s, " {} mips", d.mip_levels);
                    }
                    s
                }
                ResourceDesc::Buffer(d) => format!("buffer {}", fmt_bytes(d.size_bytes)),
            };
            let usage = match r.usage {
                Usage::Image(u) => u.to_string(),
                Usage::Buffer(u) => u.to_string(),
            };
            let origin = match r.origin {
                Origin::Created => "created",
                Origin::Imported(_) => "imported",
            };
            let memory = match r.memory {
                Some(m) => format!(
                    "block {} @ {} ({})",
                    m.block.0,
                    fmt_bytes(m.offset_bytes),
                    fmt_bytes(m.size_bytes)
                ),
                None => "-".into(),
            };
            rows.push(row([
                r.name.clone(),
                desc,
                origin.into(),
                usage,
                Self::lifetime_text(r.lifetime),
                r.residency.name().into(),
                memory,
            ]));
        }
        table(f, "  ", &rows)
    }

    fn fmt_aliasing(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = &self.aliasing;
        writeln!(
            f,
            "aliasing: {} block{}, {} requested, {} allocated, {} saved",
            a.blocks.len(),
            if a.blocks.len() == 1 { "" } else { "s" },
            fmt_bytes(a.requested_bytes),
            fmt_bytes(a.allocated_bytes),
            fmt_bytes(a.saved_bytes())
        )?;
        for (i, b) in a.blocks.iter().enumerate() {
            let residents: Vec<&str> = self
                .resources
                .iter()
                .filter(|r| r.memory.is_some_and(|m| m.block.0 as usize == i))
                .map(|r| r.name.as_str())
                .collect();
            writeln!(
                f,
                "  block {i}: {} {}: {}",
                fmt_bytes(b.size_bytes),
                b.class.name(),
                residents.join(", ")
            )?;
        }
        Ok(())
    }

    fn fmt_traffic(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = &self.traffic;
        writeln!(
            f,
            "traffic ({} model, per frame): planned {} vs naive {}",
            t.model.name(),
            fmt_bytes(t.planned.total_bytes()),
            fmt_bytes(t.naive.total_bytes())
        )?;
        let mut rows = vec![row(["".into(), "planned".into(), "naive".into()])];
        let parts = |b: &TrafficBreakdown| b.parts();
        for ((name, planned), (_, naive)) in parts(&t.planned).iter().zip(parts(&t.naive).iter()) {
            if *planned == 0 && *naive == 0 {
                continue;
            }
            rows.push(row([
                (*name).to_string(),
                fmt_bytes(*planned),
                fmt_bytes(*naive),
            ]));
        }
        rows.push(row([
            "total".into(),
            format!("{} B", t.planned.total_bytes()),
            format!("{} B", t.naive.total_bytes()),
        ]));
        table(f, "  ", &rows)
    }
}

impl fmt::Display for Plan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let render_passes = self.render_passes().count();
        writeln!(
            f,
            "plan for {}: {} passes, {} pruned, {} render pass{}, {} barriers{}",
            self.profile,
            self.passes.len(),
            self.pruned.len(),
            render_passes,
            if render_passes == 1 { "" } else { "es" },
            self.barrier_count(),
            if self.submissions.len() > 1 {
                format!(
                    ", {} submissions on 2 queues ({} sharing)",
                    self.submissions.len(),
                    match self.queue_sharing {
                        tilegraph_profile::QueueSharing::Exclusive => "exclusive",
                        tilegraph_profile::QueueSharing::Concurrent => "concurrent",
                    }
                )
            } else {
                String::new()
            }
        )?;
        writeln!(f, "passes (execution order)")?;
        let mut rows = vec![row([
            "#".into(),
            "pass".into(),
            "kind".into(),
            "class".into(),
            "step".into(),
            "uses".into(),
        ])];
        for (i, p) in self.passes.iter().enumerate() {
            let step = match p.subpass {
                Some(s) => format!("{}.{}", p.step.0, s.0),
                None => format!("{}", p.step.0),
            };
            let kind = if p.queue == Queue::AsyncCompute {
                format!("{} (async)", p.kind.name())
            } else {
                p.kind.name().into()
            };
            rows.push(row([
                format!("{i}"),
                p.name.clone(),
                kind,
                p.class.name().into(),
                step,
                self.uses_text(&p.uses),
            ]));
        }
        table(f, "  ", &rows)?;
        if !self.pruned.is_empty() {
            writeln!(f, "pruned")?;
            let mut rows = Vec::new();
            for c in &self.pruned {
                let reason = match &c.reason {
                    PruneReason::NoOutputs => "writes nothing".to_string(),
                    PruneReason::OutputsUnused => "nothing reads what it writes".to_string(),
                    PruneReason::ConsumersPruned { consumers } => {
                        let names: Vec<&str> =
                            consumers.iter().map(|&p| self.pass_name(p)).collect();
                        format!("read only by pruned {}", names.join(", "))
                    }
                };
                rows.push(row([
                    c.name.clone(),
                    c.kind.name().into(),
                    c.class.name().into(),
                    reason,
                ]));
            }
            table(f, "  ", &rows)?;
        }
        self.fmt_steps(f)?;
        self.fmt_resources(f)?;
        self.fmt_aliasing(f)?;
        self.fmt_traffic(f)
    }
}

#[cfg(test)]
mod tests {
    use super::fmt_bytes;

    #[test]
    fn bytes_are_human_readable() {
        assert_eq!(fmt_bytes(512), "512 B");
        assert_eq!(fmt_bytes(12 * 1024), "12.0 KiB");
        assert_eq!(fmt_bytes(1920 * 1080 * 4), "7.91 MiB");
    }
}

#[cfg(test)]
mod plan_tests {
    use crate::testing::*;
    use crate::*;

    fn frame() -> GraphBuilder<()> {
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let unused = rgba8(&mut g, "debug");
        let out = swapchain(&mut g);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(out, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("debug \"view\"", PassClass::Other, ())
            .sampled(depth)
            .color(unused)
            .coverage(Coverage::Full);
        g
    }

    #[test]
    fn the_table_shows_order_pruning_ops_barriers_memory_and_traffic() {
        let text = compile(frame(), &tiler()).to_string();
        for needle in [
            "plan for adreno-7xx: 1 passes, 1 pruned, 1 render pass, 2 barriers",
            "nothing reads what it writes",
            "CLEAR/DONT_CARE",
            "swapchain  release  ColorAttachment -> Present",
            "transient",
            "traffic (tiler model, per frame): planned 8.0 KiB vs naive 32.0 KiB",
        ] {
            assert!(text.contains(needle), "missing {needle:?} in\n{text}");
        }
    }

    #[test]
    fn render_passes_over_the_tile_budget_are_flagged() {
        let mali = profile("mali-valhall");
        let mut g = GraphBuilder::new();
        let a = g.create_image("a", ImageDesc::new(EXTENT, Format::R16G16B16A16_SFLOAT));
        let b = g.create_image("b", ImageDesc::new(EXTENT, Format::R16G16B16A16_SFLOAT));
        let depth = d24s8(&mut g, "depth");
        g.export(a);
        g.export(b);
        g.raster_pass("gbuffer", PassClass::Opaque, ())
            .color_clear(a, ClearColor::BLACK)
            .color_clear(b, ClearColor::BLACK)
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        let plan = compile(g, &mali);
        assert_eq!(plan.tile_budget_bytes_per_px, Some(16));
        let text = plan.to_string();
        assert!(
            text.contains("on-chip 20 B/px of 16: over the tile budget"),
            "{text}"
        );
        assert_eq!(
            compile(GraphBuilder::new(), &desktop()).tile_budget_bytes_per_px,
            None
        );
    }

    #[test]
    fn dot_draws_render_passes_as_clusters_and_pruned_passes_grey() {
        let dot = compile(frame(), &tiler()).to_dot();
        assert!(dot.starts_with("digraph plan {"));
        assert!(dot.trim_end().ends_with('}'));
        assert!(dot.contains("subgraph cluster_step1 {"), "{dot}");
        assert!(dot.contains("p1 [shape=box, style=\"dashed,filled\", fillcolor=grey90"));
        // Names are escaped.
        assert!(
            dot.contains("label=\"debug \\\"view\\\"\\npruned\""),
            "{dot}"
        );
        assert!(dot.contains("p0 -> r0 [label=\"depth\"];"));
        assert!(dot.contains("r0 -> p1 [label=\"sampled\", color=grey60"));
    }
}
