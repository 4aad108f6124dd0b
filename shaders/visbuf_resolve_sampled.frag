#version 450
// Resolve as a separate full-screen pass fetching the id texel (desktop / immediate-mode path).
#include "visbuf_resolve.glsl"

layout(set = 1, binding = 0) uniform usampler2D u_id;

void main() {
    resolve(texelFetch(u_id, ivec2(gl_FragCoord.xy), 0).r);
}
