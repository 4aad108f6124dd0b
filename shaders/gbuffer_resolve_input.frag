#version 450
// Deferred texturing's resolve as a subpass reading the G-buffer and the depth as input
// attachments: on a tiler neither leaves tile memory.
#include "gbuffer_resolve.glsl"

layout(input_attachment_index = 0, set = 1, binding = 0) uniform usubpassInput u_gbuffer;
layout(input_attachment_index = 1, set = 1, binding = 1) uniform subpassInput u_depth;

void main() {
    resolve(subpassLoad(u_gbuffer), subpassLoad(u_depth).r);
}
