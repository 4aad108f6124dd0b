#version 450
// Forward colour pass (opaque, alpha-tested, blended), instanced through the draw list.
#include "scene.glsl"
// The depth pre-pass and the colour passes compute the same position in different programs,
// and the colour pass tests EQUAL: without `invariant` a compiler may round them differently.
invariant gl_Position;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec3 v_normal;
layout(location = 1) out vec2 v_uv;
layout(location = 2) flat out uint v_material;
layout(location = 3) out vec3 v_position; // camera-relative (shadow lookups)

void main() {
    Instance inst = instance_at(draw_instances[gl_InstanceIndex]);
    vec3 p = instance_transform(inst, in_position);
    gl_Position = frame.view_proj * vec4(p, 1.0);
    v_position = p;
    v_normal = instance_normal(inst, in_normal);
    v_uv = in_uv;
    v_material = meshes[inst.mesh].material;
}
