// Body of deferred texturing's G-buffer pass (gbuffer.frag, gbuffer_layers.frag): the
// material, the normal facing the camera, the UV and its derivatives of the fragment, packed
// (gbuffer.glsl); nothing sampled but an alpha-tested material's coverage.
// ALPHA_TESTED = 1 discards where the forward path does (textures.glsl's material_color).
#include "scene.glsl"
#include "textures.glsl"
#include "gbuffer.glsl"

layout(constant_id = 0) const uint ALPHA_TESTED = 0u;

layout(location = 0) in vec3 v_normal;
layout(location = 1) in vec2 v_uv;
layout(location = 2) flat in uint v_material;
layout(location = 0) out uvec4 o_gbuffer;

void main() {
    // Before any discard: derivatives need the whole quad.
    vec2 duv_dx = dFdx(v_uv);
    vec2 duv_dy = dFdy(v_uv);
    if (ALPHA_TESTED == 1u) {
        Material m = materials[v_material];
        if (alpha_coverage(m, v_uv, material_color(m, v_uv).a) < m.alpha_cutoff) {
            discard;
        }
    }
    vec3 n = normalize(gl_FrontFacing ? v_normal : -v_normal);
    o_gbuffer = gbuffer_pack(v_material, n, v_uv, duv_dx, duv_dy);
}
