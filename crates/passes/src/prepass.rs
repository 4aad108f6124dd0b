//! The depth pre-pass (seed 003's recipe): one material class's geometry drawn depth-only, so
//! that the colour pass after it shades each pixel once, testing depth EQUAL without writing it.
//! Opaque geometry needs positions only and no fragment shader; alpha-tested geometry runs its
//! discard here, once, in depth only (seed 001), so its colour pass keeps early depth tests.

use tilegraph_graph::{BufferId, PassClass, PassId};

use crate::draws::DrawClass;
use crate::frame::{DrawSource, FrameGraph, Payload};
use crate::pipelines::Variant;
use crate::recording::{record_class, Predicate};
use crate::targets::SceneTargets;

/// Declares the depth pre-pass of `class` (opaque or alpha-tested) named `name`, drawing from
/// `source` into the targets' depth (cleared if no pass wrote it yet).
pub fn add_depth_prepass(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    class: DrawClass,
    source: DrawSource,
    name: &str,
) -> PassId {
    let variant = depth_variant(class);
    let record: Payload =
        Box::new(move |pc, res| record_class(pc, res, variant, class, source, 0, Predicate::None));
    let mut p = g.raster_pass(name, PassClass::DepthPrepass, record);
    targets.attach_depth(&mut p, false);
    source.declare_reads(&mut p);
    p.id()
}

/// The depth pre-pass of `class` over the CPU lists, each instance predicated on the previous
/// frame's occlusion-query result in `last_results` ([`import_query_results`]): last frame's
/// visible set, the occluders that conditional queries test this frame's boxes against. The
/// colour passes then test nearer-or-equal and write depth
/// ([`ColourDepth::WriteOrEqual`](crate::pipelines::ColourDepth::WriteOrEqual)): whatever the
/// pre-pass left out, the image is the unculled one, and boxes tested against less depth pass
/// more often — conservative.
///
/// [`import_query_results`]: crate::occlusion::import_query_results
pub fn add_depth_prepass_of_last_visible(
    g: &mut FrameGraph,
    targets: &mut SceneTargets,
    class: DrawClass,
    last_results: BufferId,
    name: &str,
) -> PassId {
    let variant = depth_variant(class);
    let record: Payload = Box::new(move |pc, res| {
        record_class(
            pc,
            res,
            variant,
            class,
            DrawSource::Cpu,
            0,
            Predicate::LastFrame,
        )
    });
    let mut p = g.raster_pass(name, PassClass::DepthPrepass, record);
    targets.attach_depth(&mut p, false);
    p.predicate(last_results);
    p.id()
}

/// The depth-only pipeline of a material class: alpha-tested geometry runs its discard.
fn depth_variant(class: DrawClass) -> Variant {
    if class == DrawClass::AlphaTested {
        Variant::DepthAlpha
    } else {
        Variant::DepthOpaque
    }
}
