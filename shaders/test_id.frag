#version 450
// Executor tests: a constant 32-bit id (the visibility-buffer frame's id pass).
#include "test_push.glsl"

layout(location = 0) out uint o_id;

void main() {
    o_id = pc.id;
}
