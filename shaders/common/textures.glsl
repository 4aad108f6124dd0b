// The scene's material textures (tilegraph_passes::gpu_scene::textures) at set 0, binding 8,
// bound one of two ways (the profile and the device choose; each shader that samples them is
// compiled once per way, the `_layers` files defining TEXTURE_LAYERS):
// - indexed: TEXTURE_SLOTS textures, texture t in slot t, each with its own size and sampler;
//   indexed per pixel (nonuniformEXT: shaderSampledImageArrayNonUniformIndexing);
// - layers: one array image, texture t in layer t, every texture resampled to one size; no
//   descriptor indexing at all, so it runs on every device.
#ifndef TILEGRAPH_TEXTURES_GLSL
#define TILEGRAPH_TEXTURES_GLSL

#include "scene.glsl"

const uint NO_TEXTURE = 0xFFFFFFFFu;

#ifdef TEXTURE_LAYERS
layout(set = 0, binding = 8) uniform sampler2DArray texture_layers;

vec4 sample_texture(uint t, vec2 uv) {
    return texture(texture_layers, vec3(uv, float(t)));
}
vec4 sample_texture_grad(uint t, vec2 uv, vec2 duv_dx, vec2 duv_dy) {
    return textureGrad(texture_layers, vec3(uv, float(t)), duv_dx, duv_dy);
}
#else
#extension GL_EXT_nonuniform_qualifier : require
layout(constant_id = 1) const int TEXTURE_SLOTS = 1;
layout(set = 0, binding = 8) uniform sampler2D textures[TEXTURE_SLOTS];

// nonuniformEXT in the raster passes too: one subgroup may hold fragments of several draws of
// a multi-draw, so even a per-draw material is not dynamically uniform there.
vec4 sample_texture(uint t, vec2 uv) {
    return texture(textures[nonuniformEXT(t)], uv);
}
vec4 sample_texture_grad(uint t, vec2 uv, vec2 duv_dx, vec2 duv_dy) {
    return textureGrad(textures[nonuniformEXT(t)], uv, duv_dx, duv_dy);
}
#endif

// The material's base colour at `uv`, the factor times the texture (implicit derivatives: the
// raster passes); alpha likewise. An untextured material reads no texture at all.
vec4 material_color(Material m, vec2 uv) {
    if (m.texture == NO_TEXTURE) {
        return m.base_color;
    }
    return m.base_color * sample_texture(m.texture, uv);
}

// The same with explicit UV derivatives per pixel (the visibility-buffer resolve, which has
// no neighbouring fragments of the same triangle to difference).
vec4 material_color_grad(Material m, vec2 uv, vec2 duv_dx, vec2 duv_dy) {
    if (m.texture == NO_TEXTURE) {
        return m.base_color;
    }
    return m.base_color * sample_texture_grad(m.texture, uv, duv_dx, duv_dy);
}

// An alpha-tested material's coverage at `uv`, given its colour's alpha: that alpha where it
// has a texture, the procedural leaf mask where not. Called only by alpha-tested shaders (the
// mask's atan and cos are not paid by anything else).
float alpha_coverage(Material m, vec2 uv, float alpha) {
    return m.texture == NO_TEXTURE ? leaf_alpha(uv, m.base_color.a) : alpha;
}

#endif
