// Shared declarations of the scene passes. Each struct mirrors a Rust #[repr(C)] type; the
// test `shader_layouts` (crates/passes) checks sizes and offsets against the SPIR-V.
#ifndef TILEGRAPH_SCENE_GLSL
#define TILEGRAPH_SCENE_GLSL

// tilegraph_scene::GpuInstance (96 bytes): the resident per-instance record, in world space with
// the translation split into two f32 (high + low; tilegraph_scene::SplitPoint).
struct InstanceRecord {
    vec4 rows[3];          // rows of the linear part; w: translation, high part
    vec3 translation_low;  // translation, low part
    uint mesh;
    vec3 center_offset;    // bounds centre minus translation
    float radius;
    vec3 half_extents;
    uint flags;            // tilegraph_scene::InstanceFlags
};

// An instance relative to the camera (tilegraph_scene::RelativeInstance), as instance_at() makes
// it: the camera-relative affine model matrix as three rows, the camera-relative bounds.
struct Instance {
    vec4 model_rows[3];
    vec3 center;
    uint mesh;
    vec3 half_extents;
    float radius;
};

// tilegraph_scene::GpuMesh (48 bytes).
struct Mesh {
    uint first_index;
    uint index_count;
    int vertex_offset;
    uint material;
    vec3 aabb_min;
    uint pad0;
    vec3 aabb_max;
    uint pad1;
};

// tilegraph_scene::GpuMaterial (32 bytes). class: 0 opaque, 1 alpha-tested, 2 blended;
// texture: the base colour's (textures.glsl), 0xFFFFFFFF for none.
struct Material {
    vec4 base_color;
    uint class_code;
    float alpha_cutoff;
    uint double_sided;
    uint texture;
};

// tilegraph_passes::FrameUniforms (std140).
layout(set = 0, binding = 0, std140) uniform Frame {
    mat4 view_proj;        // camera-relative view (eye at origin) times projection
    vec4 light_dir;        // xyz: unit direction towards the light, w: ambient term
    vec4 light_color;      // rgb: light colour, a: unused
    uvec4 params;          // x: heavy ALU iterations, y: visbuf instance-id bits, z, w: viewport px
    vec4 viewport;         // xy: viewport size in px, zw: 1 / size
    mat4 inv_view_proj;    // for the visibility-buffer resolve's per-pixel rays
    vec4 depth_params;     // x: depth of the near plane (1 reverse-Z, 0 standard), y: mid depth
    vec4 eye_high;         // xyz: the eye's world position, high part
    vec4 eye_low;          // xyz: its low part
    vec4 view_forward;     // xyz: the camera's unit view direction (picks a pixel's cascade)
    // The directional light's cascaded shadow maps (tilegraph_passes::shadow; shadow.glsl).
    mat4 shadow_clip[4];   // per cascade: camera-relative position to the cascade's clip space
    vec4 shadow_far;       // per cascade: the view distance its receivers end at
    vec4 shadow_texel;     // per cascade: a texel's side in metres
    vec4 shadow_params;    // x: normal offset in texels, y: a cascade's side in texels, z: 1 / y
    uvec4 shadow_info;     // x: cascades (0: no shadows), y, z: the atlas's columns and rows,
                           // w: PCF taps either side
    // Per cascade, MAX_CASTER_PLANES planes (n.xyz, d; camera-relative) that cull its casters
    // (shadow_cull.comp), and how many are in use.
    vec4 caster_planes[80];
    uvec4 caster_counts;
    // Per cascade (receivers-hiz): the height towards the light, camera-relative, a caster's
    // shadow can reach down to (the slice's lowest receiver less the reach), and what a lookup
    // reaches past a receiver, metres.
    vec4 caster_floor;
    vec4 caster_reach;
    // x: texels each pixel reads at random of the scene's textures (the memory-bound material,
    // textures.glsl's random_texel_reads; 0 = none); y: their weight in the colour, always 0 (a
    // uniform, so the compiler must make the reads, and the image stays exactly as it is).
    uvec4 material_work;
} frame;

const uint MAX_CASTER_PLANES = 20u;

layout(set = 0, binding = 1, std430) readonly buffer Instances { InstanceRecord records[]; };
// Draw list: gl_InstanceIndex (which includes firstInstance) indexes this to get the instance id.
layout(set = 0, binding = 2, std430) readonly buffer DrawList { uint draw_instances[]; };
layout(set = 0, binding = 3, std430) readonly buffer Meshes { Mesh meshes[]; };
layout(set = 0, binding = 4, std430) readonly buffer Materials { Material materials[]; };

// Instance `id` relative to the eye: the translation is (high - eye high) + (low - eye low), the
// bounds centre that plus the offset, the box grown by a few ulps of each (what rounding the
// centre, the offset and the vertex transform may move a vertex by). `precise`: the same
// operations in every shader, never fused or reordered, so every pass places an instance
// exactly alike (the colour pass's EQUAL depth test needs that) and the CPU twin
// (GpuInstance::relative) agrees.
Instance instance_at(uint id) {
    InstanceRecord r = records[id];
    precise vec3 high = vec3(r.rows[0].w, r.rows[1].w, r.rows[2].w);
    precise vec3 t = (high - frame.eye_high.xyz) + (r.translation_low - frame.eye_low.xyz);
    precise vec3 c = t + r.center_offset;
    vec3 pad = (abs(t) + abs(c) + abs(r.center_offset)) * (2.0 * 1.1920929e-7);
    Instance inst;
    inst.model_rows[0] = vec4(r.rows[0].xyz, t.x);
    inst.model_rows[1] = vec4(r.rows[1].xyz, t.y);
    inst.model_rows[2] = vec4(r.rows[2].xyz, t.z);
    inst.center = c;
    inst.mesh = r.mesh;
    inst.half_extents = r.half_extents + pad;
    inst.radius = r.radius + length(pad);
    return inst;
}

