#version 450
// Executor tests: visibility-buffer style resolve of a uint id input attachment into a colour.

layout(input_attachment_index = 0, set = 0, binding = 0) uniform usubpassInput u_id;
layout(location = 0) out vec4 o_color;

void main() {
    uint id = subpassLoad(u_id).r;
    o_color = id == 0u ? vec4(0.0, 0.0, 0.0, 1.0) : vec4(float(id & 255u) / 255.0, float((id >> 8) & 255u) / 255.0, 1.0, 1.0);
}
