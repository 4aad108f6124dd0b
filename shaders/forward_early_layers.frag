#version 450
// forward_early.frag with the textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
layout(early_fragment_tests) in;
#include "forward_body.glsl"
