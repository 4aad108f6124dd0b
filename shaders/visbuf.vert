#version 450
// Visibility-buffer write: position (and UV for alpha-tested discard), instance id passed flat.
#include "scene.glsl"
// The depth pre-pass and the colour passes compute the same position in different programs,
// and the colour pass tests EQUAL: without `invariant` a compiler may round them differently.
invariant gl_Position;

layout(location = 0) in vec3 in_position;
layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec2 v_uv;
layout(location = 1) flat out uint v_instance;

void main() {
    uint id = draw_instances[gl_InstanceIndex];
    Instance inst = instance_at(id);
    gl_Position = frame.view_proj * vec4(instance_transform(inst, in_position), 1.0);
    v_uv = in_uv;
    v_instance = id;
}
