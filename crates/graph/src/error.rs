use crate::types::Extent2d;

/// Everything that can be wrong with a declared graph. Each variant names the pass and resource
/// (by the names they were declared with) so the message points at the frame-setup code.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GraphError {
    #[error(
        "pass '{pass}' reads '{resource}' ({usage}) but no pass declared before it writes it \
         and it has no imported content"
    )]
    ReadBeforeWrite {
        pass: String,
        resource: String,
        usage: &'static str,
    },

    #[error("dependency cycle: {}", passes.join(" -> "))]
    Cycle { passes: Vec<String> },

    #[error(
        "pass '{pass}' uses '{resource}' as {first} and as {second}; a pass may combine \
             only reads that agree on the layout"
    )]
    ConflictingUses {
        pass: String,
        resource: String,
        first: &'static str,
        second: &'static str,
    },

    #[error(
        "pass '{pass}': attachment '{resource}' is {found_px} px but the render area is \
             {expected_px} px"
    )]
    ExtentMismatch {
        pass: String,
        resource: String,
        expected_px: Extent2d,
        found_px: Extent2d,
    },

    #[error(
        "pass '{pass}': attachment '{resource}' has {found} samples, the pass's other \
             attachments have {expected}"
    )]
    SampleCountMismatch {
        pass: String,
        resource: String,
        expected: u32,
        found: u32,
    },

    #[error("pass '{pass}' has {count} colour attachments; profile '{profile}' allows {max}")]
    TooManyColorAttachments {
        pass: String,
        count: u32,
        max: u32,
        profile: String,
    },

    #[error(
        "pass '{pass}' attaches two depth-stencil images, '{first}' and '{second}'; a subpass has \
             one"
    )]
    SecondDepthStencil {
        pass: String,
        first: String,
        second: String,
    },

    #[error(
        "pass '{pass}' attaches '{resource}', which has {mip_levels} mip levels; an attachment \
             has one (render into a single-level image and copy, or build mips in a compute pass)"
    )]
    MipmappedAttachment {
        pass: String,
        resource: String,
        mip_levels: u32,
    },

    #[error("pass '{pass}': '{resource}' ({format}) cannot be used as {usage}")]
    FormatMismatch {
        pass: String,
        resource: String,
        format: &'static str,
        usage: &'static str,
    },

    #[error("pass '{pass}': cannot resolve '{source_image}' into '{target}': {reason}")]
    InvalidResolve {
        pass: String,
        source_image: String,
        target: String,
        reason: &'static str,
    },

    #[error("raster pass '{pass}' has no attachment and no render area")]
    MissingRenderArea { pass: String },

    #[error("raster pass '{pass}': render area {extent_px} px is not 1 to 32768 px on each side")]
    InvalidRenderArea { pass: String, extent_px: Extent2d },

    #[error("pass '{pass}' uses resource #{index}, which this graph never declared")]
    UnknownResource { pass: String, index: u32 },

    #[error("a dependency names pass #{index}, which this graph never declared")]
    UnknownPass { index: u32 },

    #[error("resource '{resource}': {reason}")]
    InvalidResource {
        resource: String,
        reason: &'static str,
    },

    #[error("export of resource #{index}, which this graph never declared")]
    ExportOfUnknownResource { index: u32 },

    #[error("export of '{resource}', which no pass writes and which has no imported content")]
    ExportOfUnwrittenResource { resource: String },

    #[error("alias assignment given {lifetimes} lifetimes but {requirements} memory requirements")]
    AliasInputMismatch {
        lifetimes: usize,
        requirements: usize,
    },

    #[error("the plan is not one compile produced: {reason}")]
    InvalidPlan { reason: &'static str },

    #[error("memory requirement #{index}: alignment {alignment_bytes} is not a power of two")]
    InvalidAlignment { index: usize, alignment_bytes: u64 },
}
