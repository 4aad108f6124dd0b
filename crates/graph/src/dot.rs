//! Graphviz DOT: passes are boxes, resources ellipses, edges say how a pass uses a resource
//! (resource -> pass for reads, pass -> resource for writes), each render pass is a cluster, and
//! pruned passes are grey and dashed.

use std::fmt::Write as _;

use crate::declare::{Coverage, PassId, PassUse, ResourceDesc, UseKind};
use crate::plan::{Plan, Residency, Step};

fn quote(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 2);
    out.push('"');
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

fn pass_node(id: PassId) -> String {
    format!("p{}", id.0)
}

/// Whether a writing use also reads what was there (what load/store inference calls
/// `reads_prior`).
fn reads_old_content(u: &PassUse, coverage: Coverage) -> bool {
    match u.kind {
        UseKind::ColorAttachment { clear } => clear.is_none() && coverage == Coverage::Partial,
        UseKind::DepthStencilAttachment { clear } => {
            clear.is_none() && coverage == Coverage::Partial
        }
        UseKind::StorageWrite | UseKind::StorageReadWrite | UseKind::TransferDst => {
            coverage == Coverage::Partial
        }
        _ => false,
    }
}

fn edges(out: &mut String, pass: PassId, uses: &[PassUse], coverage: Coverage, pruned: bool) {
    let style = if pruned {
        ", color=grey60, fontcolor=grey60, style=dashed"
    } else {
        ""
    };
    for u in uses {
        let (pass, resource) = (pass_node(pass), format!("r{}", u.resource.0));
        let label = quote(u.kind.name());
        // A write that keeps old content (blending, depth testing, a partial copy) reads it too.
        if !u.kind.writes() || reads_old_content(u, coverage) {
            let _ = writeln!(out, "  {resource} -> {pass} [label={label}{style}];");
        }
        if u.kind.writes() {
            let _ = writeln!(out, "  {pass} -> {resource} [label={label}{style}];");
        }
    }
}

impl Plan {
    /// The plan as a Graphviz digraph (`dot -Tsvg`).
    pub fn to_dot(&self) -> String {
        let mut out = String::new();
        out.push_str("digraph plan {\n");
        let _ = writeln!(
            out,
            "  label={};",
            quote(&format!("tilegraph plan ({})", self.profile))
        );
        out.push_str("  rankdir=LR;\n  node [fontname=\"monospace\", fontsize=10];\n");
        out.push_str("  edge [fontname=\"monospace\", fontsize=8];\n");
        for (i, step) in self.steps.iter().enumerate() {
            let Step::RenderPass(rp) = step else { continue };
            let _ = writeln!(out, "  subgraph cluster_step{i} {{");
            let _ = writeln!(
                out,
                "    label={}; style=rounded; color=steelblue;",
                quote(&format!("render pass (step {i}) {} px", rp.render_area_px))
            );
            for s in &rp.subpasses {
                let _ = writeln!(out, "    {};", pass_node(s.pass));
            }
            out.push_str("  }\n");
        }
        for p in &self.passes {
            let label = format!(
                "{}\n{} {} (step {})",
                p.name,
                p.kind.name(),
                p.class.name(),
                p.step.0
            );
            let _ = writeln!(
                out,
                "  {} [shape=box, label={}];",
                pass_node(p.id),
                quote(&label)
            );
        }
        for p in &self.pruned {
            let label = format!("{}\npruned", p.name);
            let _ = writeln!(
                out,
                "  {} [shape=box, style=\"dashed,filled\", fillcolor=grey90, color=grey60, \
                 fontcolor=grey50, label={}];",
                pass_node(p.id),
                quote(&label)
            );
        }
        for r in &self.resources {
            if r.residency == Residency::Unused
                && !self
                    .pruned
                    .iter()
                    .any(|c| c.uses.iter().any(|u| u.resource == r.id))
            {
                continue;
            }
            let desc = match &r.desc {
                ResourceDesc::Image(d) => format!("{} {}", d.extent_px, d.format),
                ResourceDesc::Buffer(d) => format!("{} B", d.size_bytes),
            };
            let style = match r.residency {
                Residency::Transient => ", style=dashed",
                Residency::Imported | Residency::Exported => ", style=bold",
                Residency::Unused => ", color=grey60, fontcolor=grey50",
                Residency::FrameLocal => "",
            };
            let label = format!("{}\n{}\n{}", r.name, desc, r.residency.name());
            let _ = writeln!(
                out,
                "  r{} [shape=ellipse, label={}{style}];",
                r.id.0,
                quote(&label)
            );
        }
        for p in &self.passes {
            edges(&mut out, p.id, &p.uses, p.coverage, false);
        }
        for p in &self.pruned {
            edges(&mut out, p.id, &p.uses, p.coverage, true);
        }
        out.push_str("}\n");
        out
    }
}
