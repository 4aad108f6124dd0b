#version 450
// Deferred texturing's resolve as a separate full-screen pass fetching the G-buffer and depth
// texels (desktop / immediate-mode path); textures as layers of one image.
#define TEXTURE_LAYERS 1
#include "gbuffer_resolve.glsl"

layout(set = 1, binding = 0) uniform usampler2D u_gbuffer;
layout(set = 1, binding = 1) uniform sampler2D u_depth;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    resolve(texelFetch(u_gbuffer, px, 0), texelFetch(u_depth, px, 0).r);
}
