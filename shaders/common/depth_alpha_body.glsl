// Body of the alpha-tested depth pre-pass (depth_alpha.frag, depth_alpha_layers.frag): the one
// place the costly discard runs before colour (seed 001: Pre-Z for large alpha-tested objects;
// seed 003: discard disables early-Z).
#include "scene.glsl"
#include "textures.glsl"

layout(location = 0) in vec2 v_uv;
layout(location = 1) flat in uint v_material;

void main() {
    Material m = materials[v_material];
    if (alpha_coverage(m, v_uv, material_color(m, v_uv).a) < m.alpha_cutoff) {
        discard;
    }
}
