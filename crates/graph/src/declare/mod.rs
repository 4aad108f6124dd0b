//! Declaring a frame: resources, passes, how each pass uses each resource, and exports.
//!
//! Declaration order is program order: a pass that reads a resource sees what the passes declared
//! before it wrote (like commands in a command buffer). `compile` may reorder passes that do not
//! depend on each other, never ones that do. Builder methods never fail: every mistake is
//! reported, with names, by `compile`.

use std::fmt;

use tilegraph_profile::PassClass;

use crate::types::{ClearColor, ClearDepthStencil, ClearValue, Extent2d};

mod resources;

pub(crate) use resources::ResourceDecl;
pub use resources::{
    BufferDesc, BufferId, ImageDesc, ImageId, Import, InitialContent, Origin, ResourceDesc,
    ResourceId, ResourceState,
};

/// Handle of a pass: its declaration index. Stable across compiles of the same declarations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PassId(pub u32);

impl PassId {
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

impl fmt::Display for PassId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "p{}", self.0)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PassKind {
    Raster,
    Compute,
    Transfer,
}

impl PassKind {
    pub const fn name(self) -> &'static str {
        match self {
            PassKind::Raster => "raster",
            PassKind::Compute => "compute",
            PassKind::Transfer => "transfer",
        }
    }
}

/// Whether a pass writes every pixel (every byte) of what it writes without reading the old
/// value. `Full` makes the old content dead (DONT_CARE load); `Partial` (the default) keeps it
/// (blending, depth testing, partial copies).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Coverage {
    Partial,
    Full,
}

/// Whether pruning may remove the pass when nothing in the graph reads what it writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Retention {
    PruneIfUnused,
    /// The pass has effects outside the graph (occlusion queries into a query pool, timestamps)
    /// and always runs.
    Always,
}

/// How a pass uses a resource.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UseKind {
    /// Colour attachment; without a clear the pass draws over the old content (unless the pass
    /// covers its area fully).
    ColorAttachment {
        clear: Option<ClearColor>,
    },
    /// Depth-stencil attachment with depth writes.
    DepthStencilAttachment {
        clear: Option<ClearDepthStencil>,
    },
    /// Depth-stencil attachment tested but not written.
    DepthStencilReadOnly,
    /// Read at the same pixel through `subpassLoad`: lets a tiler keep the data on chip.
    InputAttachment,
    /// Receives the multisample resolve of the colour attachment `source`.
    ResolveTarget {
        source: ResourceId,
    },
    /// Read through a sampler (any pixel).
    Sampled,
    StorageRead,
    StorageWrite,
    /// Read and written by one pass (e.g. every HiZ mip built in one dispatch with the payload's
    /// own barriers between mips); one use, not a conflict. Its reads see its own writes, and
    /// the old content unless the pass has `Coverage::Full`.
    StorageReadWrite,
    Uniform,
    Vertex,
    Index,
    Indirect,
    /// The predicate of conditional rendering (`vkCmdBeginConditionalRenderingEXT`, needs
    /// VK_EXT_conditional_rendering): read by its own pipeline stage, not by the draws.
    ConditionalPredicate,
    TransferSrc,
    TransferDst,
}

