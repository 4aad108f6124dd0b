#version 450
// Classified visibility-buffer resolve: a quad over each screen tile that shows material
// RESOLVE_MATERIAL, from that material's tile list (visbuf_classify.comp); the resolve's
// fragment shader, specialized to the same material, shades that material's pixels only.
#include "common/scene.glsl"

layout(constant_id = 2) const uint RESOLVE_MATERIAL = 0u;
layout(constant_id = 3) const uint TILE = 16u;

layout(set = 1, binding = 1, std430) readonly buffer Tiles { uint tiles[]; };

// Two triangles per tile, corners in tile units.
const uvec2 CORNERS[6] = uvec2[6](uvec2(0, 0), uvec2(1, 0), uvec2(0, 1),
                                  uvec2(0, 1), uvec2(1, 0), uvec2(1, 1));

void main() {
    uvec2 size = uvec2(frame.viewport.xy);
    uvec2 grid = (size + TILE - 1u) / TILE;
    uint tile = tiles[RESOLVE_MATERIAL * (grid.x * grid.y) + uint(gl_VertexIndex) / 6u];
    uvec2 corner = uvec2(tile % grid.x, tile / grid.x) + CORNERS[uint(gl_VertexIndex) % 6u];
    vec2 p = vec2(min(corner * TILE, size));
    gl_Position = vec4(p * frame.viewport.zw * 2.0 - 1.0, 0.0, 1.0);
}
