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
layout(location = 2) flat out uint v_first_triangle;

// Cluster culling's commands each draw a run of a mesh's clusters from the run's first index, so
// gl_PrimitiveID counts from the run's first triangle: per cluster command (draw-list slots from
// `run_base` on), that triangle's place in its mesh. A set without cluster commands binds a
// buffer whose `run_base` is past every slot.
layout(set = 0, binding = 10, std430) readonly buffer DrawRuns {
    uint run_base;
    uint run_first_triangle[];
};

void main() {
    uint id = draw_instances[gl_InstanceIndex];
    Instance inst = instance_at(id);
    gl_Position = frame.view_proj * vec4(instance_transform(inst, in_position), 1.0);
    v_uv = in_uv;
    v_instance = id;
    uint slot = uint(gl_InstanceIndex);
    v_first_triangle = slot >= run_base ? run_first_triangle[slot - run_base] : 0u;
}
