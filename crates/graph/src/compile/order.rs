//! `order_passes`: dependencies first, then the profile's class order, then
//! declaration order.
//!
//! Edges come from resources (read-after-write, write-after-read, write-after-write, in
//! declaration order, between surviving passes) and from explicit `add_dependency` calls; only
//! the latter can form a cycle. Among passes that are ready, the scheduler picks the lowest
//! *effective* class rank: a pass inherits the rank of the most urgent pass that waits on it, so
//! a post-process pass that feeds an opaque pass is not held back behind transparents. With the
//! profile's order (occlusion queries after transparents) this puts occlusion-query passes
//! after all opaque, alpha-tested and transparent work that does not depend on them (seed 001).
//!
//! It also assigns the queues: with the profile's async compute on, an async-capable pass runs
//! on the async compute queue where a raster pass may run beside it (neither waits on the other,
//! directly or not); elsewhere the second queue would only add waits.
//!
//! With passes on the async compute queue, a graphics pass that takes what an async pass makes
//! is only as urgent as the passes that wait on it (its own class does not hurry it), and goes
//! after the other ready passes of that rank: the graphics queue draws what does not wait
//! while the async queue runs, instead of waiting at once.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use tilegraph_profile::{PassClass, Profile, QueueSharing};

use crate::declare::{PassDecl, PassId, PassKind};
use crate::error::GraphError;
use crate::plan::Queue;
use crate::types::Layout;

use super::access::PassAccesses;
use super::dataflow::Dataflow;
use super::queues::assign_queues;

const NONE: u32 = u32::MAX;

/// Every class, to look up the profile's rank once per class rather than once per pass.
const CLASSES: [PassClass; 10] = [
    PassClass::Compute,
    PassClass::Shadow,
    PassClass::DepthPrepass,
    PassClass::Opaque,
    PassClass::AlphaTested,
    PassClass::Transparent,
    PassClass::OcclusionQuery,
    PassClass::Post,
    PassClass::Transfer,
    PassClass::Other,
];

/// Successor lists (CSR) of the surviving passes.
struct Edges {
    start: Vec<u32>,
    targets: Vec<u32>,
}

impl Edges {
    fn of(&self, p: usize) -> &[u32] {
        &self.targets[self.start[p] as usize..self.start[p + 1] as usize]
    }
}

