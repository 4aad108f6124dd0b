#version 450
// Depth pre-pass, opaque: positions only, no fragment shader (seed 003: "the Fragment Shader
// does not even need to exist").
#include "scene.glsl"
// The depth pre-pass and the colour passes compute the same position in different programs,
// and the colour pass tests EQUAL: without `invariant` a compiler may round them differently.
invariant gl_Position;
// The bottleneck finder's probe (`tilegraph bottleneck`): 1 = every vertex at one point outside
// the clip volume, the shader's other work skipped: nothing is rasterized (seed 002: "simplify
// the vertex shader to the limit, return fixed coordinates").
layout(constant_id = 0) const uint TRIVIAL_VERTEX = 0u;

layout(location = 0) in vec3 in_position;

void main() {
    if (TRIVIAL_VERTEX == 1u) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        return;
    }
    Instance inst = instance_at(draw_instances[gl_InstanceIndex]);
    gl_Position = frame.view_proj * vec4(instance_transform(inst, in_position), 1.0);
}
