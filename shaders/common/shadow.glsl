// The directional light's cascaded shadow maps (tilegraph_passes::shadow): one depth atlas of
// frame.shadow_info.y x .z cascades, each a square of frame.shadow_params.y texels, sampled
// with hardware depth compares (LESS_OR_EQUAL: 1 where the receiver is nearer the light than
// the stored caster) in a (2r + 1)^2 grid of bilinear taps (PCF).
#ifndef TILEGRAPH_SHADOW_GLSL
#define TILEGRAPH_SHADOW_GLSL

#include "scene.glsl"

layout(set = 0, binding = 9) uniform sampler2DShadow shadow_atlas;

// How much of the light reaches camera-relative point `p` with normal `n` (facing the camera):
// 1 beyond the last cascade or without shadows. The cascade is the first whose far distance
// lies beyond the point's view distance; the lookup moves along the normal by a few texels of
// that cascade (normal offset: no self-shadowing on surfaces the light grazes).
float shadow_factor(vec3 p, vec3 n) {
    uint count = frame.shadow_info.x;
    if (count == 0u) {
        return 1.0;
    }
    float dist = dot(p, frame.view_forward.xyz);
    uint c = 0u;
    while (c < count && dist >= frame.shadow_far[c]) {
        c++;
    }
    if (c >= count) {
        return 1.0;
    }
    vec3 q = p + normalize(n) * (frame.shadow_params.x * frame.shadow_texel[c]);
    vec4 clip = frame.shadow_clip[c] * vec4(q, 1.0);
    vec2 uv = clip.xy * 0.5 + 0.5;
    uint cols = frame.shadow_info.y;
    vec2 cell = vec2(float(c % cols), float(c / cols));
    vec2 grid = vec2(float(cols), float(frame.shadow_info.z));
    int r = int(frame.shadow_info.w);
    float sum = 0.0;
    for (int y = -r; y <= r; ++y) {
        for (int x = -r; x <= r; ++x) {
            vec2 at = (uv + vec2(float(x), float(y)) * frame.shadow_params.z + cell) / grid;
            sum += texture(shadow_atlas, vec3(at, clip.z));
        }
    }
    float taps = float((2 * r + 1) * (2 * r + 1));
    return sum / taps;
}

#endif
