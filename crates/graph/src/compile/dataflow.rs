//! `trace_dataflow`: what each read sees. The producer of a read is the last pass declared
//! before the reader that writes the resource (declaration order is program order, as in a
//! command buffer); a read of content nobody wrote and nothing imported is
//! `ReadBeforeWrite`. Pruning walks producers back from the exports; ordering keeps every
//! producer before its readers.

use crate::declare::{PassDecl, PassId, ResourceDecl, ResourceId};
use crate::error::GraphError;

use super::access::PassAccesses;

/// Producers and last writers of the declared frame.
#[derive(Debug)]
pub(crate) struct Dataflow {
    /// Per pass, the passes whose writes it reads (`producers[start..end]`).
    producer_ranges: Vec<(u32, u32)>,
    producers: Vec<PassId>,
    /// Per resource, the last declared pass that writes it.
    pub last_writer: Vec<Option<PassId>>,
}

impl Dataflow {
    pub fn producers_of(&self, pass: usize) -> &[PassId] {
        let (start, end) = self.producer_ranges[pass];
        &self.producers[start as usize..end as usize]
    }
}

pub(crate) fn trace_dataflow(
    resources: &[ResourceDecl],
    passes: &[PassDecl],
    accesses: &PassAccesses,
    exports: &[ResourceId],
) -> Result<Dataflow, GraphError> {
    let mut last_writer: Vec<Option<PassId>> = vec![None; resources.len()];
    let mut producer_ranges = Vec::with_capacity(passes.len());
    let mut producers = Vec::with_capacity(accesses.accesses.len());
    for (p, pass) in passes.iter().enumerate() {
        let start = producers.len();
        // One access per resource in a pass: each resource's writer is updated right after
        // its read is resolved.
        for a in accesses.of(PassId(p as u32)) {
            let writer = &mut last_writer[a.resource.index()];
            if a.reads_prior() {
                match *writer {
                    Some(w) => producers.push(w),
                    None => {
                        let r = &resources[a.resource.index()];
                        if a.explicit_read() && !r.has_initial_content() {
                            return Err(GraphError::ReadBeforeWrite {
                                pass: pass.name.clone(),
                                resource: r.name.clone(),
                                usage: pass
                                    .uses
                                    .get(a.first_use as usize)
                                    .map_or("?", |u| u.kind.name()),
                            });
                        }
                    }
                }
            }
            if a.writes() {
                *writer = Some(PassId(p as u32));
            }
        }
        producer_ranges.push((start as u32, producers.len() as u32));
    }

    for &e in exports {
        let r = &resources[e.index()];
        if last_writer[e.index()].is_none() && !r.has_initial_content() {
            return Err(GraphError::ExportOfUnwrittenResource {
                resource: r.name.clone(),
            });
        }
    }

    Ok(Dataflow {
        producer_ranges,
        producers,
        last_writer,
    })
}

#[cfg(test)]
mod tests {
    use crate::testing::*;
    use crate::*;

    #[test]
    fn read_before_write_names_the_pass_and_the_resource() {
        let mut g = GraphBuilder::new();
        let hdr = rgba8(&mut g, "hdr");
        let out = swapchain(&mut g);
        g.raster_pass("post", PassClass::Post, ())
            .sampled(hdr)
            .color(out);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::ReadBeforeWrite {
                pass: "post".into(),
                resource: "hdr".into(),
                usage: "sampled",
            }
        );
    }

    #[test]
    fn declaration_order_is_program_order() {
        // Written only by a pass declared later: still read before write.
        let mut g = GraphBuilder::new();
        let hdr = rgba8(&mut g, "hdr");
        let out = swapchain(&mut g);
        g.raster_pass("post", PassClass::Post, ())
            .sampled(hdr)
            .color(out);
        g.raster_pass("opaque", PassClass::Opaque, ())
            .color_clear(hdr, ClearColor::BLACK);
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::ReadBeforeWrite { pass, .. } if pass == "post"
        ));
    }

    #[test]
    fn imported_content_can_be_read_discarded_content_cannot() {
        let mut g = GraphBuilder::new();
        let prev = history(&mut g, "history");
        let out = swapchain(&mut g);
        g.raster_pass("taa", PassClass::Post, ())
            .sampled(prev)
            .color(out)
            .coverage(Coverage::Full);
        assert_eq!(compile(g, &tiler()).passes.len(), 1);

        let mut g = GraphBuilder::new();
        let acquired = g.import_image(
            "acquired",
            ImageDesc::new(EXTENT, Format::R8G8B8A8_UNORM),
            Import::SWAPCHAIN,
        );
        let out = swapchain(&mut g);
        g.raster_pass("copy", PassClass::Post, ())
            .input(acquired)
            .color(out);
        assert!(matches!(
            compile_err(g, &tiler()),
            GraphError::ReadBeforeWrite { resource, usage: "input", .. } if resource == "acquired"
        ));
    }

    #[test]
    fn exports_must_name_something_that_has_content() {
        let mut g: GraphBuilder<()> = GraphBuilder::new();
        g.export(ResourceId(7));
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::ExportOfUnknownResource { index: 7 }
        );

        let mut g: GraphBuilder<()> = GraphBuilder::new();
        let never = rgba8(&mut g, "never_written");
        g.export(never);
        assert_eq!(
            compile_err(g, &tiler()),
            GraphError::ExportOfUnwrittenResource {
                resource: "never_written".into()
            }
        );
    }
}
