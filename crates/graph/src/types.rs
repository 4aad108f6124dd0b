//! Vocabulary types shared by declarations and the plan: formats, layouts, load/store ops and the
//! stage/access/usage masks.
//!
//! Every value that the Vulkan backend passes on carries Vulkan's own numeric value (`vk_raw()`,
//! `bits()`), so `tilegraph-vk` maps them with `from_raw` and no table: a test below pins the
//! numbers to the Vulkan headers.

use std::fmt;

/// Extents are shared with the culling references and the scene passes, so the type lives in
/// tilegraph-types; the graph's paths (`tilegraph_graph::Extent2d`) keep naming it.
pub use tilegraph_types::Extent2d;

/// Image formats the graph knows the size of. Names and `vk_raw()` values are Vulkan's `VkFormat`.
#[allow(non_camel_case_types)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Format {
    R8_UNORM,
    R8G8B8A8_UNORM,
    R8G8B8A8_SRGB,
    B8G8R8A8_UNORM,
    B8G8R8A8_SRGB,
    A2B10G10R10_UNORM_PACK32,
    R16_SFLOAT,
    R16G16_SFLOAT,
    R16G16B16A16_SFLOAT,
    /// The packed R11G11B10 float format (`VK_FORMAT_B10G11R11_UFLOAT_PACK32`).
    B10G11R11_UFLOAT_PACK32,
    R32_UINT,
    R32_SFLOAT,
    R32G32_UINT,
    R32G32B32A32_UINT,
    D16_UNORM,
    D32_SFLOAT,
    D24_UNORM_S8_UINT,
    D32_SFLOAT_S8_UINT,
}

impl Format {
    pub const ALL: [Format; 18] = [
        Format::R8_UNORM,
        Format::R8G8B8A8_UNORM,
        Format::R8G8B8A8_SRGB,
        Format::B8G8R8A8_UNORM,
        Format::B8G8R8A8_SRGB,
        Format::A2B10G10R10_UNORM_PACK32,
        Format::R16_SFLOAT,
        Format::R16G16_SFLOAT,
        Format::R16G16B16A16_SFLOAT,
        Format::B10G11R11_UFLOAT_PACK32,
        Format::R32_UINT,
        Format::R32_SFLOAT,
        Format::R32G32_UINT,
        Format::R32G32B32A32_UINT,
        Format::D16_UNORM,
        Format::D32_SFLOAT,
        Format::D24_UNORM_S8_UINT,
        Format::D32_SFLOAT_S8_UINT,
    ];

