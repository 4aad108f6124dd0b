#version 450
// The first-frame smoke test: one triangle from gl_VertexIndex, no vertex buffer.
// Vulkan NDC: y = -1 is the top row, so the apex (y = -0.6) lands in the upper half.

layout(location = 0) out vec3 v_color;

const vec2 POSITIONS[3] = vec2[](vec2(0.0, -0.6), vec2(0.6, 0.6), vec2(-0.6, 0.6));
const vec3 COLORS[3] = vec3[](vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0));

void main() {
    gl_Position = vec4(POSITIONS[gl_VertexIndex], 0.5, 1.0);
    v_color = COLORS[gl_VertexIndex];
}
