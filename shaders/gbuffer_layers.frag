#version 450
// Deferred texturing's G-buffer, textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#include "gbuffer_write.glsl"