impl UseKind {
    pub const fn name(&self) -> &'static str {
        match self {
            UseKind::ColorAttachment { .. } => "color",
            UseKind::DepthStencilAttachment { .. } => "depth",
            UseKind::DepthStencilReadOnly => "depth-ro",
            UseKind::InputAttachment => "input",
            UseKind::ResolveTarget { .. } => "resolve",
            UseKind::Sampled => "sampled",
            UseKind::StorageRead => "storage-r",
            UseKind::StorageWrite => "storage-w",
            UseKind::StorageReadWrite => "storage-rw",
            UseKind::Uniform => "uniform",
            UseKind::Vertex => "vertex",
            UseKind::Index => "index",
            UseKind::Indirect => "indirect",
            UseKind::ConditionalPredicate => "predicate",
            UseKind::TransferSrc => "transfer-src",
            UseKind::TransferDst => "transfer-dst",
        }
    }

    /// Bound to the render pass (loaded/stored by it) rather than accessed through memory.
    pub const fn is_attachment(&self) -> bool {
        matches!(
            self,
            UseKind::ColorAttachment { .. }
                | UseKind::DepthStencilAttachment { .. }
                | UseKind::DepthStencilReadOnly
                | UseKind::InputAttachment
                | UseKind::ResolveTarget { .. }
        )
    }

    pub const fn writes(&self) -> bool {
        matches!(
            self,
            UseKind::ColorAttachment { .. }
                | UseKind::DepthStencilAttachment { .. }
                | UseKind::ResolveTarget { .. }
                | UseKind::StorageWrite
                | UseKind::StorageReadWrite
                | UseKind::TransferDst
        )
    }

    /// Reads the resource on purpose (a write that keeps old content is an implicit read, decided
    /// by clear and coverage, not here).
    pub const fn reads(&self) -> bool {
        !matches!(
            self,
            UseKind::ColorAttachment { .. }
                | UseKind::DepthStencilAttachment { .. }
                | UseKind::ResolveTarget { .. }
                | UseKind::StorageWrite
                | UseKind::TransferDst
        )
    }

    pub const fn clear_value(&self) -> Option<ClearValue> {
        match self {
            UseKind::ColorAttachment { clear: Some(c) } => Some(ClearValue::Color(*c)),
            UseKind::DepthStencilAttachment { clear: Some(c) } => {
                Some(ClearValue::DepthStencil(*c))
            }
            _ => None,
        }
    }

    /// A bit per variant, for sets of uses.
    pub(crate) const fn bit(&self) -> u16 {
        1 << match self {
            UseKind::ColorAttachment { .. } => 0,
            UseKind::DepthStencilAttachment { .. } => 1,
            UseKind::DepthStencilReadOnly => 2,
            UseKind::InputAttachment => 3,
            UseKind::ResolveTarget { .. } => 4,
            UseKind::Sampled => 5,
            UseKind::StorageRead => 6,
            UseKind::StorageWrite => 7,
            UseKind::StorageReadWrite => 8,
            UseKind::Uniform => 9,
            UseKind::Vertex => 10,
            UseKind::Index => 11,
            UseKind::Indirect => 12,
            UseKind::TransferSrc => 13,
            UseKind::TransferDst => 14,
            UseKind::ConditionalPredicate => 15,
        }
    }
}

impl fmt::Display for UseKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())?;
        if let Some(clear) = self.clear_value() {
            write!(f, " clear {clear}")?;
        }
        Ok(())
    }
}

/// One declared use of a resource by a pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassUse {
    pub resource: ResourceId,
    pub kind: UseKind,
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PassDecl {
    pub name: String,
    pub kind: PassKind,
    pub class: PassClass,
    pub coverage: Coverage,
    pub retention: Retention,
    pub render_area: Option<Extent2d>,
    pub uses: Vec<PassUse>,
    /// A compute pass that may run on an async compute queue.
    pub async_capable: bool,
}

/// Declares one frame. `P` is the payload each pass carries (the backend's recording callback);
/// the graph stores and orders payloads and never looks inside.
#[derive(Debug, Clone)]
pub struct GraphBuilder<P> {
    pub(crate) resources: Vec<ResourceDecl>,
    pub(crate) passes: Vec<PassDecl>,
    pub(crate) payloads: Vec<P>,
    pub(crate) exports: Vec<ResourceId>,
    pub(crate) dependencies: Vec<(PassId, PassId)>,
}

impl<P> Default for GraphBuilder<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<P> GraphBuilder<P> {
    pub fn new() -> Self {
        Self {
            resources: Vec::new(),
            passes: Vec::new(),
            payloads: Vec::new(),
            exports: Vec::new(),
            dependencies: Vec::new(),
        }
    }

    pub fn pass_count(&self) -> usize {
        self.passes.len()
    }

    pub fn resource_count(&self) -> usize {
        self.resources.len()
    }

    /// Prefixes the names of the passes from index `passes_from` and of the resources from
    /// `resources_from` with `prefix`: a composition declared twice on one graph (a frame's
    /// second view) keeps names a reader — and the per-pass timings — can tell apart.
    pub fn prefix_names(&mut self, passes_from: usize, resources_from: usize, prefix: &str) {
        for p in self.passes.iter_mut().skip(passes_from) {
            p.name.insert_str(0, prefix);
        }
        for r in self.resources.iter_mut().skip(resources_from) {
            r.name.insert_str(0, prefix);
        }
    }

