#version 450
// GPU-driven instance culling (common/cull_body.glsl).
#include "cull_body.glsl"
