#version 450
// Deferred texturing's G-buffer, textures indexed (textures.glsl).
#include "gbuffer_write.glsl"
