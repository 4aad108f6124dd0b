#version 450
// Raster occlusion: a fragment of the box survived the early depth test, so the instance may be
// visible. Early tests are forced: without them the store would run for occluded fragments too.
// The flag is written once: every other fragment of a visible box reads it set and stores
// nothing (thousands of fragments storing to one word serialize in the memory system; a load
// of a word already set is served by the cache). A stale read only costs a redundant store.
layout(early_fragment_tests) in;

layout(set = 1, binding = 0, std430) buffer Visible { uint visible[]; };

layout(location = 0) flat in uint v_instance;

void main() {
    // Bit 0 of the word, atomically (bit 1, last frame's drawn flag, which the vertex shader
    // reads, is never written during this pass).
    if ((visible[v_instance] & 1u) == 0u) {
        atomicOr(visible[v_instance], 1u);
    }
}
