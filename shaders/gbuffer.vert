#version 450
// Deferred texturing's G-buffer pass, instanced through the draw list: what the G-buffer
// stores (normal, UV, material) and no position (the resolve rebuilds it from the depth).
#include "scene.glsl"
// Two-phase culling draws the G-buffer in two passes over one depth; both must round alike.
invariant gl_Position;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec3 v_normal;
layout(location = 1) out vec2 v_uv;
layout(location = 2) flat out uint v_material;

void main() {
    Instance inst = instance_at(draw_instances[gl_InstanceIndex]);
    gl_Position = frame.view_proj * vec4(instance_transform(inst, in_position), 1.0);
    v_normal = instance_normal(inst, in_normal);
    v_uv = in_uv;
    v_material = meshes[inst.mesh].material;
}
