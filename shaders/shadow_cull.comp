#version 450
// Shadow-caster culling, one thread per instance slot: for each cascade, a caster (drawn, with
// CASTS_SHADOWS, opaque or alpha-tested) whose box lies outside none of the cascade's planes
// (frame.caster_planes; none with caster culling off) gets a draw in its cascade's list of its
// class: list = cascade * 2 + class, `capacity` slots each.
//
// GPU count: appended (atomic), the count read by vkCmdDrawIndexedIndirectCount. The order of
// a depth-only pass changes no depth (the nearest wins whatever comes first), so the map is the
// same in any order. Fixed count: every instance slot keeps its command, zero instances when
// culled.
#include "scene.glsl"

layout(local_size_x = 64) in;

struct DrawCommand {
    uint index_count;
    uint instance_count;
    uint first_index;
    int vertex_offset;
    uint first_instance;
};

layout(set = 1, binding = 0, std430) writeonly buffer Commands { DrawCommand commands[]; };
layout(set = 1, binding = 1, std430) buffer Counts { uint counts[]; };
layout(set = 1, binding = 2, std430) writeonly buffer Casters { uint caster_ids[]; };
layout(push_constant) uniform Push {
    uint instances;  // instance slots in use
    uint capacity;   // slots per list
    uint fixed_count;
} push;

const uint FLAG_HIDDEN = 1u;
const uint FLAG_CASTS_SHADOWS = 2u;
const uint FLAG_FREE = 0x80000000u;

// Wholly outside one of cascade c's planes (the nearest corner of the box behind it).
bool culled(uint c, vec3 center, vec3 half_size) {
    uint n = frame.caster_counts[c];
    for (uint i = 0u; i < n; ++i) {
        vec4 p = frame.caster_planes[c * MAX_CASTER_PLANES + i];
        if (dot(p.xyz, center) + dot(abs(p.xyz), half_size) + p.w < 0.0) {
            return true;
        }
    }
    return false;
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
        bool draw = cls < 2u && !culled(c, inst.center, inst.half_extents);
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
