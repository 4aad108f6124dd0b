// The surface a visibility-buffer pixel shows, rebuilt from its id (seed 000): fetch the
// triangle, intersect the pixel's ray with it for exact perspective-correct barycentrics
// (robust when a vertex is behind the camera, unlike 2D barycentrics from projected vertices),
// interpolate the normal and UV. UV derivatives are analytic: the rays through the other pixels
// of this pixel's 2x2 quad hit this triangle's plane at the UVs a forward quad of the triangle
// would difference (its neighbours in the quad may show other triangles, so hardware
// derivatives would be wrong at every edge). Shared by tilegraph's resolve
// (visbuf_resolve.glsl) and the engine's (include/tilegraph_visbuf.glsl).
#ifndef TILEGRAPH_VISBUF_SURFACE_GLSL
#define TILEGRAPH_VISBUF_SURFACE_GLSL

#include "scene.glsl"
#include "visbuf.glsl"

layout(set = 0, binding = 5, std430) readonly buffer Vertices { float vertex_data[]; }; // 8 floats each
layout(set = 0, binding = 6, std430) readonly buffer Indices { uint index_data[]; };

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

// A pixel's surface: its instance (camera-relative), the triangle's eye-relative corners and
// vertices, the ray through the pixel centre and its barycentrics.
struct Surface {
    uint instance;
    Instance inst;
    Vtx v0;
    Vtx v1;
    Vtx v2;
    vec3 p0;
    vec3 p1;
    vec3 p2;
    vec3 ray;
    vec3 bc;
};

// The mesh of the pixel with (non-background) id `id`: its material decides who shades it.
Mesh visbuf_mesh(uint id) {
    return meshes[records[visbuf_unpack(id).x].mesh];
}

// The surface at framebuffer position `px` of the pixel with id `id` (of mesh `mesh`).
Surface visbuf_surface(uint id, Mesh mesh, vec2 px) {
    uvec2 it = visbuf_unpack(id);
    Surface s;
    s.instance = it.x;
    s.inst = instance_at(it.x);
    uint base = mesh.first_index + 3u * it.y;
    s.v0 = load_vertex(uint(int(index_data[base]) + mesh.vertex_offset));
    s.v1 = load_vertex(uint(int(index_data[base + 1u]) + mesh.vertex_offset));
    s.v2 = load_vertex(uint(int(index_data[base + 2u]) + mesh.vertex_offset));
    s.p0 = instance_transform(s.inst, s.v0.p);
    s.p1 = instance_transform(s.inst, s.v1.p);
    s.p2 = instance_transform(s.inst, s.v2.p);
    vec2 ndc = px * frame.viewport.zw * 2.0 - 1.0;
    vec3 o = unproject(ndc, frame.depth_params.x);
    s.ray = unproject(ndc, frame.depth_params.y) - o;
    s.bc = ray_barycentrics(o, s.ray, s.p0, s.p1, s.p2);
    return s;
}

// The interpolated UV.
vec2 surface_uv(Surface s) {
    return s.v0.uv * s.bc.x + s.v1.uv * s.bc.y + s.v2.uv * s.bc.z;
}

// The UV of the pixel at framebuffer position `px` on the surface's triangle.
vec2 surface_uv_at(Surface s, vec2 px) {
    vec2 ndc = px * frame.viewport.zw * 2.0 - 1.0;
    vec3 o = unproject(ndc, frame.depth_params.x);
    vec3 d = unproject(ndc, frame.depth_params.y) - o;
    vec3 b = ray_barycentrics(o, d, s.p0, s.p1, s.p2);
    return s.v0.uv * b.x + s.v1.uv * b.y + s.v2.uv * b.z;
}

// d(uv)/dx and d(uv)/dy at `px` (UV `uv`): the triangle's UV differenced across the pixel's own
// 2x2 quad (its row pair and its column pair), as fine derivatives do in a forward quad, whose
// helper pixels extend the triangle's plane the same way.
void surface_uv_grad(Surface s, vec2 px, vec2 uv, out vec2 duv_dx, out vec2 duv_dy) {
    vec2 side = vec2((int(px.x) & 1) == 0 ? 1.0 : -1.0, (int(px.y) & 1) == 0 ? 1.0 : -1.0);
    vec2 uv_x = surface_uv_at(s, px + vec2(side.x, 0.0));
    vec2 uv_y = surface_uv_at(s, px + vec2(0.0, side.y));
    duv_dx = (uv_x - uv) * side.x;
    duv_dy = (uv_y - uv) * side.y;
}

// The world normal facing the camera (flipped on back faces, from the geometric normal, as
// gl_FrontFacing does in the forward pass).
vec3 surface_normal(Surface s) {
    vec3 n_obj = s.v0.n * s.bc.x + s.v1.n * s.bc.y + s.v2.n * s.bc.z;
    vec3 n = instance_normal(s.inst, n_obj);
    vec3 face = cross(s.p1 - s.p0, s.p2 - s.p0);
    if (dot(face, s.ray) > 0.0) {
        n = -n;
    }
    return n;
}

#endif
