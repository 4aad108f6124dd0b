#version 450
// An engine's own material (tests): its vertex shader through tilegraph's include.
#include "include/tilegraph_instance.glsl"
invariant gl_Position;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec3 v_normal;
layout(location = 1) out vec2 v_uv;
layout(location = 2) flat out uint v_instance;

void main() {
    uint id = tilegraph_instance_id(gl_InstanceIndex);
    Instance inst = tilegraph_instance(id);
    gl_Position = tilegraph_clip_position(inst, in_position);
    v_normal = tilegraph_world_normal(inst, in_normal);
    v_uv = in_uv;
    v_instance = id;
}