    fn push_resource(&mut self, name: String, desc: ResourceDesc, origin: Origin) -> ResourceId {
        // u32 handles: 4 billion resources is beyond any frame; saturate rather than wrap so an
        // absurd graph fails validation instead of aliasing handles.
        let id = ResourceId(u32::try_from(self.resources.len()).unwrap_or(u32::MAX));
        self.resources.push(ResourceDecl { name, desc, origin });
        id
    }

    /// An image that lives only in this frame; its usage is inferred from the passes.
    pub fn create_image(&mut self, name: impl Into<String>, desc: ImageDesc) -> ImageId {
        ImageId(self.push_resource(name.into(), ResourceDesc::Image(desc), Origin::Created))
    }

    /// A buffer that lives only in this frame.
    pub fn create_buffer(&mut self, name: impl Into<String>, size_bytes: u64) -> BufferId {
        BufferId(self.push_resource(
            name.into(),
            ResourceDesc::Buffer(BufferDesc { size_bytes }),
            Origin::Created,
        ))
    }

    /// An image owned outside the graph (swapchain, history from the last frame).
    pub fn import_image(
        &mut self,
        name: impl Into<String>,
        desc: ImageDesc,
        import: Import,
    ) -> ImageId {
        ImageId(self.push_resource(
            name.into(),
            ResourceDesc::Image(desc),
            Origin::Imported(import),
        ))
    }

    /// A buffer owned outside the graph (geometry, readback, query results).
    pub fn import_buffer(
        &mut self,
        name: impl Into<String>,
        size_bytes: u64,
        import: Import,
    ) -> BufferId {
        BufferId(self.push_resource(
            name.into(),
            ResourceDesc::Buffer(BufferDesc { size_bytes }),
            Origin::Imported(import),
        ))
    }

    /// Marks a resource's final content as needed after the frame (presented image, history,
    /// readback). Exports are what pruning keeps alive.
    pub fn export(&mut self, resource: impl Into<ResourceId>) {
        let resource = resource.into();
        if !self.exports.contains(&resource) {
            self.exports.push(resource);
        }
    }

    /// Orders `after` after `before` without a resource between them (effects outside the graph,
    /// such as a query pool written by one pass and copied by another). Ordering only: it does
    /// not keep `before` from being pruned.
    pub fn add_dependency(&mut self, before: PassId, after: PassId) {
        self.dependencies.push((before, after));
    }

    fn push_pass(&mut self, name: String, kind: PassKind, class: PassClass, payload: P) -> PassId {
        let id = PassId(u32::try_from(self.passes.len()).unwrap_or(u32::MAX));
        self.passes.push(PassDecl {
            name,
            kind,
            class,
            coverage: Coverage::Partial,
            retention: Retention::PruneIfUnused,
            render_area: None,
            uses: Vec::new(),
            async_capable: false,
        });
        self.payloads.push(payload);
        id
    }

    pub fn raster_pass(
        &mut self,
        name: impl Into<String>,
        class: PassClass,
        payload: P,
    ) -> RasterPassBuilder<'_, P> {
        let pass = self.push_pass(name.into(), PassKind::Raster, class, payload);
        RasterPassBuilder { graph: self, pass }
    }

    pub fn compute_pass(
        &mut self,
        name: impl Into<String>,
        class: PassClass,
        payload: P,
    ) -> ComputePassBuilder<'_, P> {
        let pass = self.push_pass(name.into(), PassKind::Compute, class, payload);
        ComputePassBuilder { graph: self, pass }
    }

    pub fn transfer_pass(
        &mut self,
        name: impl Into<String>,
        class: PassClass,
        payload: P,
    ) -> TransferPassBuilder<'_, P> {
        let pass = self.push_pass(name.into(), PassKind::Transfer, class, payload);
        TransferPassBuilder { graph: self, pass }
    }

    /// The raster pass `pass`, to declare more of its uses (`None`: no such raster pass). For
    /// callers that declare a pass over several calls (the C API).
    pub fn raster(&mut self, pass: PassId) -> Option<RasterPassBuilder<'_, P>> {
        let decl = self.passes.get(pass.index())?;
        (decl.kind == PassKind::Raster).then_some(RasterPassBuilder { graph: self, pass })
    }

    /// The compute pass `pass`, to declare more of its uses (`None`: no such compute pass).
    pub fn compute(&mut self, pass: PassId) -> Option<ComputePassBuilder<'_, P>> {
        let decl = self.passes.get(pass.index())?;
        (decl.kind == PassKind::Compute).then_some(ComputePassBuilder { graph: self, pass })
    }

    fn pass_mut(&mut self, pass: PassId) -> Option<&mut PassDecl> {
        self.passes.get_mut(pass.index())
    }

    fn push_use(&mut self, pass: PassId, resource: ResourceId, kind: UseKind) {
        if let Some(decl) = self.pass_mut(pass) {
            decl.uses.push(PassUse { resource, kind });
        }
    }
}

