//! The resources of a frame: handles, descriptions, and how imported ones come in and must be
//! left.

use std::fmt;

use crate::types::{AccessFlags, Extent2d, Format, Layout, PipelineStages, SampleCount};

/// Handle of any resource (image or buffer) of one graph; the index of its row in
/// [`Plan::resources`](crate::Plan::resources).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ResourceId(pub u32);

impl ResourceId {
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

impl fmt::Display for ResourceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "r{}", self.0)
    }
}

/// Handle of an image of one graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ImageId(pub ResourceId);

/// Handle of a buffer of one graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BufferId(pub ResourceId);

impl From<ImageId> for ResourceId {
    fn from(id: ImageId) -> Self {
        id.0
    }
}

impl From<BufferId> for ResourceId {
    fn from(id: BufferId) -> Self {
        id.0
    }
}

/// An image: 2D, one array layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ImageDesc {
    pub extent_px: Extent2d,
    pub format: Format,
    pub samples: SampleCount,
    /// 1 for a plain render target; a HiZ pyramid has the full chain.
    pub mip_levels: u32,
}

impl ImageDesc {
    pub const fn new(extent_px: Extent2d, format: Format) -> Self {
        Self {
            extent_px,
            format,
            samples: SampleCount::S1,
            mip_levels: 1,
        }
    }

    pub const fn with_samples(mut self, samples: SampleCount) -> Self {
        self.samples = samples;
        self
    }

    pub const fn with_mip_levels(mut self, mip_levels: u32) -> Self {
        self.mip_levels = mip_levels;
        self
    }

    /// Bytes of mip 0 with all samples: what one load or store of the attachment moves.
    pub const fn attachment_bytes(&self) -> u64 {
        self.extent_px.pixel_count()
            * self.format.bytes_per_pixel() as u64
            * self.samples.count() as u64
    }

    /// Bytes of every mip with all samples: the memory estimate and what a full read moves.
    pub fn total_bytes(&self) -> u64 {
        let per_px = u64::from(self.format.bytes_per_pixel()) * u64::from(self.samples.count());
        (0..self.mip_levels.min(32))
            .map(|level| self.extent_px.mip(level).pixel_count() * per_px)
            .sum()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BufferDesc {
    pub size_bytes: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ResourceDesc {
    Image(ImageDesc),
    Buffer(BufferDesc),
}

impl ResourceDesc {
    pub const fn image(&self) -> Option<&ImageDesc> {
        match self {
            ResourceDesc::Image(desc) => Some(desc),
            ResourceDesc::Buffer(_) => None,
        }
    }

    /// Memory estimate (all mips and samples; a buffer's size).
    pub fn size_bytes(&self) -> u64 {
        match self {
            ResourceDesc::Image(desc) => desc.total_bytes(),
            ResourceDesc::Buffer(desc) => desc.size_bytes,
        }
    }
}

/// Where a resource stands at a frame boundary: its layout (images; `Undefined` for buffers) and
/// the stages and accesses that touched it last (on the way in) or will touch it next (on the
/// way out).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ResourceState {
    pub layout: Layout,
    pub stages: PipelineStages,
    pub access: AccessFlags,
}

impl ResourceState {
    /// Nothing touched it; content undefined.
    pub const UNDEFINED: Self = Self {
        layout: Layout::Undefined,
        stages: PipelineStages::NONE,
        access: AccessFlags::NONE,
    };

    /// A swapchain image just acquired: the acquire semaphore is waited on at colour output, so
    /// the first transition must wait for that stage.
    pub const SWAPCHAIN_ACQUIRED: Self = Self {
        layout: Layout::Undefined,
        stages: PipelineStages::COLOR_ATTACHMENT_OUTPUT,
        access: AccessFlags::NONE,
    };

    /// Ready for presentation (the present semaphore orders the rest).
    pub const PRESENT: Self = Self {
        layout: Layout::Present,
        stages: PipelineStages::NONE,
        access: AccessFlags::NONE,
    };

    /// Read by the host after the frame's fence (readback buffers).
    pub const HOST_READ: Self = Self {
        layout: Layout::Undefined,
        stages: PipelineStages::HOST,
        access: AccessFlags::HOST_READ,
    };

    /// Sampled by the next frame's fragment or compute shaders (history images).
    pub const SHADER_READ: Self = Self {
        layout: Layout::ShaderReadOnly,
        stages: PipelineStages::from_bits(
            PipelineStages::FRAGMENT_SHADER.bits() | PipelineStages::COMPUTE_SHADER.bits(),
        ),
        access: AccessFlags::SHADER_SAMPLED_READ,
    };

    pub const fn image(layout: Layout, stages: PipelineStages, access: AccessFlags) -> Self {
        Self {
            layout,
            stages,
            access,
        }
    }

    pub const fn buffer(stages: PipelineStages, access: AccessFlags) -> Self {
        Self {
            layout: Layout::Undefined,
            stages,
            access,
        }
    }
}

/// Whether an imported resource's content at the start of the frame matters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InitialContent {
    /// Keep it: the first pass that needs old content gets LOAD (history, accumulation). A
    /// frame that only reads it leaves it as it came (a render pass that reads it stores it, or
    /// keeps it with NONE): reading never costs the caller its content. Keeping what the frame
    /// *writes* into it is what [`GraphBuilder::export`](crate::GraphBuilder::export) says: written and not exported, the
    /// new content is only needed until its last use (and may end with a DONT_CARE store).
    Preserve,
    /// Drop it (a freshly acquired swapchain image): never loaded, layout starts `Undefined`.
    Discard,
}

/// How an external resource comes in and must be left.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Import {
    /// Its state when the frame starts: what the first barrier waits for.
    pub initial: ResourceState,
    pub content: InitialContent,
    /// The state it must be left in (e.g. `Present`, `TransferSrc`, host read).
    pub final_state: ResourceState,
}

impl Import {
    /// A swapchain image: acquired (content discarded), left for presentation.
    pub const SWAPCHAIN: Self = Self {
        initial: ResourceState::SWAPCHAIN_ACQUIRED,
        content: InitialContent::Discard,
        final_state: ResourceState::PRESENT,
    };
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Origin {
    /// Created by the graph for this frame: memory is the graph's to place (and alias).
    Created,
    Imported(Import),
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ResourceDecl {
    pub name: String,
    pub desc: ResourceDesc,
    pub origin: Origin,
}

impl ResourceDecl {
    /// Imported with content the frame must see (`InitialContent::Preserve`).
    pub fn has_initial_content(&self) -> bool {
        matches!(
            self.origin,
            Origin::Imported(import) if import.content == InitialContent::Preserve
        )
    }
}
