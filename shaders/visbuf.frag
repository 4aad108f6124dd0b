#version 450
// Visibility-buffer ids, textures indexed (textures.glsl).
#include "visbuf_id.glsl"
