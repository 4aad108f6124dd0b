#version 450
// forward_late_depth.frag with the textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#define WRITE_DEPTH 1
#include "forward_body.glsl"
