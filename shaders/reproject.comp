#version 450
// Depth reprojection (seed 000; seed 002's previous-frame depth), first half: every texel of
// last frame's depth (the pyramid's level 0, built at the end of that frame) is moved into this
// frame's view and lands on one pixel, keeping the farthest depth of whatever lands there
// (atomicMin on an order-preserving key). Pixels nothing lands on stay empty: far, no
// occlusion. reproject_resolve.comp turns the keys into the new pyramid's level 0.
//
// Not conservative: a texel is a point sample, so a pixel it lands on is taken as covered
// although the surface may not reach that pixel's centre (docs/CULLING.md measures the misses).

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, std430) readonly buffer Previous { float previous[]; };
// Per pixel: 0xFFFFFFFF empty, else the key of the farthest depth that landed there.
layout(set = 0, binding = 1, std430) buffer Keys { uint keys[]; };

layout(push_constant) uniform Push {
    // Last frame's NDC (x, y, depth, 1) -> this frame's clip space (camera-relative, f64 on the
    // CPU then rounded).
    mat4 now_from_previous;
    // x, y: level 0 size; z: 1 reverse-Z; w: level 0's first texel.
    uvec4 info;
} pc;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    uvec2 size = pc.info.xy;
    if (any(greaterThanEqual(p, size))) {
        return;
    }
    bool reverse = pc.info.z == 1u;
    float d = previous[pc.info.w + p.y * size.x + p.x];
    if (d == (reverse ? 0.0 : 1.0)) {
        return; // nothing drawn there last frame
    }
    vec2 ndc = (vec2(p) + 0.5) / vec2(size) * 2.0 - 1.0;
    vec4 clip = pc.now_from_previous * vec4(ndc, d, 1.0);
    if (clip.w <= 1e-6) {
        return; // behind this frame's camera
    }
    vec3 n = clip.xyz / clip.w;
    if (n.z < 0.0 || n.z > 1.0) {
        return;
    }
    vec2 f = floor((n.xy * 0.5 + 0.5) * vec2(size));
    if (any(lessThan(f, vec2(0.0))) || any(greaterThanEqual(f, vec2(size)))) {
        return;
    }
    uvec2 q = uvec2(f);
    // The farthest wins: reverse-Z's smallest depth, standard's largest (its bits inverted).
    // Depths are in [0, 1], so the keys never reach the empty 0xFFFFFFFF but for standard
    // depth 0 (the near plane itself), which stays empty: far, the safe side.
    uint bits = floatBitsToUint(n.z);
    atomicMin(keys[q.y * size.x + q.x], reverse ? bits : ~bits);
}
