#version 450
// Depth pre-pass, opaque: positions only, no fragment shader (seed 003: "the Fragment Shader
// does not even need to exist").
#include "scene.glsl"
// The depth pre-pass and the colour passes compute the same position in different programs,
// and the colour pass tests EQUAL: without `invariant` a compiler may round them differently.
invariant gl_Position;

layout(location = 0) in vec3 in_position;

void main() {
    Instance inst = instance_at(draw_instances[gl_InstanceIndex]);
    gl_Position = frame.view_proj * vec4(instance_transform(inst, in_position), 1.0);
}
