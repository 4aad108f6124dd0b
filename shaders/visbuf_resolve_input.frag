#version 450
// Resolve as a subpass reading the id as an input attachment: on a tiler the id never leaves
// tile memory (seed 000, visibility buffer; seed 001, GMEM load/store).
#include "visbuf_resolve.glsl"

layout(input_attachment_index = 0, set = 1, binding = 0) uniform usubpassInput u_id;

void main() {
    resolve(subpassLoad(u_id).r);
}