    /// The format of a `VkFormat` value, if the graph has it.
    pub fn from_vk_raw(raw: i32) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.vk_raw() == raw)
    }

    /// `VkFormat` value.
    pub const fn vk_raw(self) -> i32 {
        match self {
            Format::R8_UNORM => 9,
            Format::R8G8B8A8_UNORM => 37,
            Format::R8G8B8A8_SRGB => 43,
            Format::B8G8R8A8_UNORM => 44,
            Format::B8G8R8A8_SRGB => 50,
            Format::A2B10G10R10_UNORM_PACK32 => 64,
            Format::R16_SFLOAT => 76,
            Format::R16G16_SFLOAT => 83,
            Format::R16G16B16A16_SFLOAT => 97,
            Format::R32_UINT => 98,
            Format::R32_SFLOAT => 100,
            Format::R32G32_UINT => 101,
            Format::R32G32B32A32_UINT => 107,
            Format::B10G11R11_UFLOAT_PACK32 => 122,
            Format::D16_UNORM => 124,
            Format::D32_SFLOAT => 126,
            Format::D24_UNORM_S8_UINT => 129,
            Format::D32_SFLOAT_S8_UINT => 130,
        }
    }

    /// Bytes one sample occupies, depth and stencil together (D32S8 counts 5: the traffic model
    /// moves 4 bytes of depth and 1 of stencil).
    pub const fn bytes_per_pixel(self) -> u32 {
        match self {
            Format::R8_UNORM => 1,
            Format::R16_SFLOAT | Format::D16_UNORM => 2,
            Format::R8G8B8A8_UNORM
            | Format::R8G8B8A8_SRGB
            | Format::B8G8R8A8_UNORM
            | Format::B8G8R8A8_SRGB
            | Format::A2B10G10R10_UNORM_PACK32
            | Format::R16G16_SFLOAT
            | Format::B10G11R11_UFLOAT_PACK32
            | Format::R32_UINT
            | Format::R32_SFLOAT
            | Format::D32_SFLOAT
            | Format::D24_UNORM_S8_UINT => 4,
            Format::D32_SFLOAT_S8_UINT => 5,
            Format::R16G16B16A16_SFLOAT | Format::R32G32_UINT => 8,
            Format::R32G32B32A32_UINT => 16,
        }
    }

    pub const fn has_depth(self) -> bool {
        matches!(
            self,
            Format::D16_UNORM
                | Format::D32_SFLOAT
                | Format::D24_UNORM_S8_UINT
                | Format::D32_SFLOAT_S8_UINT
        )
    }

    pub const fn has_stencil(self) -> bool {
        matches!(self, Format::D24_UNORM_S8_UINT | Format::D32_SFLOAT_S8_UINT)
    }

    /// A depth and/or stencil format (attached as depth-stencil, never as colour).
    pub const fn is_depth_stencil(self) -> bool {
        self.has_depth() || self.has_stencil()
    }

    /// Short name for tables.
    pub const fn name(self) -> &'static str {
        match self {
            Format::R8_UNORM => "R8_UNORM",
            Format::R8G8B8A8_UNORM => "RGBA8_UNORM",
            Format::R8G8B8A8_SRGB => "RGBA8_SRGB",
            Format::B8G8R8A8_UNORM => "BGRA8_UNORM",
            Format::B8G8R8A8_SRGB => "BGRA8_SRGB",
            Format::A2B10G10R10_UNORM_PACK32 => "A2BGR10_UNORM",
            Format::R16_SFLOAT => "R16_SFLOAT",
            Format::R16G16_SFLOAT => "RG16_SFLOAT",
            Format::R16G16B16A16_SFLOAT => "RGBA16_SFLOAT",
            Format::B10G11R11_UFLOAT_PACK32 => "R11G11B10_UFLOAT",
            Format::R32_UINT => "R32_UINT",
            Format::R32_SFLOAT => "R32_SFLOAT",
            Format::R32G32_UINT => "RG32_UINT",
            Format::R32G32B32A32_UINT => "RGBA32_UINT",
            Format::D16_UNORM => "D16_UNORM",
            Format::D32_SFLOAT => "D32_SFLOAT",
            Format::D24_UNORM_S8_UINT => "D24S8",
            Format::D32_SFLOAT_S8_UINT => "D32S8",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Multisample count; `vk_bits()` is the `VkSampleCountFlagBits` value (equal to the count).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SampleCount {
    S1,
    S2,
    S4,
    S8,
    S16,
}

impl SampleCount {
    pub const fn count(self) -> u32 {
        match self {
            SampleCount::S1 => 1,
            SampleCount::S2 => 2,
            SampleCount::S4 => 4,
            SampleCount::S8 => 8,
            SampleCount::S16 => 16,
        }
    }

    pub const fn vk_bits(self) -> u32 {
        self.count()
    }
}

impl fmt::Display for SampleCount {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x", self.count())
    }
}

/// Image layout; `vk_raw()` is the `VkImageLayout` value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Layout {
    Undefined,
    General,
    ColorAttachment,
    DepthStencilAttachment,
    DepthStencilReadOnly,
    ShaderReadOnly,
    TransferSrc,
    TransferDst,
    Present,
}

impl Layout {
    pub const ALL: [Layout; 9] = [
        Layout::Undefined,
        Layout::General,
        Layout::ColorAttachment,
        Layout::DepthStencilAttachment,
        Layout::DepthStencilReadOnly,
        Layout::ShaderReadOnly,
        Layout::TransferSrc,
        Layout::TransferDst,
        Layout::Present,
    ];

