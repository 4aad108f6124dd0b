#version 450
// Shadow-caster culling by the cascades' planes and this frame's camera depth pyramid
// (`receivers-hiz`; common/shadow_cull_body.glsl).
#define RECEIVER_HIZ
#include "shadow_cull_body.glsl"
