// Body of the visibility-buffer write (visbuf.frag, visbuf_layers.frag; seed 000): one 32-bit
// id per pixel, instance and triangle.
// ALPHA_TESTED = 1 discards where the forward path does (textures.glsl's material_color).
#include "scene.glsl"
#include "visbuf.glsl"
#include "textures.glsl"

layout(constant_id = 0) const uint ALPHA_TESTED = 0u;

layout(location = 0) in vec2 v_uv;
layout(location = 1) flat in uint v_instance;
// The mesh's triangle the draw's first primitive is (visbuf.vert: a cluster run's first).
layout(location = 2) flat in uint v_first_triangle;
layout(location = 0) out uint o_id;

void main() {
    if (ALPHA_TESTED == 1u) {
        Material m = materials[meshes[records[v_instance].mesh].material];
        if (alpha_coverage(m, v_uv, material_color(m, v_uv).a) < m.alpha_cutoff) {
            discard;
        }
    }
    o_id = visbuf_pack(v_instance, v_first_triangle + uint(gl_PrimitiveID));
}
