#version 450
// forward_count_late.frag with the textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#define COUNT_FRAGMENTS 1
#include "forward_body.glsl"
