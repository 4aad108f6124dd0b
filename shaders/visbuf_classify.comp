#version 450
// Material classification of the visibility buffer (seed 000): one workgroup per screen tile
// finds the materials its pixels show, then appends the tile to each of those materials' tile
// lists and grows that material's indirect draw (six vertices, one quad, per tile). Each
// material's resolve then shades its own tiles only (visbuf_tile.vert).
#include "common/scene.glsl"
#include "common/visbuf.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
// The tile's side in pixels (8, 16 or 32: knob classify_tile).
layout(constant_id = 3) const uint TILE = 16u;

// Materials a tile can name: 32 per word.
const uint MASK_WORDS = MAX_CLASSIFIED_MATERIALS / 32u;

layout(set = 1, binding = 0) uniform usampler2D u_id;
layout(set = 1, binding = 1, std430) writeonly buffer Tiles { uint tiles[]; };
// Per material: VkDrawIndirectCommand (vertexCount, instanceCount, firstVertex, firstInstance),
// zeroed before the dispatch.
layout(set = 1, binding = 2, std430) buffer Commands { uint commands[]; };

shared uint mask[MASK_WORDS];

void main() {
    uint t = gl_LocalInvocationIndex;
    if (t < MASK_WORDS) {
        mask[t] = 0u;
    }
    barrier();
    ivec2 size = ivec2(frame.viewport.xy);
    ivec2 origin = ivec2(gl_WorkGroupID.xy * TILE);
    for (uint y = gl_LocalInvocationID.y; y < TILE; y += 8u) {
        for (uint x = gl_LocalInvocationID.x; x < TILE; x += 8u) {
            ivec2 p = origin + ivec2(x, y);
            if (p.x >= size.x || p.y >= size.y) {
                continue;
            }
            uint id = texelFetch(u_id, p, 0).r;
            if (id == VISBUF_BACKGROUND) {
                continue;
            }
            uint m = meshes[records[visbuf_unpack(id).x].mesh].material;
            atomicOr(mask[m >> 5u], 1u << (m & 31u));
        }
    }
    barrier();
    if (t < MASK_WORDS) {
        uvec2 grid = (uvec2(size) + TILE - 1u) / TILE;
        uint capacity = grid.x * grid.y;
        uint tile = gl_WorkGroupID.y * grid.x + gl_WorkGroupID.x;
        uint bits = mask[t];
        while (bits != 0u) {
            uint b = uint(findLSB(bits));
            bits &= bits - 1u;
            uint m = t * 32u + b;
            uint slot = atomicAdd(commands[4u * m], 6u) / 6u;
            commands[4u * m + 1u] = 1u;
            tiles[m * capacity + slot] = tile;
        }
    }
}