/// Methods every pass kind has.
macro_rules! common_pass_methods {
    () => {
        /// The pass's handle.
        pub fn id(&self) -> PassId {
            self.pass
        }

        /// See [`Coverage`]; the default is `Partial`.
        pub fn coverage(&mut self, coverage: Coverage) -> &mut Self {
            if let Some(decl) = self.graph.pass_mut(self.pass) {
                decl.coverage = coverage;
            }
            self
        }

        /// See [`Retention`]; the default is `PruneIfUnused`.
        pub fn retention(&mut self, retention: Retention) -> &mut Self {
            if let Some(decl) = self.graph.pass_mut(self.pass) {
                decl.retention = retention;
            }
            self
        }

        /// Runs after `before` (see [`GraphBuilder::add_dependency`]).
        pub fn after(&mut self, before: PassId) -> &mut Self {
            self.graph.add_dependency(before, self.pass);
            self
        }

        pub fn storage_read(&mut self, resource: impl Into<ResourceId>) -> &mut Self {
            self.graph
                .push_use(self.pass, resource.into(), UseKind::StorageRead);
            self
        }

        pub fn storage_write(&mut self, resource: impl Into<ResourceId>) -> &mut Self {
            self.graph
                .push_use(self.pass, resource.into(), UseKind::StorageWrite);
            self
        }

        pub fn storage_read_write(&mut self, resource: impl Into<ResourceId>) -> &mut Self {
            self.graph
                .push_use(self.pass, resource.into(), UseKind::StorageReadWrite);
            self
        }

        pub fn sampled(&mut self, image: ImageId) -> &mut Self {
            self.graph.push_use(self.pass, image.0, UseKind::Sampled);
            self
        }

        pub fn uniform(&mut self, buffer: BufferId) -> &mut Self {
            self.graph.push_use(self.pass, buffer.0, UseKind::Uniform);
            self
        }

        pub fn indirect(&mut self, buffer: BufferId) -> &mut Self {
            self.graph.push_use(self.pass, buffer.0, UseKind::Indirect);
            self
        }

        /// The pass draws or dispatches under conditional rendering predicated on `buffer`.
        pub fn predicate(&mut self, buffer: BufferId) -> &mut Self {
            self.graph
                .push_use(self.pass, buffer.0, UseKind::ConditionalPredicate);
            self
        }
    };
}

/// Declares a raster pass: attachments (one extent for all, the render area) and other reads.
pub struct RasterPassBuilder<'g, P> {
    graph: &'g mut GraphBuilder<P>,
    pass: PassId,
}

