#version 450
// Executor tests: post-process reading the scene colour at the same pixel as an input
// attachment (a subpass on tilers) and inverting it.

layout(input_attachment_index = 0, set = 0, binding = 0) uniform subpassInput u_scene;
layout(location = 0) out vec4 o_color;

void main() {
    vec4 c = subpassLoad(u_scene);
    o_color = vec4(1.0 - c.rgb, 1.0);
}
