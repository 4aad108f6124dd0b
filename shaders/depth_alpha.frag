#version 450
// Depth pre-pass, alpha-tested, textures indexed (textures.glsl).
#include "depth_alpha_body.glsl"
