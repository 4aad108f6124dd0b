// Deferred texturing's G-buffer (seed 000): 128 bits a pixel in one RGBA32_UINT attachment,
// beside the depth — what a tiler's tile memory holds per pixel without spilling:
//   x: material + 1 (bits 0-11) | octahedral normal, 10 bits a component (bits 12-21, 22-31)
//   y: UV, 16-bit unorm each, reduced to one period of 2 around [0, 1] (see gbuffer_pack_uv)
//   z: d(UV)/dx, two halves;  w: d(UV)/dy, two halves
// A cleared pixel (zero, the value fast clears most commonly take) holds GBUFFER_BACKGROUND in place
// of a material: nothing drew there.
#ifndef TILEGRAPH_GBUFFER_GLSL
#define TILEGRAPH_GBUFFER_GLSL

const uint GBUFFER_BACKGROUND = 0xFFFFFFFFu;

// The normal's octahedral coordinates in [0, 1]^2 (the octahedron unfolded onto a square).
vec2 gbuffer_oct(vec3 n) {
    n /= abs(n.x) + abs(n.y) + abs(n.z);
    vec2 p = n.xy;
    if (n.z < 0.0) {
        vec2 s = vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
        p = (1.0 - abs(n.yx)) * s;
    }
    return p * 0.5 + 0.5;
}

vec3 gbuffer_unoct(vec2 e) {
    vec2 p = e * 2.0 - 1.0;
    vec3 n = vec3(p, 1.0 - abs(p.x) - abs(p.y));
    float t = max(-n.z, 0.0);
    n.x += n.x >= 0.0 ? -t : t;
    n.y += n.y >= 0.0 ? -t : t;
    return normalize(n);
}

// UV with the period of every wrap mode that repeats (1 for repeat, 2 for mirrored repeat)
// taken out, kept in [-0.5, 1.5): exact for both, and for clamp-to-edge wherever a coordinate
// lies within half the texture of [0, 1]. 16 bits over 2: 1/32768 of the texture, an
// eighth of a texel of a 4096-texel texture.
uint gbuffer_pack_uv(vec2 uv) {
    vec2 w = uv - 2.0 * floor((uv + 0.5) * 0.5);
    return packUnorm2x16((w + 0.5) * 0.5);
}

vec2 gbuffer_unpack_uv(uint v) {
    return unpackUnorm2x16(v) * 2.0 - 0.5;
}

uvec4 gbuffer_pack(uint material, vec3 n, vec2 uv, vec2 duv_dx, vec2 duv_dy) {
    uvec2 e = uvec2(round(clamp(gbuffer_oct(n), 0.0, 1.0) * 1023.0));
    // Halves saturate at 65504: a larger derivative picks the smallest mip either way.
    const float HALF_MAX = 65504.0;
    return uvec4(
        ((material + 1u) & 0xFFFu) | (e.x << 12u) | (e.y << 22u),
        gbuffer_pack_uv(uv),
        packHalf2x16(clamp(duv_dx, -HALF_MAX, HALF_MAX)),
        packHalf2x16(clamp(duv_dy, -HALF_MAX, HALF_MAX)));
}

// The pixel's material, or GBUFFER_BACKGROUND.
uint gbuffer_material(uvec4 g) {
    return (g.x & 0xFFFu) - 1u;
}

vec3 gbuffer_normal(uvec4 g) {
    return gbuffer_unoct(vec2((g.x >> 12u) & 0x3FFu, g.x >> 22u) * (1.0 / 1023.0));
}

#endif
