#version 460
// HiZ levels k+1 .. k+n (n <= 4) from level k in one dispatch: level k+1 from the pyramid
// buffer, each further level from the one before it in shared memory. Same source ranges and
// the same min/max as hiz_reduce.comp, so the result is still bit-identical to
// tilegraph_cull::HizPyramid::build (docs/CULLING.md, "Dispatches").
//
// Tiles: workgroup w (per axis) owns texels [w * span_j, (w + 1) * span_j) of fused level j,
// span_j = B << (n - 1 - j), so its level j - 1 texels are exactly the ones its level j texels
// read; the last workgroup of an axis also owns everything past that up to the level's edge,
// where the EdgeAware rule's last texel takes the odd leftovers. With B = 2 and n <= 4 a tile
// never exceeds 31 texels per axis (docs/CULLING.md), so two 32x32 tiles of shared memory
// (8 KiB) hold every level.
#include "hiz.glsl"

layout(local_size_x = 16, local_size_y = 16) in;

// tilegraph_passes::hiz::HizLevelsPush (80 bytes).
layout(push_constant) uniform HizLevelsPush {
    uint src_offset;       // first texel of level k in the pyramid buffer
    uint levels;           // n, 1..4
    uvec2 src_extent;      // size of level k
    uint rule;             // HIZ_RULE_EDGE_AWARE or HIZ_RULE_HALVE
    uint convention;       // HIZ_STANDARD_MAX / HIZ_REVERSE_MIN
    uvec2 groups;          // workgroups per axis
    uvec4 dst_offset;      // first texel of levels k+1 .. k+n
    uvec2 dst_extent[4];   // sizes of levels k+1 .. k+n
} pc;

layout(std430, set = 0, binding = 1) buffer Pyramid {
    float texels[];
} pyramid;

const uint B = 2u;
const uint TILE = 32u;
shared float tiles[2][TILE * TILE];

float keep(float a, float b) {
    return pc.convention == HIZ_STANDARD_MAX ? max(a, b) : min(a, b);
}

void main() {
    uvec2 wg = gl_WorkGroupID.xy;
    bvec2 last = equal(wg, pc.groups - 1u);
    uvec2 lid = gl_LocalInvocationID.xy;
    uvec2 src = pc.src_extent;
    uvec2 prev_start = uvec2(0u);
    for (uint j = 0u; j < pc.levels; ++j) {
        uvec2 dst = pc.dst_extent[j];
        uint span = B << (pc.levels - 1u - j);
        uvec2 start = wg * span;
        uvec2 end = min(mix(start + span, dst, last), dst);
        uvec2 size = end - start;
        for (uint y = lid.y; y < size.y; y += 16u) {
            for (uint x = lid.x; x < size.x; x += 16u) {
                uvec2 t = start + uvec2(x, y);
                uvec2 lo = 2u * t;
                uvec2 hi = pc.rule == HIZ_RULE_EDGE_AWARE
                    ? mix(2u * t + 1u, src - 1u, equal(t, dst - 1u))
                    : min(2u * t + 1u, src - 1u);
                float v;
                if (j == 0u) {
                    v = pyramid.texels[pc.src_offset + lo.y * src.x + lo.x];
                    for (uint sy = lo.y; sy <= hi.y; ++sy) {
                        for (uint sx = lo.x; sx <= hi.x; ++sx) {
                            v = keep(v, pyramid.texels[pc.src_offset + sy * src.x + sx]);
                        }
                    }
                } else {
                    uint from = (j - 1u) & 1u;
                    v = tiles[from][(lo.y - prev_start.y) * TILE + (lo.x - prev_start.x)];
                    for (uint sy = lo.y; sy <= hi.y; ++sy) {
                        for (uint sx = lo.x; sx <= hi.x; ++sx) {
                            v = keep(v, tiles[from][(sy - prev_start.y) * TILE + (sx - prev_start.x)]);
                        }
                    }
                }
                tiles[j & 1u][y * TILE + x] = v;
                pyramid.texels[pc.dst_offset[j] + t.y * dst.x + t.x] = v;
            }
        }
        // The level is complete in shared memory before the next one reads it (the bounds are
        // uniform per workgroup, so every invocation reaches this barrier).
        barrier();
        prev_start = start;
        src = dst;
    }
}