vec3 instance_transform(Instance inst, vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(inst.model_rows[0], h), dot(inst.model_rows[1], h), dot(inst.model_rows[2], h));
}

// Normals: the inverse-transpose of the linear part, computed per vertex (uniform scale is
// common, but glTF allows anything).
vec3 instance_normal(Instance inst, vec3 n) {
    mat3 m = mat3(inst.model_rows[0].xyz, inst.model_rows[1].xyz, inst.model_rows[2].xyz); // rows as columns = transpose
    mat3 linear = transpose(m);
    return normalize(transpose(inverse(linear)) * n);
}

// Alpha-tested materials without a texture (the procedural scenes' leaves) get their coverage
// from a procedural leaf mask on the UVs: a lobed disc. The same function runs in the pre-pass and in the colour
// pass, so both discard exactly the same fragments (EQUAL depth test stays exact).
float leaf_alpha(vec2 uv, float base_alpha) {
    vec2 p = uv * 2.0 - 1.0;
    float r = length(p);
    float lobes = 0.75 + 0.25 * cos(5.0 * atan(p.y, p.x));
    return base_alpha * (r < lobes ? 1.0 : 0.0);
}

// Lambert + ambient with a directional light, plus `iterations` of ALU work that cannot be
// optimised away (models an expensive material; the result is scaled to ~0 contribution).
// `lit`: how much of the light reaches the surface (1 unshadowed, shadow.glsl's factor).
vec3 shade_lit(vec3 base, vec3 n, float lit, uint iterations) {
    float ndl = max(dot(normalize(n), frame.light_dir.xyz), 0.0) * lit;
    vec3 c = base * (frame.light_dir.w + ndl * frame.light_color.rgb);
    float acc = 0.0;
    for (uint i = 0u; i < iterations; ++i) {
        acc = fract(sin(acc * 12.9898 + float(i) * 78.233 + n.x) * 43758.5453);
    }
    return c + vec3(acc * 1e-6);
}

vec3 shade(vec3 base, vec3 n, uint iterations) {
    return shade_lit(base, n, 1.0, iterations);
}

// Occlusion proxies (query boxes, raster-occlusion boxes) coincide with the surfaces they bound
// (a building or a pole is its own box). Two triangles covering the same plane or edge need not
// get the same depth or coverage on every GPU (a few ulps apart on NVIDIA; identical on
// lavapipe), and a proxy a hair behind or inside its own object's silhouette culls a visible
// object; rasterizers also snap vertices to a sub-pixel grid, so a proxy edge can miss a pixel
// centre its object's (differently snapped) edge covers. So a proxy corner is pushed out by
// 1/1024 of the half size, 0.1 mm, and a quarter of a pixel's footprint at the box's centre
// (0.5 / height for a 90-degree view), then scaled towards the eye, which keeps its projection
// (same x/w, y/w) and brings its depth nearer by ~2.4e-4 relative: far more than rounding, far
// less than any real gap.
vec3 proxy_corner(vec3 center, vec3 half_size, vec3 corner_sign) {
    float pixel = length(center) * 0.5 * frame.viewport.w;
    vec3 grown = half_size * (1.0 + 1.0 / 1024.0) + vec3(1e-4 + pixel);
    return (center + grown * corner_sign) * (1.0 - 1.0 / 4096.0);
}

// Corner `c` of a box as a sign per axis (bit 0: +x, bit 1: +y, bit 2: +z).
vec3 proxy_corner_sign(uint c) {
    return vec3(float(c & 1u), float((c >> 1u) & 1u), float((c >> 2u) & 1u)) * 2.0 - 1.0;
}

// How near the near plane a proxy may come and still be rasterized, in NDC depth (2^-12). The
// proxy pipelines bias depth toward the eye by a few units of the depth format (at most 2^-22 for
// a float near 1, 2^-14 for D16: PROXY_DEPTH_BIAS in pipelines.rs), which then stays inside
// [0, 1]. A nearer box counts as crossing the near plane (`crosses_near_plane` on the CPU).
const float NEAR_GUARD = 1.0 / 4096.0;

// Whether one clip-space proxy corner lies behind the eye or within NEAR_GUARD of the near plane;
// `tol` (clip units) widens the test.
bool proxy_corner_near(vec4 clip, bool reverse, float tol) {
    return clip.w <= tol
        || (reverse ? clip.z >= clip.w * (1.0 - NEAR_GUARD) - tol
                    : clip.z <= clip.w * NEAR_GUARD + tol);
}

// Whether a camera-relative box's proxy (its grown corners) reaches the near plane's guard band
// or behind the eye; `margin` widens the test relative to each corner's w.
bool proxy_crosses_near(vec3 center, vec3 half_size, float margin) {
    bool reverse = frame.depth_params.x == 1.0;
    bool near = false;
    for (uint i = 0u; i < 8u; ++i) {
        vec3 corner = proxy_corner(center, half_size, proxy_corner_sign(i));
        vec4 clip = frame.view_proj * vec4(corner, 1.0);
        near = near || proxy_corner_near(clip, reverse, margin * abs(clip.w));
    }
    return near;
}

// The padded f32 half size the raster-occlusion proxies are built from: rounding the
// camera-relative bounds never shrinks the box.
vec3 raster_proxy_half_size(vec3 half_extents) {
    return half_extents * (1.0 + 1e-5) + vec3(1e-5);
}

#endif
