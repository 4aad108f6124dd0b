#version 450
// Visibility-buffer write (seed 000): one 32-bit id per pixel, instance and triangle.
// ALPHA_TESTED = 1 discards with the same leaf mask as the forward path.
#include "scene.glsl"
#include "visbuf.glsl"

layout(constant_id = 0) const uint ALPHA_TESTED = 0u;

layout(location = 0) in vec2 v_uv;
layout(location = 1) flat in uint v_instance;
layout(location = 0) out uint o_id;

void main() {
    if (ALPHA_TESTED == 1u) {
        Material m = materials[meshes[records[v_instance].mesh].material];
        if (leaf_alpha(v_uv, m.base_color.a) < m.alpha_cutoff) {
            discard;
        }
    }
    o_id = visbuf_pack(v_instance, uint(gl_PrimitiveID));
}
