// Shared declarations of the HiZ pyramid (docs/CULLING.md, "GPU pyramid build"). Helpers and
// constants for every shader that reads the pyramid; the build shaders (hiz_copy.comp,
// hiz_reduce.comp) define HIZ_BUILD first to also get their push constants and binding. The push
// constants mirror tilegraph_passes::hiz::HizPush (48 bytes; tests/e2e/hiz.rs checks the size and
// offsets against the SPIR-V).
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

// NpotMode, for the base level's footprint (hiz_copy.comp at a base level above 0).
const uint HIZ_NPOT_EDGE_AWARE = 0u;
const uint HIZ_NPOT_PAD = 1u;

// DepthConvention: which depth is the farther one the pyramid keeps.
const uint HIZ_STANDARD_MAX = 0u;
const uint HIZ_REVERSE_MIN = 1u;

#ifdef HIZ_BUILD
layout(push_constant) uniform HizPush {
    uint src_offset;   // first texel of the source level in the pyramid buffer (reduce only)
    uint dst_offset;   // first texel of the level this dispatch writes
    uvec2 src_extent;  // source level (reduce) or depth image (copy) size
    uvec2 dst_extent;  // size of the level this dispatch writes
    uint rule;         // HIZ_RULE_* (reduce) or HIZ_COPY_* (copy)
    uint convention;   // HIZ_STANDARD_MAX / HIZ_REVERSE_MIN
    uint base_level;   // copy: the level written (0 = a copy; b > 0 reduces each footprint)
    uint npot;         // copy: HIZ_NPOT_* (the footprint rule)
    uvec2 pow2_extent; // copy: PadToPow2's level-1 extent P (base level >= 1)
} pc;

// Every level packed, level 0 first, each row-major with row 0 at the top.
layout(std430, set = 0, binding = 1) buffer Pyramid {
    float texels[];
} pyramid;
#endif

// The f32 nearest to k / 65535 (tilegraph_cull::dequantize_d16), exactly, in integer arithmetic.
// The UNORM -> float conversion of a D16 texel need not be correctly rounded (lavapipe's is one
// ulp off for 512 of the 65536 codes), nor need GLSL's `c / 65535.0`: a shader that compares
// with the pyramid's D16 values forms its depths with this function.
// For 0 < k < 65535, k / (2^16 - 1) in binary is k's 16 bits repeated forever: 0.kkkk... . With
// k' = k rotated (16 bits) so that its leading one is on top, the significand is the first 24
// bits of k'k'k'..., and the rest is never exactly a half (it repeats a non-zero pattern), so
// round to nearest is "add the 25th bit", k' bit 7.
float hiz_d16_exact(uint k) {
    if (k == 0u) {
        return 0.0;
    }
    if (k >= 65535u) {
        return 1.0;
    }
    int m = findMSB(k); // k / 65535 lies in [2^(m-16), 2^(m-15))
    uint p = uint(15 - m);
    uint kr = ((k << p) | (k >> (16u - p))) & 0xFFFFu;
    uint q = ((kr << 8) | (kr >> 8)) + ((kr >> 7) & 1u);
    // q < 2^24: it would need k' = 0xFFFF, i.e. k = 65535.
    return uintBitsToFloat((uint(m - 16 + 127) << 23) | (q & 0x7FFFFFu));
}

#endif
