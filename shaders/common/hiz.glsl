// Shared declarations of the HiZ pyramid build (hiz_copy.comp, hiz_reduce.comp). The push
// constants mirror tilegraph_passes::hiz::HizPush (32 bytes; tests/e2e/hiz.rs checks the size and
// offsets against the SPIR-V). See docs/CULLING.md, "GPU pyramid build".
#ifndef TILEGRAPH_HIZ_GLSL
#define TILEGRAPH_HIZ_GLSL

// How texel t of the destination level picks its source range, per axis (x shown):
// EDGE_AWARE  2t ..= (t == dst - 1 ? src - 1 : 2t + 1)       NpotMode::EdgeAware, every level
// HALVE       2t ..= min(2t + 1, src - 1)                     NpotMode::PadToPow2, levels >= 2
// PAD_FIRST   (t * src) / dst ..= ((t + 1) * src + dst - 1) / dst - 1
//                                                             NpotMode::PadToPow2, level 1
const uint HIZ_RULE_EDGE_AWARE = 0u;
const uint HIZ_RULE_HALVE = 1u;
const uint HIZ_RULE_PAD_FIRST = 2u;

// The copy (level 0) reads `rule` as the depth format instead.
const uint HIZ_COPY_D32 = 0u;
const uint HIZ_COPY_D16 = 1u;

// DepthConvention: which depth is the farther one the pyramid keeps.
const uint HIZ_STANDARD_MAX = 0u;
const uint HIZ_REVERSE_MIN = 1u;

layout(push_constant) uniform HizPush {
    uint src_offset;   // first texel of the source level in the pyramid buffer (reduce only)
    uint dst_offset;   // first texel of the level this dispatch writes
    uvec2 src_extent;  // source level (reduce) or depth image (copy) size
    uvec2 dst_extent;  // size of the level this dispatch writes
    uint rule;         // HIZ_RULE_* (reduce) or HIZ_COPY_* (copy)
    uint convention;   // HIZ_STANDARD_MAX / HIZ_REVERSE_MIN
} pc;

// Every level packed, level 0 first, each row-major with row 0 at the top.
layout(std430, set = 0, binding = 1) buffer Pyramid {
    float texels[];
} pyramid;

#endif
