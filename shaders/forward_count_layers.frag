#version 450
// forward_count.frag with the textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
layout(early_fragment_tests) in;
#define COUNT_FRAGMENTS 1
#include "forward_body.glsl"
