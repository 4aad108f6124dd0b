// tilegraph's scene, for an engine's own material shaders (docs/EMBEDDING.md, "Engine
// materials"). Include it from the engine's vertex and fragment shaders (it includes
// ../common/scene.glsl beside it); target Vulkan 1.2 or later.
//
// The contract, what tilegraph keeps stable between versions of one major release:
// - set 0 is tilegraph's (scene.glsl): 0 frame uniforms, 1 instance records, 2 the draw list,
//   3 meshes, 4 materials, 5 vertices, 6 indices, 7 counters, 8 textures. The engine's pipeline
//   layout has tilegraph's set-0 layout (`SceneRenderer::scene_set_layout`) as set 0; its own
//   sets start at 1, and push constants are its own.
// - Vertex input: location 0 position (vec3), 1 normal (vec3), 2 uv (vec2), 32-byte stride.
// - gl_InstanceIndex indexes the draw list (`draw_instances`), whose entry is the instance id:
//   pass it to tilegraph_instance_id (a parameter, so the include compiles in any stage).
// - Positions: `tilegraph_clip_position` computes exactly what tilegraph's depth pre-pass
//   computes, so an engine colour shader passes the EQUAL depth test after that pre-pass. The
//   engine's vertex shader must declare `invariant gl_Position;`.
// What may change: the struct layouts behind set 0 (use the functions below, not the fields).
#ifndef TILEGRAPH_INSTANCE_GLSL
#define TILEGRAPH_INSTANCE_GLSL

#include "../common/scene.glsl"

// The id of the instance a vertex belongs to: tilegraph_instance_id(gl_InstanceIndex).
uint tilegraph_instance_id(int instance_index) {
    return draw_instances[instance_index];
}

// Instance `id` relative to the eye (camera-relative model rows and bounds).
Instance tilegraph_instance(uint id) {
    return instance_at(id);
}

// Clip-space position of object-space `p`, as every tilegraph pass computes it.
vec4 tilegraph_clip_position(Instance inst, vec3 p) {
    return frame.view_proj * vec4(instance_transform(inst, p), 1.0);
}

// Eye-relative world position (world minus the eye: small numbers near the camera).
vec3 tilegraph_relative_position(Instance inst, vec3 p) {
    return instance_transform(inst, p);
}

// World-space normal of object-space `n` (inverse transpose of the linear part).
vec3 tilegraph_world_normal(Instance inst, vec3 n) {
    return instance_normal(inst, n);
}

// The tilegraph material of the instance's mesh (an index into `materials`).
uint tilegraph_material(Instance inst) {
    return meshes[inst.mesh].material;
}

// The directional light tilegraph shades with: xyz the direction towards it, w the ambient.
vec4 tilegraph_light() {
    return frame.light_dir;
}

#endif
