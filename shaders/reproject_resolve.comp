#version 450
// Depth reprojection, second half: each pixel's key (reproject.comp) as a depth in the new
// pyramid's level 0. A pixel nothing landed on (a crack where a surface came closer and its
// samples spread apart) takes the farthest depth that landed in its 3x3 neighbourhood, and is
// far (no occlusion) when nothing did: one far texel would make every coarser texel above it far.
// The pyramid's further levels are reduced from it as any HiZ pyramid's (hiz_reduce*.comp).

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 1, std430) readonly buffer Keys { uint keys[]; };
layout(set = 0, binding = 2, std430) writeonly buffer Reprojected { float reprojected[]; };

layout(push_constant) uniform Push {
    mat4 now_from_previous;
    uvec4 info; // x, y: level 0 size; z: 1 reverse-Z; w: level 0's first texel
} pc;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    uvec2 size = pc.info.xy;
    if (any(greaterThanEqual(p, size))) {
        return;
    }
    bool reverse = pc.info.z == 1u;
    uint i = p.y * size.x + p.x;
    uint key = keys[i];
    if (key == 0xFFFFFFFFu) {
        // The smallest key is the farthest depth (reproject.comp keeps the minimum) and the
        // empty key the largest: the neighbours' minimum is their farthest landed depth.
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
                ivec2 q = ivec2(p) + ivec2(dx, dy);
                if (all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, ivec2(size)))) {
                    key = min(key, keys[uint(q.y) * size.x + uint(q.x)]);
                }
            }
        }
    }
    float d = reverse ? 0.0 : 1.0;
    if (key != 0xFFFFFFFFu) {
        d = uintBitsToFloat(reverse ? key : ~key);
    }
    reprojected[pc.info.w + i] = d;
}
