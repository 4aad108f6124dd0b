#version 450
// Shadow-caster culling by the cascades' planes (common/shadow_cull_body.glsl).
#include "shadow_cull_body.glsl"
