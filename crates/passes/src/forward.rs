//! Forward shading: the colour passes of opaque and alpha-tested geometry, the blended pass,
//! and the clear a frame gets when nothing drew. After a depth pre-pass of the same class, a
//! colour pass tests depth EQUAL without writing it (the pre-pass and colour vertex shaders
//! declare `gl_Position` invariant, so both compute the same depth).

use tilegraph_graph::{BufferId, Coverage, PassClass, PassId};

use crate::draws::DrawClass;
use crate::frame::{DrawSource, FrameGraph, Payload};
use crate::pipelines::{ColourDepth, Variant};
use crate::recording::{record_class, Predicate};
use crate::targets::SceneTargets;

/// Declares the colour pass of `class` (opaque or alpha-tested) named `name`, drawing from
/// `source`. `depth`: what a depth pre-pass wrote of this class (all of it: test EQUAL, no
/// writes). `predicate`: this frame's occlusion-query results on the GPU that each instance's
/// draw is predicated on (conditional rendering; the graph makes them visible to that stage).
pub fn add_forward(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    class: DrawClass,
    depth: ColourDepth,
    source: DrawSource,
    predicate: Option<BufferId>,
    name: &str,
) -> PassId {
    let variant = Variant::Forward { class, depth };
    let predicate_results = if predicate.is_some() {
        Predicate::ThisFrame
    } else {
        Predicate::None
    };
    let record: Payload = Box::new(move |pc, res| {
        record_class(pc, res, variant, class, source, 1, predicate_results)
    });
    let pass_class = if class == DrawClass::AlphaTested {
        PassClass::AlphaTested
    } else {
        PassClass::Opaque
    };
    let mut p = g.raster_pass(name, pass_class, record);
    targets.attach_color(&mut p);
    targets.attach_depth(&mut p, depth == ColourDepth::Equal);
    source.declare_reads(&mut p);
    if let Some(c) = predicate {
        p.predicate(c);
    }
    p.id()
}

/// Declares the blended pass: the CPU list's blended draws, back to front, depth tested
/// without writes.
pub fn add_transparent(g: &mut FrameGraph, targets: &mut SceneTargets) -> PassId {
    let class = DrawClass::Blended;
    let variant = Variant::Forward {
        class,
        depth: ColourDepth::Write,
    };
    let record: Payload = Box::new(move |pc, res| {
        record_class(pc, res, variant, class, DrawSource::Cpu, 1, Predicate::None)
    });
    let mut p = g.raster_pass("transparent", PassClass::Transparent, record);
    targets.attach_color(&mut p);
    targets.attach_depth(&mut p, true);
    p.id()
}

/// Declares a pass that only clears: the colour target when no pass drew it (an empty view of
/// an empty scene still produces a cleared image), and with `depth` the depth target when no
/// pass wrote it (a depth image the renderer keeps is exported, cleared to the far plane).
pub fn add_clear(g: &mut FrameGraph, targets: &mut SceneTargets, depth: bool) -> PassId {
    let record: Payload = Box::new(|_, _| Ok(()));
    let mut p = g.raster_pass("clear", PassClass::Opaque, record);
    if !targets.color_written() {
        targets.attach_color(&mut p);
    }
    if depth && !targets.depth_written() {
        targets.attach_depth(&mut p, false);
    }
    p.coverage(Coverage::Full);
    p.id()
}
