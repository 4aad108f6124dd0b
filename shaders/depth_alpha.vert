#version 450
// Depth pre-pass, alpha-tested: position and UV, for the discard in depth_alpha.frag.
#include "scene.glsl"
// The depth pre-pass and the colour passes compute the same position in different programs,
// and the colour pass tests EQUAL: without `invariant` a compiler may round them differently.
invariant gl_Position;

layout(location = 0) in vec3 in_position;
layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec2 v_uv;
layout(location = 1) flat out uint v_material;

void main() {
    Instance inst = instance_at(draw_instances[gl_InstanceIndex]);
    gl_Position = frame.view_proj * vec4(instance_transform(inst, in_position), 1.0);
    v_uv = in_uv;
    v_material = meshes[inst.mesh].material;
}
