#version 450
// Executor tests: flat colour from push constants.
#include "test_push.glsl"

layout(location = 0) out vec4 o_color;

void main() {
    o_color = pc.color;
}