    /// The layout of a `VkImageLayout` value, if the graph has it.
    pub fn from_vk_raw(raw: i32) -> Option<Layout> {
        Layout::ALL.into_iter().find(|l| l.vk_raw() == raw)
    }

    pub const fn vk_raw(self) -> i32 {
        match self {
            Layout::Undefined => 0,
            Layout::General => 1,
            Layout::ColorAttachment => 2,
            Layout::DepthStencilAttachment => 3,
            Layout::DepthStencilReadOnly => 4,
            Layout::ShaderReadOnly => 5,
            Layout::TransferSrc => 6,
            Layout::TransferDst => 7,
            Layout::Present => 1_000_001_002,
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            Layout::Undefined => "Undefined",
            Layout::General => "General",
            Layout::ColorAttachment => "ColorAttachment",
            Layout::DepthStencilAttachment => "DepthStencilAttachment",
            Layout::DepthStencilReadOnly => "DepthStencilReadOnly",
            Layout::ShaderReadOnly => "ShaderReadOnly",
            Layout::TransferSrc => "TransferSrc",
            Layout::TransferDst => "TransferDst",
            Layout::Present => "Present",
        }
    }
}

impl fmt::Display for Layout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What a render pass does with an attachment's content when it begins (`VkAttachmentLoadOp`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LoadOp {
    Load,
    Clear,
    DontCare,
}

impl LoadOp {
    pub const fn vk_raw(self) -> i32 {
        match self {
            LoadOp::Load => 0,
            LoadOp::Clear => 1,
            LoadOp::DontCare => 2,
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            LoadOp::Load => "LOAD",
            LoadOp::Clear => "CLEAR",
            LoadOp::DontCare => "DONT_CARE",
        }
    }
}

/// What a render pass does with an attachment's content when it ends (`VkAttachmentStoreOp`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum StoreOp {
    Store,
    DontCare,
    /// Keep the content without writing it: the render pass only read the attachment
    /// (`VK_ATTACHMENT_STORE_OP_NONE`, on profiles with `store_op_none`). Neither a write nor
    /// memory traffic.
    None,
}

impl StoreOp {
    pub const fn vk_raw(self) -> i32 {
        match self {
            StoreOp::Store => 0,
            StoreOp::DontCare => 1,
            StoreOp::None => 1_000_301_000,
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            StoreOp::Store => "STORE",
            StoreOp::DontCare => "DONT_CARE",
            StoreOp::None => "NONE",
        }
    }
}

/// Colour clear value; which member the backend fills depends on the format's numeric type.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClearColor {
    Float([f32; 4]),
    Uint([u32; 4]),
    Int([i32; 4]),
}

impl ClearColor {
    pub const BLACK: Self = ClearColor::Float([0.0, 0.0, 0.0, 1.0]);
    pub const TRANSPARENT: Self = ClearColor::Float([0.0; 4]);
    pub const ZERO_UINT: Self = ClearColor::Uint([0; 4]);
}

/// Depth-stencil clear value. Reverse-Z clears depth to 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearDepthStencil {
    pub depth: f32,
    pub stencil: u32,
}

impl ClearDepthStencil {
    /// Reverse-Z: the far plane is at depth 0.
    pub const REVERSE_Z: Self = Self {
        depth: 0.0,
        stencil: 0,
    };
    pub const FORWARD_Z: Self = Self {
        depth: 1.0,
        stencil: 0,
    };
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClearValue {
    Color(ClearColor),
    DepthStencil(ClearDepthStencil),
}

impl fmt::Display for ClearValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClearValue::Color(ClearColor::Float(v)) => {
                write!(f, "({}, {}, {}, {})", v[0], v[1], v[2], v[3])
            }
            ClearValue::Color(ClearColor::Uint(v)) => {
                write!(f, "({}u, {}u, {}u, {}u)", v[0], v[1], v[2], v[3])
            }
            ClearValue::Color(ClearColor::Int(v)) => {
                write!(f, "({}i, {}i, {}i, {}i)", v[0], v[1], v[2], v[3])
            }
            ClearValue::DepthStencil(ds) => write!(f, "d={} s={}", ds.depth, ds.stencil),
        }
    }
}

