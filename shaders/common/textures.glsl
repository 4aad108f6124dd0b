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
vec4 sample_texture_level0(uint t, vec2 uv) {
    return textureLod(texture_layers, vec3(uv, float(t)), 0.0);
}
uint texture_count() {
    return uint(textureSize(texture_layers, 0).z);
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
vec4 sample_texture_level0(uint t, vec2 uv) {
    return textureLod(textures[nonuniformEXT(t)], uv, 0.0);
}
uint texture_count() {
    return uint(TEXTURE_SLOTS);
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

// The memory-bound material (seed 000's "memory bound" test, `Lighting::random_reads`):
// `reads` texels of level 0 at random places of random textures of the scene, the places a
// hash of the pixel, so neighbouring pixels read far apart and no cache line serves two of
// them. The caller weighs the sum by a uniform that is 0 (frame.material_work.y): the reads
// are made, the image is unchanged. 0 reads: nothing read.
uint texel_hash(uint v) {
    // A 32-bit integer mix (xorshift-multiply rounds): every bit of v reaches every bit out.
    v ^= v >> 16u;
    v *= 0x7feb352du;
    v ^= v >> 15u;
    v *= 0x846ca68bu;
    v ^= v >> 16u;
    return v;
}

vec4 random_texel_reads(uvec2 pixel, uint reads) {
    vec4 sum = vec4(0.0);
    uint count = max(texture_count(), 1u);
    uint h = texel_hash(pixel.x * 0x9e3779b9u ^ texel_hash(pixel.y));
    for (uint i = 0u; i < reads; ++i) {
        h = texel_hash(h + i);
        uint u = texel_hash(h ^ 0x68e31da4u);
        uint v = texel_hash(u);
        vec2 uv = vec2(float(u >> 8u), float(v >> 8u)) * (1.0 / 16777216.0);
        sum += sample_texture_level0(h % count, uv);
    }
    return sum;
}

#endif
