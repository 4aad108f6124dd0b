// tilegraph's visibility buffer, for an engine's own resolve fragment shader (docs/EMBEDDING.md,
// "Engine materials"): the surface a pixel shows, rebuilt from the id tilegraph's id pass wrote.
// Include it from the engine's resolve fragment shader (it includes ../common/ beside it);
// tilegraph supplies the vertex shader (a quad over each screen tile classification found the
// material in) and runs the engine's shader with `visbuf_resolve = classified`.
//
// The contract, in addition to tilegraph_instance.glsl's:
// - set 1 is tilegraph's too (`SceneRenderer::resolve_set_layout`): binding 0 the ids, 1 and 2
//   the classification's lists. The engine's resolve pipeline layout is (tilegraph's set 0,
//   tilegraph's set 1, then its own sets from 2); push constants are its own.
// - Specialization constant 2 is tilegraph's: the scene material the pipeline resolves
//   (tilegraph makes one pipeline per scene material the engine material draws).
// - Call tilegraph_surface first; when it returns false the pixel is another material's (or
//   the background): discard.
// What may change: everything behind the functions (use TilegraphSurface, not the internals).
#ifndef TILEGRAPH_VISBUF_INCLUDE_GLSL
#define TILEGRAPH_VISBUF_INCLUDE_GLSL

#include "../common/visbuf_surface.glsl"

layout(set = 1, binding = 0) uniform usampler2D tilegraph_ids;
layout(constant_id = 2) const uint TILEGRAPH_RESOLVE_MATERIAL = 0xFFFFFFFFu;

// What the pixel shows.
struct TilegraphSurface {
    // The instance (its id, as tilegraph_instance_id gives it in the raster passes).
    uint instance;
    // The tilegraph material (an index into `materials`; the pipeline's).
    uint material;
    // Eye-relative world position (world minus the eye).
    vec3 position;
    // World normal, facing the camera.
    vec3 normal;
    // UV (set 0) and its screen-space derivatives (for textureGrad).
    vec2 uv;
    vec2 uv_dx;
    vec2 uv_dy;
};

// The surface at this fragment; false where the pixel is not this pipeline's material.
bool tilegraph_surface(out TilegraphSurface t) {
    uint id = texelFetch(tilegraph_ids, ivec2(gl_FragCoord.xy), 0).r;
    if (id == VISBUF_BACKGROUND) {
        return false;
    }
    Mesh mesh = visbuf_mesh(id);
    if (mesh.material != TILEGRAPH_RESOLVE_MATERIAL) {
        return false;
    }
    Surface s = visbuf_surface(id, mesh, gl_FragCoord.xy);
    t.instance = s.instance;
    t.material = mesh.material;
    t.position = s.p0 * s.bc.x + s.p1 * s.bc.y + s.p2 * s.bc.z;
    t.normal = surface_normal(s);
    t.uv = surface_uv(s);
    surface_uv_grad(s, gl_FragCoord.xy, t.uv, t.uv_dx, t.uv_dy);
    return true;
}

#endif
