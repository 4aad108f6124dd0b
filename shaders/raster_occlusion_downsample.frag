#version 450
// Conservative low-resolution depth for raster occlusion at about 1/k resolution: each texel
// keeps the farthest depth (reverse-Z: the smallest value) of every full-resolution pixel whose
// centre falls in it (plus a margin), so whatever passes the depth test at full resolution
// passes here too. The low-resolution size is ceil(size / k), so a texel spans `scale` =
// size / ceil(size / k) <= k full-resolution pixels, not exactly k.
layout(set = 0, binding = 0) uniform sampler2D u_depth;

layout(push_constant) uniform Params {
    vec4 scale; // xy: full-resolution pixels per texel
    uvec4 info; // x: 1 for reverse-Z, yz: full-resolution size in px
} params;

void main() {
    bool reverse = params.info.x == 1u;
    ivec2 last = ivec2(params.info.yz) - 1;
    vec2 j = floor(gl_FragCoord.xy);
    ivec2 lo = clamp(ivec2(floor(j * params.scale.xy - 0.5)), ivec2(0), last);
    ivec2 hi = clamp(ivec2(ceil((j + 1.0) * params.scale.xy - 0.5)), ivec2(0), last);
    float far_depth = reverse ? 1.0 : 0.0;
    for (int y = lo.y; y <= hi.y; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
            float d = texelFetch(u_depth, ivec2(x, y), 0).r;
            far_depth = reverse ? min(far_depth, d) : max(far_depth, d);
        }
    }
    gl_FragDepth = far_depth;
}
