#version 450
// Depth pre-pass, alpha-tested: the one place the costly discard runs before colour (seed 001:
// Pre-Z for large alpha-tested objects; seed 003: discard disables early-Z).
#include "scene.glsl"

layout(location = 0) in vec2 v_uv;
layout(location = 1) flat in uint v_material;

void main() {
    Material m = materials[v_material];
    if (leaf_alpha(v_uv, m.base_color.a) < m.alpha_cutoff) {
        discard;
    }
}
