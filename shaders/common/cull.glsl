// Shared declarations of the culling shaders (cull.comp, cull_compact.comp, cull_commands.comp):
// one parameter block and one descriptor set layout for the three dispatches of a phase.
//
// The lists (docs/ARCHITECTURE.md, "ordered compaction"): 8 lists (opaque / alpha-tested, single- /
// double-sided, early-or-only / late phase) of `stride` entries each. An instance has a fixed
// entry per phase in the unculled draw order; the CPU draw list's instanced draws are the
// groups (one mesh, a run of consecutive entries). cull.comp marks each entry, the compaction
// packs each group's survivors in order, and the command pass writes one instanced indirect
// command per group, in group order.
#ifndef TILEGRAPH_CULL_GLSL
#define TILEGRAPH_CULL_GLSL

// tilegraph_passes::cull::CullParams (std140).
layout(set = 1, binding = 0, std140) uniform CullParams {
    vec4 planes[6];        // camera-relative frustum planes (xyz normal, w distance); (0,0,0,1) = absent
    mat4 hiz_view_proj;    // camera-relative position -> clip space of the frame the pyramid was built in
    uvec4 info;            // x: instances, y: phase, z: HiZ levels (0 = no pyramid), w: 1 reverse-Z
    uvec4 screen;          // x, y: depth size (px) the pyramid maps from, z: list stride, w: 1 = sphere bounds
    uvec4 groups;          // x: groups per phase, y: 1 = keep empty commands (fixed draw count), z: 1 = D16 depth
    uvec4 group_start;     // per list of a phase: its first group
    uvec4 group_count;     // per list of a phase: its number of groups
    // Sphere bounds only:
    mat4 hiz_view;         // camera-relative position -> view space of the frame the pyramid was built in
    vec4 hiz_proj;         // x, y: NDC per view unit (P00, P11); z: 1 perspective, 0 orthographic, -1 neither (test the box)
    vec4 hiz_depth;        // clip z = x * view z + y, clip w = z * view z + w
    // Cluster culling only (common/cluster.glsl):
    uvec4 clusters;        // x: draw id of cluster command 0, y: 1 = back-facing cone test, z: cluster instances,
                           // w: sub-pixel steps per unit of lateral offset at distance 1 (f32 bits; the cone's snapping margin)
    uvec4 cmd_base[2];     // per list (0-7): its first cluster command
    uvec4 commands;        // x: command slots per list (the most draw groups a list holds); clusters:
                           // y first chunks in cluster_base, z chunk instances there, w chunks
    uvec4 triangles;       // per-triangle culling (common/triangles.glsl): x the tail's first index
                           // in the scene's index buffer, y its capacity in indices, z the snapping
                           // step in pixels (f32 bits), w where the tail places start in its buffer
    vec4 lod;              // level of detail (knob lod_error_px): x the largest error in pixels (0: off),
                           // y pixels per unit of length at distance 1 (perspective) or anywhere
                           // (orthographic), z 1 perspective, w the switching band (knob lod_hysteresis)
    uvec4 lod_info;        // x levels per draw group (1: off; commands per group), y meshes in the level table,
                           // z 1 = last frame's levels steer this frame's (no cut, not the first frame)
} cull;

// Levels of detail of a mesh coarser than its own (tilegraph_scene::GpuLod; MAX_LODS per mesh).
const uint MAX_LODS = 6u;
struct Lod {
    uint first_index;
    uint index_count;      // 0: no such level
    float error;           // in the mesh's units
    uint pad;
};

// The cluster techniques' work buffer (cluster.glsl's Work): per region (0 early or only, 1 late)
// its chunk dispatch (x, 1, 1) and chunk count (words 0-7); per phase (0 early or only, 1 late)
// and list 0-7, how many of the list's draw groups cluster_place.comp has placed (words 8-23);
// from WORK_CHUNKS, the regions' chunk lists. A transfer resets words 0-23 every frame.
const uint WORK_CHUNKS = 24u;

// Where an instance's visibility word (cull_body.glsl's Visibility) keeps the level of detail
// it was drawn with (bit 0: two-phase culling's visible last frame).
const uint LEVEL_HISTORY_SHIFT = 8u;

// An entry of a list (cull.comp -> cull_compact.comp): 0 culled, else the instance id + 1 and,
// from bit ENTRY_LEVEL_SHIFT, the level of detail it is drawn with.
const uint ENTRY_LEVEL_SHIFT = 29u;
const uint ENTRY_ID_MASK = (1u << ENTRY_LEVEL_SHIFT) - 1u;

// A draw group: `len` consecutive entries of list `list` (of a phase) from `position`, all of
// mesh `mesh` (a bucket of the scene: the unculled frame's instanced draw). `first`: the entries
// of the list's groups before it in the frame's draw order (the groups are not in entry order:
// the frame orders buckets front to back, say).
struct Group {
    uint position;
    uint len;
    uint mesh;
    uint list;
    uint first;
};

#endif