fn dependency_edges(
    accesses: &PassAccesses,
    dataflow: &Dataflow,
    n_resources: usize,
    alive: &[bool],
    dependencies: &[(PassId, PassId)],
) -> Edges {
    let n = alive.len();
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(accesses.accesses.len() * 2);
    // Per resource: its last writer, and the readers since as a linked list in `readers`.
    let mut last = vec![(NONE, NONE); n_resources];
    let mut readers: Vec<(u32, u32)> = Vec::with_capacity(accesses.accesses.len());
    for p in (0..n).filter(|&p| alive[p]) {
        let pu = p as u32;
        // A pass has one access per resource, so each resource's state can be updated as soon
        // as its edges are out.
        for a in accesses.of(PassId(p as u32)) {
            let entry = &mut last[a.resource.index()];
            let (w, head) = *entry;
            // Every access orders after the last write: a read needs its data, a write must
            // not be overtaken by the older one.
            debug_assert!(w != pu, "two accesses to one resource in one pass");
            if w != NONE {
                pairs.push((w, pu));
            }
            if a.writes() {
                let mut node = head;
                while node != NONE {
                    let (q, next) = readers[node as usize];
                    debug_assert!(q != pu, "two accesses to one resource in one pass");
                    pairs.push((q, pu));
                    node = next;
                }
                *entry = (pu, NONE);
            } else if dataflow.last_writer[a.resource.index()].is_some_and(|w| w.0 > pu) {
                // Only a later write needs to wait for this read.
                readers.push((pu, head));
                entry.1 = (readers.len() - 1) as u32;
            }
        }
    }
    for &(before, after) in dependencies {
        if alive[before.index()] && alive[after.index()] {
            pairs.push((before.0, after.0));
        }
    }
    // Counting sort by source.
    let mut start = vec![0u32; n + 1];
    for &(from, _) in &pairs {
        start[from as usize + 1] += 1;
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    // Fill with `start[from]` as the cursor (it ends at the next list's start), then shift back.
    let mut targets = vec![0u32; pairs.len()];
    for &(from, to) in &pairs {
        targets[start[from as usize] as usize] = to;
        start[from as usize] += 1;
    }
    start.copy_within(0..n, 1);
    start[0] = 0;
    Edges { start, targets }
}

/// Names the passes of one cycle among `remaining` (passes Kahn's algorithm could not free).
fn find_cycle(edges: &Edges, remaining: &[bool], passes: &[PassDecl]) -> GraphError {
    let n = remaining.len();
    let mut preds: Vec<Vec<u32>> = vec![Vec::new(); n];
    for p in (0..n).filter(|&p| remaining[p]) {
        for &s in edges.of(p) {
            if remaining[s as usize] {
                preds[s as usize].push(p as u32);
            }
        }
    }
    // Every remaining pass has a remaining predecessor, so walking backwards must repeat.
    let Some(mut v) = (0..n).find(|&p| remaining[p]) else {
        return GraphError::Cycle { passes: Vec::new() };
    };
    let mut seen_at = vec![NONE; n];
    let mut path: Vec<u32> = Vec::new();
    while seen_at[v] == NONE {
        seen_at[v] = path.len() as u32;
        path.push(v as u32);
        match preds[v].iter().min() {
            Some(&u) => v = u as usize,
            None => break,
        }
    }
    let from = seen_at[v].min(path.len() as u32) as usize;
    let mut cycle: Vec<u32> = path[from..].to_vec();
    cycle.reverse();
    if let Some(&first) = cycle.first() {
        cycle.push(first);
    }
    GraphError::Cycle {
        passes: cycle
            .iter()
            .map(|&p| passes[p as usize].name.clone())
            .collect(),
    }
}

/// The passes in execution order, and the queue of each (index: `PassId`).
pub(crate) struct Ordered {
    pub order: Vec<PassId>,
    pub queue_of: Vec<Queue>,
}

pub(crate) fn order_passes(
    accesses: &PassAccesses,
    dataflow: &Dataflow,
    passes: &[PassDecl],
    n_resources: usize,
    alive: &[bool],
    dependencies: &[(PassId, PassId)],
    profile: &Profile,
) -> Result<Ordered, GraphError> {
    let n = passes.len();
    let edges = dependency_edges(accesses, dataflow, n_resources, alive, dependencies);
    let mut indegree = vec![0u32; n];
    for &t in &edges.targets {
        indegree[t as usize] += 1;
    }

    // A first topological order, to find cycles and to propagate urgency backwards. Resource
    // edges always point forward in declaration order, so without explicit dependencies the
    // declaration order is one.
    let alive_count = alive.iter().filter(|&&a| a).count();
    let topo: Vec<u32> = if dependencies.is_empty() {
        let mut topo = Vec::with_capacity(alive_count);
        topo.extend((0..n as u32).filter(|&p| alive[p as usize]));
        topo
    } else {
        let mut remaining = indegree.clone();
        let mut queue: VecDeque<u32> = (0..n as u32)
            .filter(|&p| alive[p as usize] && remaining[p as usize] == 0)
            .collect();
        let mut topo: Vec<u32> = Vec::with_capacity(alive_count);
        while let Some(p) = queue.pop_front() {
            topo.push(p);
            for &s in edges.of(p as usize) {
                remaining[s as usize] -= 1;
                if remaining[s as usize] == 0 {
                    queue.push_back(s);
                }
            }
        }
        if topo.len() < alive_count {
            let stuck: Vec<bool> = (0..n).map(|p| alive[p] && remaining[p] > 0).collect();
            return Err(find_cycle(&edges, &stuck, passes));
        }
        topo
    };

    let queue_of = if profile.queues.async_compute {
        let exclusive = profile.queues.sharing == QueueSharing::Exclusive;
        let beside = beside_raster(
            &edges,
            &topo,
            (passes, alive),
            exclusive.then_some(accesses),
        );
        let capable: Vec<bool> = passes.iter().map(|p| p.async_capable).collect();
        assign_queues(&capable, &beside)
    } else {
        vec![Queue::Graphics; n]
    };
    let on_async: Vec<bool> = queue_of.iter().map(|&q| q == Queue::AsyncCompute).collect();
    // Graphics passes that wait on an async pass.
    let mut defer = vec![false; n];
    for p in (0..n).filter(|&p| on_async[p]) {
        for &s in edges.of(p) {
            defer[s as usize] = !on_async[s as usize];
        }
    }

    // Indexed by the class's discriminant; ranks are clamped to 16 bits for the key below.
    let mut class_rank = [u16::MAX; CLASSES.len()];
    for c in CLASSES {
        if let Some(slot) = class_rank.get_mut(c as usize) {
            *slot = profile.passes.class_rank(c).min(0xffff) as u16;
        }
    }
    let rank: Vec<u16> = passes
        .iter()
        .map(|p| {
            class_rank
                .get(p.class as usize)
                .copied()
                .unwrap_or(u16::MAX)
        })
        .collect();
    let mut effective = rank.clone();
    for &p in topo.iter().rev() {
        let p = p as usize;
        for &s in edges.of(p) {
            effective[p] = effective[p].min(effective[s as usize]);
        }
    }

    // A pass that waits on the async queue: as urgent as the raster work that waits on it only.
    // Compute and transfer passes between it and that raster work do not count (their class
    // comes first in every profile's order, and would make the wait as urgent as ever: a
    // late culling chain would go ahead of a shadow map that could draw meanwhile).
    let mut urgency = effective.clone();
    if defer.iter().any(|&d| d) {
        let mut raster_effective: Vec<u16> = passes
            .iter()
            .zip(&rank)
            .map(|(p, &r)| {
                if p.kind == PassKind::Raster {
                    r
                } else {
                    u16::MAX
                }
            })
            .collect();
        for &p in topo.iter().rev() {
            let p = p as usize;
            for &s in edges.of(p) {
                raster_effective[p] = raster_effective[p].min(raster_effective[s as usize]);
            }
        }
        for p in (0..n).filter(|&p| defer[p]) {
            let waiting = edges
                .of(p)
                .iter()
                .map(|&s| raster_effective[s as usize])
                .min()
                .unwrap_or(u16::MAX);
            urgency[p] = if waiting == u16::MAX {
                rank[p]
            } else {
                waiting
            };
        }
    }
    // (urgency, waits on the async queue, own rank, declaration index) packed into one integer
    // key.
    let key = |p: usize| -> u128 {
        (u128::from(urgency[p]) << 49)
            | (u128::from(defer[p]) << 48)
            | (u128::from(rank[p]) << 32)
            | p as u128
    };
    let mut ready: BinaryHeap<Reverse<u128>> = BinaryHeap::with_capacity(alive_count);
    ready.extend(
        topo.iter()
            .filter(|&&p| indegree[p as usize] == 0)
            .map(|&p| Reverse(key(p as usize))),
    );
    let mut order = Vec::with_capacity(alive_count);
    // The smallest ready key, when known, is kept out of the heap: in a chain the pass freed by
    // the one just emitted is usually the next one, and then it never enters the heap.
    let mut next: Option<u128> = None;
    while let Some(k) = next.take().or_else(|| ready.pop().map(|Reverse(k)| k)) {
        let p = (k & 0xffff_ffff) as u32;
        order.push(PassId(p));
        for &s in edges.of(p as usize) {
            let s = s as usize;
            indegree[s] -= 1;
            if indegree[s] == 0 {
                let k = key(s);
                match next {
                    Some(n) if k < n => {
                        ready.push(Reverse(n));
                        next = Some(k);
                    }
                    Some(_) => ready.push(Reverse(k)),
                    None if ready.peek().is_none_or(|&Reverse(top)| k < top) => next = Some(k),
                    None => ready.push(Reverse(k)),
                }
            }
        }
    }
    Ok(Ordered { order, queue_of })
}

/// Whether each pass has a raster pass beside it: one that neither waits on it nor is waited on
/// by it, directly or not, and so may run while it does. Only such a pass gains from the async
/// queue; one that every raster pass waits on (or follows) would only add waits and
/// submissions to the frame. With exclusive sharing (`accesses` given), two passes that use
/// one image are not beside each other either: the image belongs to one queue's family at a
/// time, so even two reads take turns.
fn beside_raster(
    edges: &Edges,
    topo: &[u32],
    (passes, alive): (&[PassDecl], &[bool]),
    accesses: Option<&PassAccesses>,
) -> Vec<bool> {
    let n = passes.len();
    let words = n.div_ceil(64);
    // after[p]: the passes that wait on p, directly or not (a bit set of `words` words).
    let mut after = vec![0u64; n * words];
    for &p in topo.iter().rev() {
        let p = p as usize;
        for &s in edges.of(p) {
            let s = s as usize;
            after[p * words + s / 64] |= 1 << (s % 64);
            for w in 0..words {
                let bits = after[s * words + w];
                after[p * words + w] |= bits;
            }
        }
    }
    let ordered = |a: usize, b: usize| after[a * words + b / 64] & (1 << (b % 64)) != 0;
    let share_an_image = |a: usize, b: usize| {
        accesses.is_some_and(|acc| {
            let images = |p: usize| {
                acc.of(PassId(p as u32))
                    .iter()
                    .filter(|x| x.layout != Layout::Undefined)
                    .map(|x| x.resource)
            };
            images(a).any(|r| images(b).any(|s| s == r))
        })
    };
    let raster: Vec<usize> = (0..n)
        .filter(|&r| alive[r] && passes[r].kind == PassKind::Raster)
        .collect();
    (0..n)
        .map(|p| {
            alive[p]
                && raster
                    .iter()
                    .any(|&r| r != p && !ordered(p, r) && !ordered(r, p) && !share_an_image(p, r))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    #[test]
    fn independent_passes_follow_the_class_order() {
        // Declared transparent-first, but they do not depend on each other.
        let mut g = GraphBuilder::new();
        let a = rgba8(&mut g, "a");
        let b = rgba8(&mut g, "b");
        let c = g.create_buffer("c", 256);
        g.export(a);
        g.export(b);
        g.export(c);
        g.raster_pass("particles", PassClass::Transparent, ())
            .color_clear(a, ClearColor::BLACK);
        g.raster_pass("shadows", PassClass::Opaque, ())
            .color_clear(b, ClearColor::BLACK);
        g.compute_pass("cull", PassClass::Compute, ())
            .storage_write(c);
        assert_eq!(
            order(&compile(g, &tiler())),
            ["cull", "shadows", "particles"]
        );
    }

    #[test]
    fn dependencies_come_before_the_class_order() {
        // Post-class pass that opaque work reads: it must run first, and it pulls its urgency
        // (opaque's rank) ahead of the unrelated transparent pass.
        let mut g = GraphBuilder::new();
        let lut = rgba8(&mut g, "lut");
        let scene = rgba8(&mut g, "scene");
        let glass = rgba8(&mut g, "glass");
        g.export(scene);
        g.export(glass);
        g.raster_pass("glass", PassClass::Transparent, ())
            .color_clear(glass, ClearColor::BLACK);
        g.raster_pass("bake_lut", PassClass::Post, ())
            .color_clear(lut, ClearColor::BLACK);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .sampled(lut)
            .color_clear(scene, ClearColor::BLACK);
        assert_eq!(
            order(&compile(g, &tiler())),
            ["bake_lut", "opaque", "glass"]
        );
    }

    #[test]
    fn occlusion_queries_go_after_the_drawing_that_does_not_need_them() {
        // seed 001: opaque, alpha-tested, transparent, then the occlusion queries.
        let mut g = GraphBuilder::new();
        let depth = d24s8(&mut g, "depth");
        let out = swapchain(&mut g);
        g.raster_pass("prepass", PassClass::DepthPrepass, ())
            .depth_stencil_clear(depth, ClearDepthStencil::REVERSE_Z);
        g.raster_pass("queries", PassClass::OcclusionQuery, ())
            .depth_stencil_read_only(depth)
            .retention(Retention::Always);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(out, ClearColor::BLACK)
            .depth_stencil_read_only(depth);
        g.raster_pass("transparent", PassClass::Transparent, ())
            .color(out)
            .depth_stencil_read_only(depth);
        assert_eq!(
            order(&compile(g, &tiler())),
            ["prepass", "opaque", "transparent", "queries"]
        );
    }

    #[test]
    fn declaration_order_breaks_ties() {
        let mut g = GraphBuilder::new();
        let names = ["c", "a", "b"];
        for name in names {
            let buf = g.create_buffer(name, 64);
            g.export(buf);
            g.compute_pass(name, PassClass::Compute, ())
                .storage_write(buf);
        }
        assert_eq!(order(&compile(g, &tiler())), names);
    }

    #[test]
    fn explicit_dependencies_order_and_can_form_a_cycle() {
        let mut g = GraphBuilder::new();
        let a = g.create_buffer("a", 64);
        let b = g.create_buffer("b", 64);
        g.export(a);
        g.export(b);
        let first = g
            .compute_pass("first", PassClass::Compute, ())
            .storage_write(a)
            .id();
        let second = g
            .compute_pass("second", PassClass::Compute, ())
            .storage_write(b)
            .id();
        let mut ordered = g.clone();
        ordered.add_dependency(second, first);
        assert_eq!(order(&compile(ordered, &tiler())), ["second", "first"]);

        let mut cyclic = g.clone();
        cyclic.add_dependency(second, first);
        cyclic.add_dependency(first, second);
        assert_eq!(
            compile_err(cyclic, &tiler()),
            GraphError::Cycle {
                passes: vec!["second".into(), "first".into(), "second".into()]
            }
        );

        let mut g2 = GraphBuilder::new();
        let x = g2.create_buffer("x", 64);
        let y = g2.create_buffer("y", 64);
        g2.export(y);
        let producer = g2
            .compute_pass("producer", PassClass::Compute, ())
            .storage_write(x)
            .id();
        g2.compute_pass("consumer", PassClass::Compute, ())
            .storage_read(x)
            .storage_write(y)
            .after(producer);
        let consumer = PassId(1);
        g2.add_dependency(consumer, producer);
        assert!(matches!(
            compile_err(g2, &tiler()),
            GraphError::Cycle { passes } if passes.contains(&"producer".to_string())
                && passes.contains(&"consumer".to_string())
        ));
    }

    #[test]
    fn a_pass_after_itself_is_a_cycle() {
        let mut g = GraphBuilder::new();
        let a = g.create_buffer("a", 64);
        g.export(a);
        let p = g
            .compute_pass("narcissus", PassClass::Compute, ())
            .storage_write(a)
            .id();
        g.add_dependency(p, p);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::Cycle {
                passes: vec!["narcissus".into(), "narcissus".into()]
            }
        );
    }
}
