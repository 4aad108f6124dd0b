#version 450
// Visibility-buffer ids, textures as layers of one image (textures.glsl).
#define TEXTURE_LAYERS 1
#include "visbuf_id.glsl"
