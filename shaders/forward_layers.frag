#version 450
// forward.frag with the textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#include "forward_body.glsl"
