#version 450
// Forward colour pass (opaque, alpha-tested, blended), instanced through the draw list.
#include "scene.glsl"
// The depth pre-pass and the colour passes compute the same position in different programs,
// and the colour pass tests EQUAL: without `invariant` a compiler may round them differently.
invariant gl_Position;
// The bottleneck finder's probe (`tilegraph bottleneck`): 1 = every vertex at one point outside
// the clip volume, the shader's other work skipped: nothing is rasterized (seed 002: "simplify
// the vertex shader to the limit, return fixed coordinates").
layout(constant_id = 0) const uint TRIVIAL_VERTEX = 0u;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec3 v_normal;
layout(location = 1) out vec2 v_uv;
layout(location = 2) flat out uint v_material;
layout(location = 3) out vec3 v_position; // camera-relative (shadow lookups)

void main() {
    if (TRIVIAL_VERTEX == 1u) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        v_normal = vec3(0.0);
        v_uv = vec2(0.0);
        v_material = 0u;
        v_position = vec3(0.0);
        return;
    }
    Instance inst = instance_at(draw_instances[gl_InstanceIndex]);
    vec3 p = instance_transform(inst, in_position);
    gl_Position = frame.view_proj * vec4(p, 1.0);
    v_position = p;
    v_normal = instance_normal(inst, in_normal);
    v_uv = in_uv;
    v_material = meshes[inst.mesh].material;
}
