// Visibility-buffer resolve, shared by the input-attachment (tiler subpass) and the sampled
// (desktop) variants: the pixel's surface rebuilt from its id (visbuf_surface.glsl), shaded
// like forward. Alpha coverage was decided in the id pass; texture LOD from the surface's
// analytic derivatives.
#include "visbuf_surface.glsl"
#include "textures.glsl"
#include "shadow.glsl"

// Specialization 2: ALL_MATERIALS shades every pixel (the über-resolve); a material index
// shades that material's pixels only and discards the others' (the per-material resolves, over
// the full screen or over the material's tiles after classification) — the same arithmetic, so
// the same colours.
layout(constant_id = 2) const uint RESOLVE_MATERIAL = ALL_MATERIALS;

layout(location = 0) out vec4 o_color;

void resolve(uint id) {
    if (id == VISBUF_BACKGROUND) {
        discard;
    }
    Mesh mesh = visbuf_mesh(id);
    if (RESOLVE_MATERIAL != ALL_MATERIALS && mesh.material != RESOLVE_MATERIAL) {
        discard;
    }
    Surface s = visbuf_surface(id, mesh, gl_FragCoord.xy);
    Material m = materials[mesh.material];
    vec4 color;
    if (m.texture == NO_TEXTURE) {
        color = m.base_color;
    } else {
        vec2 uv = surface_uv(s);
        vec2 duv_dx, duv_dy;
        surface_uv_grad(s, gl_FragCoord.xy, uv, duv_dx, duv_dy);
        color = material_color_grad(m, uv, duv_dx, duv_dy);
    }
    vec3 n = surface_normal(s);
    vec3 p = s.p0 * s.bc.x + s.p1 * s.bc.y + s.p2 * s.bc.z;
    vec3 c = shade_lit(color.rgb, n, shadow_factor(p, n), frame.params.x);
    c += random_texel_reads(uvec2(gl_FragCoord.xy), frame.material_work.x).rgb
        * float(frame.material_work.y);
    o_color = vec4(c, 1.0);
}
