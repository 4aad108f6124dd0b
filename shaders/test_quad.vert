#version 450
// Executor tests: an axis-aligned quad (two triangles, six vertices) at a constant depth.
#include "test_push.glsl"

void main() {
    const vec2 corners[6] = vec2[](vec2(0, 0), vec2(1, 0), vec2(1, 1), vec2(0, 0), vec2(1, 1), vec2(0, 1));
    vec2 c = corners[gl_VertexIndex];
    gl_Position = vec4(mix(pc.rect.xy, pc.rect.zw, c), pc.depth, 1.0);
}
