// Visibility-buffer resolve, shared by the input-attachment (tiler subpass) and the sampled
// (desktop) variants: fetch the triangle, intersect the pixel's ray with it for exact
// perspective-correct barycentrics (robust when a vertex is behind the camera, unlike 2D
// barycentrics from projected vertices), interpolate the normal and UV, shade like forward.
// Alpha coverage was decided in the id pass. Texture LOD from analytic derivatives: the rays
// through the other pixels of this pixel's 2x2 quad hit this triangle's plane at the UVs a
// forward quad of the triangle would difference (its neighbours in the quad may show other
// triangles, so hardware derivatives of the resolve would be wrong at every edge).
#include "scene.glsl"
#include "visbuf.glsl"
#include "textures.glsl"

layout(set = 0, binding = 5, std430) readonly buffer Vertices { float vertex_data[]; }; // 8 floats each
layout(set = 0, binding = 6, std430) readonly buffer Indices { uint index_data[]; };

// Specialization 2: ALL_MATERIALS shades every pixel (the über-resolve); a material index
// shades that material's pixels only and discards the others' (the per-material resolves, over
// the full screen or over the material's tiles after classification) — the same arithmetic, so
// the same colours.
layout(constant_id = 2) const uint RESOLVE_MATERIAL = ALL_MATERIALS;

layout(location = 0) out vec4 o_color;

struct Vtx { vec3 p; vec3 n; vec2 uv; };

Vtx load_vertex(uint v) {
    uint b = v * 8u;
    Vtx r;
    r.p = vec3(vertex_data[b], vertex_data[b + 1u], vertex_data[b + 2u]);
    r.n = vec3(vertex_data[b + 3u], vertex_data[b + 4u], vertex_data[b + 5u]);
    r.uv = vec2(vertex_data[b + 6u], vertex_data[b + 7u]);
    return r;
}

vec3 unproject(vec2 ndc, float depth) {
    vec4 h = frame.inv_view_proj * vec4(ndc, depth, 1.0);
    return h.xyz / h.w;
}

// Barycentrics (b0, b1, b2) of the ray's hit with triangle (a, b, c) (Moller-Trumbore, no
// culling: the raster pass already decided the pixel belongs to this triangle).
vec3 ray_barycentrics(vec3 o, vec3 d, vec3 a, vec3 b, vec3 c) {
    vec3 e1 = b - a;
    vec3 e2 = c - a;
    vec3 p = cross(d, e2);
    float det = dot(e1, p);
    float inv = 1.0 / det;
    vec3 t = o - a;
    float u = dot(t, p) * inv;
    vec3 q = cross(t, e1);
    float v = dot(d, q) * inv;
    return vec3(1.0 - u - v, u, v);
}

// The UV of the pixel at framebuffer position `px` on the triangle (p0, p1, p2).
vec2 uv_at(vec2 px, vec3 p0, vec3 p1, vec3 p2, vec2 uv0, vec2 uv1, vec2 uv2) {
    vec2 ndc = px * frame.viewport.zw * 2.0 - 1.0;
    vec3 o = unproject(ndc, frame.depth_params.x);
    vec3 d = unproject(ndc, frame.depth_params.y) - o;
    vec3 b = ray_barycentrics(o, d, p0, p1, p2);
    return uv0 * b.x + uv1 * b.y + uv2 * b.z;
}

void resolve(uint id) {
    if (id == VISBUF_BACKGROUND) {
        discard;
    }
    uvec2 it = visbuf_unpack(id);
    Mesh mesh = meshes[records[it.x].mesh];
    if (RESOLVE_MATERIAL != ALL_MATERIALS && mesh.material != RESOLVE_MATERIAL) {
        discard;
    }
    Instance inst = instance_at(it.x);
    uint base = mesh.first_index + 3u * it.y;
    Vtx v0 = load_vertex(uint(int(index_data[base]) + mesh.vertex_offset));
    Vtx v1 = load_vertex(uint(int(index_data[base + 1u]) + mesh.vertex_offset));
    Vtx v2 = load_vertex(uint(int(index_data[base + 2u]) + mesh.vertex_offset));
    vec3 p0 = instance_transform(inst, v0.p);
    vec3 p1 = instance_transform(inst, v1.p);
    vec3 p2 = instance_transform(inst, v2.p);
    vec2 ndc = gl_FragCoord.xy * frame.viewport.zw * 2.0 - 1.0;
    vec3 o = unproject(ndc, frame.depth_params.x);
    vec3 d = unproject(ndc, frame.depth_params.y) - o;
    vec3 bc = ray_barycentrics(o, d, p0, p1, p2);
    vec3 n_obj = v0.n * bc.x + v1.n * bc.y + v2.n * bc.z;
    Material m = materials[mesh.material];
    vec4 color;
    if (m.texture == NO_TEXTURE) {
        color = m.base_color;
    } else {
        vec2 uv = v0.uv * bc.x + v1.uv * bc.y + v2.uv * bc.z;
        // Difference this triangle's UV across the pixel's own 2x2 quad (its row pair and its
        // column pair), as fine derivatives do in a forward quad, whose helper pixels extend
        // the triangle's plane the same way.
        vec2 px = gl_FragCoord.xy;
        vec2 side = vec2((int(px.x) & 1) == 0 ? 1.0 : -1.0, (int(px.y) & 1) == 0 ? 1.0 : -1.0);
        vec2 uv_x = uv_at(px + vec2(side.x, 0.0), p0, p1, p2, v0.uv, v1.uv, v2.uv);
        vec2 uv_y = uv_at(px + vec2(0.0, side.y), p0, p1, p2, v0.uv, v1.uv, v2.uv);
        color = material_color_grad(m, uv, (uv_x - uv) * side.x, (uv_y - uv) * side.y);
    }
    vec3 n = instance_normal(inst, n_obj);
    // Facing from the geometric normal, as gl_FrontFacing does in the forward pass.
    vec3 face = cross(p1 - p0, p2 - p0);
    if (dot(face, d) > 0.0) {
        n = -n;
    }
    o_color = vec4(shade(color.rgb, n, frame.params.x), 1.0);
}