impl<P> RasterPassBuilder<'_, P> {
    common_pass_methods!();

    /// Colour attachment drawn over its old content.
    pub fn color(&mut self, image: ImageId) -> &mut Self {
        self.graph
            .push_use(self.pass, image.0, UseKind::ColorAttachment { clear: None });
        self
    }

    pub fn color_clear(&mut self, image: ImageId, clear: ClearColor) -> &mut Self {
        self.graph.push_use(
            self.pass,
            image.0,
            UseKind::ColorAttachment { clear: Some(clear) },
        );
        self
    }

    /// Depth-stencil attachment, tested and written, starting from its old content.
    pub fn depth_stencil(&mut self, image: ImageId) -> &mut Self {
        self.graph.push_use(
            self.pass,
            image.0,
            UseKind::DepthStencilAttachment { clear: None },
        );
        self
    }

    pub fn depth_stencil_clear(&mut self, image: ImageId, clear: ClearDepthStencil) -> &mut Self {
        self.graph.push_use(
            self.pass,
            image.0,
            UseKind::DepthStencilAttachment { clear: Some(clear) },
        );
        self
    }

    /// Depth-stencil attachment tested but not written (EQUAL after a pre-pass, transparents,
    /// occlusion queries).
    pub fn depth_stencil_read_only(&mut self, image: ImageId) -> &mut Self {
        self.graph
            .push_use(self.pass, image.0, UseKind::DepthStencilReadOnly);
        self
    }

    /// Input attachment: read at the same pixel, so a tiler can keep it on chip.
    pub fn input(&mut self, image: ImageId) -> &mut Self {
        self.graph
            .push_use(self.pass, image.0, UseKind::InputAttachment);
        self
    }

    /// Resolves the multisampled colour attachment `color` into `target` at the end of the pass.
    pub fn resolve(&mut self, color: ImageId, target: ImageId) -> &mut Self {
        self.graph.push_use(
            self.pass,
            target.0,
            UseKind::ResolveTarget { source: color.0 },
        );
        self
    }

    pub fn vertex(&mut self, buffer: BufferId) -> &mut Self {
        self.graph.push_use(self.pass, buffer.0, UseKind::Vertex);
        self
    }

    pub fn index(&mut self, buffer: BufferId) -> &mut Self {
        self.graph.push_use(self.pass, buffer.0, UseKind::Index);
        self
    }

    /// Render area for a pass without attachments; with attachments it must equal their extent.
    pub fn render_area(&mut self, extent_px: Extent2d) -> &mut Self {
        if let Some(decl) = self.graph.pass_mut(self.pass) {
            decl.render_area = Some(extent_px);
        }
        self
    }
}

/// Declares a compute pass.
pub struct ComputePassBuilder<'g, P> {
    graph: &'g mut GraphBuilder<P>,
    pass: PassId,
}

impl<P> ComputePassBuilder<'_, P> {
    common_pass_methods!();

    /// The pass may run on an async compute queue, beside the raster work, where the profile
    /// asks for async compute (`[queues] async_compute`) and the device has such a queue: it
    /// writes nothing but what it declares (it may read buffers no pass of the frame writes,
    /// such as the scene's), and records nothing a compute-only queue lacks. The compiler adds
    /// the semaphore waits and ownership transfers its uses need.
    pub fn async_compute(&mut self) -> &mut Self {
        if let Some(decl) = self.graph.pass_mut(self.pass) {
            decl.async_capable = true;
        }
        self
    }
}

/// Declares a transfer pass (copies, blits, clears, query-result copies).
pub struct TransferPassBuilder<'g, P> {
    graph: &'g mut GraphBuilder<P>,
    pass: PassId,
}

impl<P> TransferPassBuilder<'_, P> {
    /// The pass's handle.
    pub fn id(&self) -> PassId {
        self.pass
    }

    /// The pass may run on the async compute queue, as
    /// [`ComputePassBuilder::async_compute`]: for copies, fills and updates between compute
    /// passes there (a compute queue has no blits), so that they do not bounce the work back
    /// to the graphics queue.
    pub fn async_compute(&mut self) -> &mut Self {
        if let Some(decl) = self.graph.pass_mut(self.pass) {
            decl.async_capable = true;
        }
        self
    }

    pub fn transfer_src(&mut self, resource: impl Into<ResourceId>) -> &mut Self {
        self.graph
            .push_use(self.pass, resource.into(), UseKind::TransferSrc);
        self
    }

    pub fn transfer_dst(&mut self, resource: impl Into<ResourceId>) -> &mut Self {
        self.graph
            .push_use(self.pass, resource.into(), UseKind::TransferDst);
        self
    }

    /// See [`Coverage`]: `Full` when the copy overwrites the whole destination.
    pub fn coverage(&mut self, coverage: Coverage) -> &mut Self {
        if let Some(decl) = self.graph.pass_mut(self.pass) {
            decl.coverage = coverage;
        }
        self
    }

    pub fn retention(&mut self, retention: Retention) -> &mut Self {
        if let Some(decl) = self.graph.pass_mut(self.pass) {
            decl.retention = retention;
        }
        self
    }

    pub fn after(&mut self, before: PassId) -> &mut Self {
        self.graph.add_dependency(before, self.pass);
        self
    }
}
