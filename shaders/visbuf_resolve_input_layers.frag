#version 450
// visbuf_resolve_input.frag with the textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#include "visbuf_resolve.glsl"

layout(input_attachment_index = 0, set = 1, binding = 0) uniform usubpassInput u_id;

void main() {
    resolve(subpassLoad(u_id).r);
}
