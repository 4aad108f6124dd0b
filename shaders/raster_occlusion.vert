#version 450
// Raster occlusion: every instance's camera-relative bounding box (instance = gl_InstanceIndex,
// vertex = corner: an indexed draw of the box's 12 triangles over 8 corners, BOX_INDICES in
// occlusion/raster.rs, no vertex buffer), depth tested against the pre-pass depth, nothing
// written but the fragment shader's visibility flag. A box that reaches the near plane (or its
// guard band, NEAR_GUARD) would be clipped and could miss: it draws nothing, and cull.comp counts
// it visible (the same test, widened).
#include "scene.glsl"
#include "recheck.glsl"

layout(location = 0) flat out uint v_instance;

// Per instance: FLAG_PASSED (this frame, the fragment shader) | FLAG_DRAWN (last frame).
layout(set = 1, binding = 0, std430) readonly buffer Visible { uint visible[]; };

// x: the packed recheck (recheck.glsl): an instance drawn last frame whose turn has not come is
// not tested (cull.comp draws it).
layout(push_constant) uniform Push { uvec4 recheck; } push;

// 1: the box itself, at full resolution. k > 1: against a 1/k-resolution farthest-depth image,
// where a small box could miss every low-resolution pixel centre; instead its screen rectangle,
// grown by one low-resolution pixel, at the box's nearest depth (conservative: the object's
// depth at any pixel is no nearer than that, the low-resolution depth no nearer than the
// full-resolution one).
layout(constant_id = 0) const uint SCALE = 1u;


void main() {
    uint id = uint(gl_InstanceIndex);
    v_instance = id;
    if (raster_carried(visible[id], push.recheck.x, id)) {
        gl_Position = vec4(2.0, 2.0, 0.5, 1.0); // every vertex on one point off screen
        return;
    }
    Instance inst = instance_at(id);
    // f32 camera-relative bounds: pad by a few ulps so rounding never shrinks the box.
    vec3 half_size = raster_proxy_half_size(inst.half_extents);
    bool reverse = frame.depth_params.x == 1.0;
    bool crosses = false;
    // Outcodes: bit k set while every corner lies beyond side k of the clip volume (x < -w,
    // x > w, y < -w, y > w) or behind the eye (w <= 0). The box is the hull of its corners and
    // clip space is linear in them, so a bit still set after all 8 puts the whole box outside:
    // it draws nothing (and is not counted as crossing the near plane: without the outcodes,
    // every box the eye's plane cuts — a row of buildings across the whole city — would).
    uint outside = 31u;
    for (uint i = 0u; i < 8u; ++i) {
        // The corners drawn below (grown toward the eye), not the box's own.
        vec3 corner = proxy_corner(inst.center, half_size, proxy_corner_sign(i));
        vec4 clip = frame.view_proj * vec4(corner, 1.0);
        crosses = crosses || proxy_corner_near(clip, reverse, 0.0);
        // A relative margin: rounding must never put a touching box outside.
        float tol = 1e-5 * abs(clip.w) + 1e-6;
        uint code = (clip.x < -clip.w - tol ? 1u : 0u) | (clip.x > clip.w + tol ? 2u : 0u)
                  | (clip.y < -clip.w - tol ? 4u : 0u) | (clip.y > clip.w + tol ? 8u : 0u)
                  | (clip.w < -tol ? 16u : 0u);
        outside &= code;
    }
    if (outside != 0u || crosses) {
        // Outside: nothing to test. Crossing the near plane: cull.comp counts it visible.
        gl_Position = vec4(2.0, 2.0, 0.5, 1.0); // every vertex on one point off screen
        return;
    }
    uint c = uint(gl_VertexIndex);
    if (SCALE > 1u) {
        vec2 lo = vec2(1e30);
        vec2 hi = vec2(-1e30);
        float nearest = reverse ? 0.0 : 1.0;
        for (uint i = 0u; i < 8u; ++i) {
            vec4 clip = frame.view_proj * vec4(inst.center + proxy_corner_sign(i) * half_size, 1.0);
            vec3 ndc = clip.xyz / clip.w;
            lo = min(lo, ndc.xy);
            hi = max(hi, ndc.xy);
            nearest = reverse ? max(nearest, ndc.z) : min(nearest, ndc.z);
        }
        // A few ulps nearer, against rounding in the divide.
        nearest = reverse ? min(uintBitsToFloat(floatBitsToUint(nearest) + 4u), 1.0)
                          : uintBitsToFloat(max(floatBitsToUint(nearest), 4u) - 4u);
        vec2 pad = 2.0 * float(SCALE) * frame.viewport.zw;
        lo -= pad;
        hi += pad;
        // Corners 0-3 are the rectangle's (bit 0: right, bit 1: bottom): the -z face's two
        // triangles (0, 2, 1), (1, 2, 3) cover it front-facing. Corners 4-7 collapse onto its
        // top-left corner: the other faces draw nothing or part of the rectangle again.
        vec2 p = vec2((c & 1u) != 0u ? hi.x : lo.x, (c & 2u) != 0u ? hi.y : lo.y);
        gl_Position = vec4(c < 4u ? p : lo, nearest, 1.0);
        return;
    }
    gl_Position = frame.view_proj * vec4(proxy_corner(inst.center, half_size, proxy_corner_sign(c)), 1.0);
}
