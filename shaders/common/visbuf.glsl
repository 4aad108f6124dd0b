// Visibility buffer: the 32-bit id packs (instance << triangle_bits) | triangle, where
// instance_bits = frame.params.y is chosen per scene so that every instance fits with its
// all-ones value left free; 0xFFFFFFFF is the cleared background.
#ifndef TILEGRAPH_VISBUF_GLSL
#define TILEGRAPH_VISBUF_GLSL

const uint VISBUF_BACKGROUND = 0xFFFFFFFFu;

// Material classification (visbuf_classify.comp) tracks materials below this
// (tilegraph_passes::visbuf::MAX_CLASSIFIED_MATERIALS); scenes with more resolve in one pass.
const uint MAX_CLASSIFIED_MATERIALS = 256u;
// RESOLVE_MATERIAL of the über-resolve: every material.
const uint ALL_MATERIALS = 0xFFFFFFFFu;

uint visbuf_pack(uint instance, uint triangle) {
    uint tri_bits = 32u - frame.params.y;
    return (instance << tri_bits) | triangle;
}

uvec2 visbuf_unpack(uint id) {
    uint tri_bits = 32u - frame.params.y;
    uint mask = tri_bits >= 32u ? 0xFFFFFFFFu : ((1u << tri_bits) - 1u);
    return uvec2(tri_bits >= 32u ? 0u : (id >> tri_bits), id & mask);
}

#endif
