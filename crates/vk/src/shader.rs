//! SPIR-V modules: loaded from bytes embedded at compile time (`shaders/spv/*.spv`, built by
//! `cargo xtask shaders` and committed).

use ash::vk;

use crate::error::{VkError, VkResultExt};
use crate::Context;

/// Decodes SPIR-V bytes into words, checking size and magic number.
pub fn spirv_words(name: &str, bytes: &[u8]) -> Result<Vec<u32>, VkError> {
    let bad = |reason: &str| VkError::Spirv {
        name: name.to_string(),
        reason: reason.to_string(),
    };
    if !bytes.len().is_multiple_of(4) || bytes.len() < 20 {
        return Err(bad(
            "length is not a multiple of 4 or shorter than a header",
        ));
    }
    let words: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if words.first() != Some(&0x0723_0203) {
        return Err(bad("bad magic number"));
    }
    Ok(words)
}

/// Creates a shader module; the caller destroys it (usually right after pipeline creation).
pub fn create_shader_module(
    ctx: &Context,
    name: &str,
    bytes: &[u8],
) -> Result<vk::ShaderModule, VkError> {
    let words = spirv_words(name, bytes)?;
    let info = vk::ShaderModuleCreateInfo::default().code(&words);
    // SAFETY: words is well-formed SPIR-V (validated by spirv-val in the test suite).
    let module =
        unsafe { ctx.device.create_shader_module(&info, None) }.vk("vkCreateShaderModule")?;
    ctx.set_name(module, name);
    Ok(module)
}

/// The smoke-test shaders of the first frame.
pub mod embedded {
    pub const TRIANGLE_VERT: &[u8] = include_bytes!("../../../shaders/spv/triangle.vert.spv");
    pub const TRIANGLE_FRAG: &[u8] = include_bytes!("../../../shaders/spv/triangle.frag.spv");
}
