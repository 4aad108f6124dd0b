#version 450
// visbuf_resolve_sampled.frag with the textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#include "visbuf_resolve.glsl"

layout(set = 1, binding = 0) uniform usampler2D u_id;

void main() {
    resolve(texelFetch(u_id, ivec2(gl_FragCoord.xy), 0).r);
}
