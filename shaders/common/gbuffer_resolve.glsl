// Deferred texturing's resolve, shared by the input-attachment (tiler subpass) and the
// sampled (desktop) variants: the pixel's material, normal, UV and UV derivatives from the
// G-buffer, its position from the depth, shaded like forward — the textures sampled once a
// pixel, with the derivatives the G-buffer pass took.
#include "scene.glsl"
#include "textures.glsl"
#include "shadow.glsl"
#include "gbuffer.glsl"

layout(location = 0) out vec4 o_color;

void resolve(uvec4 g, float depth) {
    uint material = gbuffer_material(g);
    if (material == GBUFFER_BACKGROUND) {
        discard;
    }
    Material m = materials[material];
    vec2 duv_dx = unpackHalf2x16(g.z);
    vec2 duv_dy = unpackHalf2x16(g.w);
    vec4 color = material_color_grad(m, gbuffer_unpack_uv(g.y), duv_dx, duv_dy);
    vec3 n = gbuffer_normal(g);
    // The camera-relative position: the pixel centre at its depth, unprojected.
    vec2 ndc = gl_FragCoord.xy * frame.viewport.zw * 2.0 - 1.0;
    vec4 h = frame.inv_view_proj * vec4(ndc, depth, 1.0);
    vec3 p = h.xyz / h.w;
    vec3 c = shade_lit(color.rgb, n, shadow_factor(p, n), frame.params.x);
    c += random_texel_reads(uvec2(gl_FragCoord.xy), frame.material_work.x).rgb
        * float(frame.material_work.y);
    o_color = vec4(c, 1.0);
}
