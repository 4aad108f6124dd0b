// Body of the forward colour shaders (forward.frag, forward_early.frag).
#include "scene.glsl"
#include "textures.glsl"
#include "shadow.glsl"

#ifdef COUNT_FRAGMENTS
layout(set = 0, binding = 7, std430) buffer Counters { uint shaded[4]; } counters;
#endif

layout(constant_id = 0) const uint MATERIAL_CLASS = 0u;
// The bottleneck finder's probe (`tilegraph bottleneck`): 1 = a fixed colour, the material,
// texture and lighting work skipped (seed 002: "simplify the fragment shader to the limit").
layout(constant_id = 2) const uint TRIVIAL_FRAGMENT = 0u;

layout(location = 0) in vec3 v_normal;
layout(location = 1) in vec2 v_uv;
layout(location = 2) flat in uint v_material;
layout(location = 3) in vec3 v_position;
layout(location = 0) out vec4 o_color;

void main() {
#ifdef WRITE_DEPTH
    // The depth it would have: only the test's timing changes (after the shader).
    gl_FragDepth = gl_FragCoord.z;
#endif
    if (TRIVIAL_FRAGMENT == 1u) {
        o_color = vec4(0.5, 0.5, 0.5, 1.0);
        return;
    }
    Material m = materials[v_material];
    vec4 base = material_color(m, v_uv);
    // Nested, not `&&`: a branch on the specialization constant alone, which specialization
    // (and the state lint reading the SPIR-V) removes with the discard for other classes.
    if (MATERIAL_CLASS == 1u) {
        if (alpha_coverage(m, v_uv, base.a) < m.alpha_cutoff) {
            discard;
        }
    }
    vec3 n = gl_FrontFacing ? v_normal : -v_normal;
    vec3 c = shade_lit(base.rgb, n, shadow_factor(v_position, n), frame.params.x);
    c += random_texel_reads(uvec2(gl_FragCoord.xy), frame.material_work.x).rgb
        * float(frame.material_work.y);
    o_color = vec4(c, MATERIAL_CLASS == 2u ? base.a : 1.0);
#ifdef COUNT_FRAGMENTS
    atomicAdd(counters.shaded[MATERIAL_CLASS], 1u);
#endif
}
