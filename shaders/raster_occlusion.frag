#version 450
// Raster occlusion: a fragment of the box survived the early depth test, so the instance may be
// visible. Early tests are forced: without them the store would run for occluded fragments too.
layout(early_fragment_tests) in;

layout(set = 1, binding = 0, std430) writeonly buffer Visible { uint visible[]; };

layout(location = 0) flat in uint v_instance;

void main() {
    visible[v_instance] = 1u;
}
