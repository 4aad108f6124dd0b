// Body of the shadow-caster culling (shadow_cull.comp; shadow_cull_hiz.comp defines
// RECEIVER_HIZ), one thread per instance slot: for each cascade, a caster (drawn, with
// CASTS_SHADOWS, opaque or alpha-tested) whose box lies outside none of the cascade's planes
// (frame.caster_planes; none with caster culling off) gets a draw in its cascade's list of its
// class: list = cascade * 2 + class, `capacity` slots each.
//
// RECEIVER_HIZ (caster culling `receivers-hiz`, seed 004's second pass): a caster is dropped
// from a cascade when the volume its shadow can darken — its box swept away from the light down
// to the cascade's lowest receiver, grown by what a lookup reaches — lies behind this frame's
// camera depth pyramid over its whole screen rectangle: no surface the camera sees lies in it.
// The pyramid is the early phase's (two-phase culling); the final depth is nearer or equal
// everywhere, so the test stays exact.
//
// GPU count: appended (atomic), the count read by vkCmdDrawIndexedIndirectCount. The order of
// a depth-only pass changes no depth (the nearest wins whatever comes first), so the map is the
// same in any order. Fixed count: every instance slot keeps its command, zero instances when
// culled.
#include "scene.glsl"

#ifdef RECEIVER_HIZ
#include "cull.glsl"
#include "cull_tests.glsl"
#define LISTS_SET 2
#else
#define LISTS_SET 1
#endif

layout(local_size_x = 64) in;

struct DrawCommand {
    uint index_count;
    uint instance_count;
    uint first_index;
    int vertex_offset;
    uint first_instance;
};

layout(set = LISTS_SET, binding = 0, std430) writeonly buffer Commands { DrawCommand commands[]; };
layout(set = LISTS_SET, binding = 1, std430) buffer Counts { uint counts[]; };
layout(set = LISTS_SET, binding = 2, std430) writeonly buffer Casters { uint caster_ids[]; };
layout(push_constant) uniform Push {
    uint instances;  // instance slots in use
    uint capacity;   // slots per list
    uint fixed_count;
} push;

const uint FLAG_HIDDEN = 1u;
const uint FLAG_CASTS_SHADOWS = 2u;
const uint FLAG_FREE = 0x80000000u;

// Wholly outside one of cascade c's planes (the nearest corner of the box behind it).
bool outside_planes(uint c, vec3 center, vec3 half_size) {
    uint n = frame.caster_counts[c];
    for (uint i = 0u; i < n; ++i) {
        vec4 p = frame.caster_planes[c * MAX_CASTER_PLANES + i];
        if (dot(p.xyz, center) + dot(abs(p.xyz), half_size) + p.w < 0.0) {
            return true;
        }
    }
    return false;
}

#ifdef RECEIVER_HIZ
// The caster's shadow volume in cascade c hidden from the camera: the hull of its box (grown by
// the lookup's reach) and that box moved away from the light down to the cascade's floor, its
// 16 corners projected into this frame's camera (as project_box does for 8).
bool shadow_hidden(uint c, Instance inst) {
    if (cull.info.z == 0u) {
        return false;
    }
    vec3 l = frame.light_dir.xyz;
    vec3 h = inst.half_extents + vec3(frame.caster_reach[c]);
    float top = dot(l, inst.center) + dot(abs(l), h);
    vec3 moved = -l * max(top - frame.caster_floor[c], 0.0);
    bool reverse = cull.info.w == 1u;
    Projected p;
    p.lo = vec2(1e30);
    p.hi = vec2(-1e30);
    p.nearest = reverse ? 0.0 : 1.0;
    for (uint i = 0u; i < 16u; ++i) {
        vec3 s = vec3((i & 1u) != 0u ? 1.0 : -1.0, (i & 2u) != 0u ? 1.0 : -1.0, (i & 4u) != 0u ? 1.0 : -1.0);
        vec3 corner = inst.center + s * h + (i >= 8u ? moved : vec3(0.0));
        vec4 clip = cull.hiz_view_proj * vec4(corner, 1.0);
        if (clip.w <= 1e-6) {
            return false; // reaches the eye's plane: not hidden
        }
        vec3 ndc = clip.xyz / clip.w;
        if (reverse ? ndc.z >= 1.0 : ndc.z <= 0.0) {
            return false;
        }
        p.lo = min(p.lo, ndc.xy);
        p.hi = max(p.hi, ndc.xy);
        p.nearest = reverse ? max(p.nearest, ndc.z) : min(p.nearest, ndc.z);
    }
    return !hiz_rect_visible(p, 4u);
}
#endif

bool culled(uint c, Instance inst) {
    if (outside_planes(c, inst.center, inst.half_extents)) {
        return true;
    }
#ifdef RECEIVER_HIZ
    return shadow_hidden(c, inst);
#else
    return false;
#endif
}

void main() {
    uint id = gl_GlobalInvocationID.x;
    if (id >= push.instances) {
        return;
    }
    uint flags = records[id].flags;
    bool caster = (flags & (FLAG_HIDDEN | FLAG_FREE)) == 0u && (flags & FLAG_CASTS_SHADOWS) != 0u;
    uint cls = 2u;
    Mesh mesh = Mesh(0u, 0u, 0, 0u, vec3(0.0), 0u, vec3(0.0), 0u);
    Instance inst;
    if (caster) {
        inst = instance_at(id);
        mesh = meshes[inst.mesh];
        cls = materials[mesh.material].class_code;
    }
    for (uint c = 0u; c < frame.shadow_info.x; ++c) {
        bool draw = cls < 2u && !culled(c, inst);
        uint list = c * 2u + min(cls, 1u);
        if (push.fixed_count != 0u) {
            // Both lists of the cascade keep this slot's command.
            for (uint k = 0u; k < 2u; ++k) {
                uint slot = (c * 2u + k) * push.capacity + id;
                bool here = draw && k == cls;
                commands[slot] = DrawCommand(mesh.index_count, here ? 1u : 0u, mesh.first_index,
                                             mesh.vertex_offset, slot);
                caster_ids[slot] = id;
            }
        } else if (draw) {
            uint slot = list * push.capacity + atomicAdd(counts[list], 1u);
            commands[slot] = DrawCommand(mesh.index_count, 1u, mesh.first_index,
                                         mesh.vertex_offset, slot);
            caster_ids[slot] = id;
        }
    }
}
