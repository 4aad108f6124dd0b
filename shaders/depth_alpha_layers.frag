#version 450
// Depth pre-pass, alpha-tested, textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#include "depth_alpha_body.glsl"