/// Defines a bit-mask newtype with Vulkan's bit values and the usual set operations.
macro_rules! vk_flags {
    (
        $(#[$meta:meta])*
        $name:ident($int:ty) {
            $( $(#[$fmeta:meta])* $flag:ident = $value:expr, )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
        pub struct $name(pub $int);

        impl $name {
            pub const NONE: Self = Self(0);
            $( $(#[$fmeta])* pub const $flag: Self = Self($value); )*

            /// Every named flag with its name, in bit order.
            pub const NAMED: &'static [(&'static str, $name)] = &[ $( (stringify!($flag), Self($value)), )* ];

            /// The Vulkan bit value (`from_raw` on the ash side).
            pub const fn bits(self) -> $int {
                self.0
            }
            pub const fn from_bits(bits: $int) -> Self {
                Self(bits)
            }
            /// `bits` when every bit set is a named flag's, else `None` (bits from outside,
            /// an engine's through the C ABI, are checked before they reach a barrier).
            pub fn from_named_bits(bits: $int) -> Option<Self> {
                let named = Self::NAMED.iter().fold(0, |all, (_, f)| all | f.0);
                (bits & !named == 0).then_some(Self(bits))
            }
            pub const fn is_empty(self) -> bool {
                self.0 == 0
            }
            pub const fn contains(self, other: Self) -> bool {
                self.0 & other.0 == other.0
            }
            pub const fn intersects(self, other: Self) -> bool {
                self.0 & other.0 != 0
            }
            pub const fn union(self, other: Self) -> Self {
                Self(self.0 | other.0)
            }
            pub const fn intersection(self, other: Self) -> Self {
                Self(self.0 & other.0)
            }
            pub const fn difference(self, other: Self) -> Self {
                Self(self.0 & !other.0)
            }
        }

        impl std::ops::BitOr for $name {
            type Output = Self;
            fn bitor(self, rhs: Self) -> Self {
                self.union(rhs)
            }
        }

        impl std::ops::BitOrAssign for $name {
            fn bitor_assign(&mut self, rhs: Self) {
                self.0 |= rhs.0;
            }
        }

        impl std::ops::BitAnd for $name {
            type Output = Self;
            fn bitand(self, rhs: Self) -> Self {
                self.intersection(rhs)
            }
        }

        impl fmt::Display for $name {
            /// `A|B|C` with Vulkan's names, `NONE` when empty, unknown bits in hex.
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                if self.0 == 0 {
                    return f.write_str("NONE");
                }
                let mut rest = self.0;
                let mut first = true;
                for (name, flag) in Self::NAMED {
                    if flag.0 != 0 && self.0 & flag.0 == flag.0 && rest & flag.0 != 0 {
                        if !first {
                            f.write_str("|")?;
                        }
                        f.write_str(name)?;
                        first = false;
                        rest &= !flag.0;
                    }
                }
                if rest != 0 {
                    if !first {
                        f.write_str("|")?;
                    }
                    write!(f, "{:#x}", rest)?;
                }
                Ok(())
            }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}({})", stringify!($name), self)
            }
        }
    };
}

vk_flags! {
    /// `VkPipelineStageFlags2`, same bit values.
    PipelineStages(u64) {
        TOP_OF_PIPE = 0x1,
        DRAW_INDIRECT = 0x2,
        VERTEX_INPUT = 0x4,
        VERTEX_SHADER = 0x8,
        TESSELLATION_CONTROL_SHADER = 0x10,
        TESSELLATION_EVALUATION_SHADER = 0x20,
        GEOMETRY_SHADER = 0x40,
        FRAGMENT_SHADER = 0x80,
        EARLY_FRAGMENT_TESTS = 0x100,
        LATE_FRAGMENT_TESTS = 0x200,
        COLOR_ATTACHMENT_OUTPUT = 0x400,
        COMPUTE_SHADER = 0x800,
        ALL_TRANSFER = 0x1000,
        BOTTOM_OF_PIPE = 0x2000,
        HOST = 0x4000,
        ALL_GRAPHICS = 0x8000,
        ALL_COMMANDS = 0x1_0000,
        CONDITIONAL_RENDERING = 0x4_0000,
        COPY = 0x1_0000_0000,
        RESOLVE = 0x2_0000_0000,
        BLIT = 0x4_0000_0000,
        CLEAR = 0x8_0000_0000,
        INDEX_INPUT = 0x10_0000_0000,
        VERTEX_ATTRIBUTE_INPUT = 0x20_0000_0000,
        PRE_RASTERIZATION_SHADERS = 0x40_0000_0000,
    }
}

impl PipelineStages {
    /// Every stage a graph's passes can run work in, spelled out: "whatever touched it last"
    /// for a buffer kept across frames. `ALL_COMMANDS` means the same for what a graph
    /// records, but validation's best-practices checks flag it as a stall of everything.
    /// (Conditional rendering's stage is left out: its bit needs the device feature.)
    pub const EVERY_GRAPH_STAGE: Self = Self(
        Self::DRAW_INDIRECT.0
            | Self::VERTEX_INPUT.0
            | Self::PRE_RASTERIZATION_SHADERS.0
            | Self::FRAGMENT_SHADER.0
            | Self::EARLY_FRAGMENT_TESTS.0
            | Self::LATE_FRAGMENT_TESTS.0
            | Self::COLOR_ATTACHMENT_OUTPUT.0
            | Self::COMPUTE_SHADER.0
            | Self::ALL_TRANSFER.0,
    );
}

vk_flags! {
    /// `VkAccessFlags2`, same bit values.
    AccessFlags(u64) {
        INDIRECT_COMMAND_READ = 0x1,
        INDEX_READ = 0x2,
        VERTEX_ATTRIBUTE_READ = 0x4,
        UNIFORM_READ = 0x8,
        INPUT_ATTACHMENT_READ = 0x10,
        SHADER_READ = 0x20,
        SHADER_WRITE = 0x40,
        COLOR_ATTACHMENT_READ = 0x80,
        COLOR_ATTACHMENT_WRITE = 0x100,
        DEPTH_STENCIL_ATTACHMENT_READ = 0x200,
        DEPTH_STENCIL_ATTACHMENT_WRITE = 0x400,
        TRANSFER_READ = 0x800,
        TRANSFER_WRITE = 0x1000,
        HOST_READ = 0x2000,
        HOST_WRITE = 0x4000,
        MEMORY_READ = 0x8000,
        MEMORY_WRITE = 0x1_0000,
        CONDITIONAL_RENDERING_READ = 0x10_0000,
        SHADER_SAMPLED_READ = 0x1_0000_0000,
        SHADER_STORAGE_READ = 0x2_0000_0000,
        SHADER_STORAGE_WRITE = 0x4_0000_0000,
    }
}

impl AccessFlags {
    /// Every access that writes memory; the rest only read.
    pub const ALL_WRITES: Self = Self(
        Self::SHADER_WRITE.0
            | Self::COLOR_ATTACHMENT_WRITE.0
            | Self::DEPTH_STENCIL_ATTACHMENT_WRITE.0
            | Self::TRANSFER_WRITE.0
            | Self::HOST_WRITE.0
            | Self::MEMORY_WRITE.0
            | Self::SHADER_STORAGE_WRITE.0,
    );

    pub const fn writes(self) -> Self {
        self.intersection(Self::ALL_WRITES)
    }
}

vk_flags! {
    /// `VkImageUsageFlags`, same bit values.
    ImageUsage(u32) {
        TRANSFER_SRC = 0x1,
        TRANSFER_DST = 0x2,
        SAMPLED = 0x4,
        STORAGE = 0x8,
        COLOR_ATTACHMENT = 0x10,
        DEPTH_STENCIL_ATTACHMENT = 0x20,
        TRANSIENT_ATTACHMENT = 0x40,
        INPUT_ATTACHMENT = 0x80,
    }
}

vk_flags! {
    /// `VkBufferUsageFlags`, same bit values.
    BufferUsage(u32) {
        TRANSFER_SRC = 0x1,
        TRANSFER_DST = 0x2,
        UNIFORM_BUFFER = 0x10,
        STORAGE_BUFFER = 0x20,
        INDEX_BUFFER = 0x40,
        VERTEX_BUFFER = 0x80,
        INDIRECT_BUFFER = 0x100,
        CONDITIONAL_RENDERING = 0x200,
    }
}

vk_flags! {
    /// `VkDependencyFlags`, same bit values.
    DependencyFlags(u32) {
        BY_REGION = 0x1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vulkan_values_match_the_headers() {
        // Values from vulkan_core.h (1.3); the backend relies on them through from_raw.
        assert_eq!(Format::R8G8B8A8_UNORM.vk_raw(), 37);
        assert_eq!(Format::B8G8R8A8_SRGB.vk_raw(), 50);
        assert_eq!(Format::R16G16B16A16_SFLOAT.vk_raw(), 97);
        assert_eq!(Format::B10G11R11_UFLOAT_PACK32.vk_raw(), 122);
        assert_eq!(Format::D24_UNORM_S8_UINT.vk_raw(), 129);
        assert_eq!(Format::D32_SFLOAT_S8_UINT.vk_raw(), 130);
        assert_eq!(Layout::Present.vk_raw(), 1_000_001_002);
        assert_eq!(Layout::DepthStencilReadOnly.vk_raw(), 4);
        assert_eq!(PipelineStages::COLOR_ATTACHMENT_OUTPUT.bits(), 0x400);
        assert_eq!(PipelineStages::INDEX_INPUT.bits(), 1 << 36);
        assert_eq!(AccessFlags::SHADER_SAMPLED_READ.bits(), 1 << 32);
        assert_eq!(AccessFlags::SHADER_STORAGE_WRITE.bits(), 1 << 34);
        assert_eq!(ImageUsage::TRANSIENT_ATTACHMENT.bits(), 0x40);
        assert_eq!(BufferUsage::INDIRECT_BUFFER.bits(), 0x100);
        assert_eq!(LoadOp::DontCare.vk_raw(), 2);
        assert_eq!(StoreOp::DontCare.vk_raw(), 1);
    }

    #[test]
    fn format_properties() {
        for format in Format::ALL {
            assert!(format.bytes_per_pixel() > 0);
            if format.has_stencil() {
                assert!(format.has_depth(), "{format} has stencil without depth");
            }
        }
        assert_eq!(Format::D24_UNORM_S8_UINT.bytes_per_pixel(), 4);
        assert!(!Format::D32_SFLOAT.has_stencil());
        assert!(!Format::R32_UINT.is_depth_stencil());
    }

    #[test]
    fn flags_print_with_vulkan_names() {
        let s = PipelineStages::EARLY_FRAGMENT_TESTS | PipelineStages::LATE_FRAGMENT_TESTS;
        assert_eq!(s.to_string(), "EARLY_FRAGMENT_TESTS|LATE_FRAGMENT_TESTS");
        assert_eq!(AccessFlags::NONE.to_string(), "NONE");
        assert_eq!(AccessFlags(1 << 60).to_string(), "0x1000000000000000");
        assert!(AccessFlags::COLOR_ATTACHMENT_WRITE
            .writes()
            .contains(AccessFlags::COLOR_ATTACHMENT_WRITE));
        assert!(AccessFlags::SHADER_SAMPLED_READ.writes().is_empty());
    }
}
