// GPU-driven culling, one thread per instance (seeds 000, 002, 004). Marks each instance's fixed
// entry in the list of its draw class (instance id + 1 = drawn, 0 = culled);
// cull_compact.comp and cull_commands.comp then pack the survivors into instanced indirect
// commands (common/cull.glsl).
//
// Phases (cull.info.y):
//   0 frustum      frustum only;
//   1 hiz          frustum + HiZ test against the previous frame's pyramid, projected with the
//                  previous frame's matrices (reprojected to the current eye);
//   2 early        two-phase, first half: what was visible last frame and is in the frustum;
//                  raster occlusion (groups.w != 0): this frame's box flags, or carried;
//   3 late         two-phase, second half: test everything in the frustum against the pyramid
//                  of the early depth; list what is visible and was not drawn early (and add it
//                  to the early lists, which the colour pass then draws); the result is next
//                  frame's visibility.
// Blended instances are not culled here (they are sorted back to front on the CPU).
#include "scene.glsl"
#include "cull.glsl"
#include "cull_tests.glsl"
#include "recheck.glsl"

layout(local_size_x = 64) in;

// Per entry: 0 = culled, instance id + 1 = drawn (read by cull_compact.comp).
layout(set = 1, binding = 8, std430) writeonly buffer Entries { uint entries[]; };
// Per instance: two-phase culling's 0 / 1 (visible last frame); raster occlusion's
// FLAG_PASSED | FLAG_DRAWN (recheck.glsl).
layout(set = 1, binding = 4, std430) buffer Visibility { uint visible_last[]; };
// Per instance: its entry in its list, list * stride + position, in the CPU draw order (the
// order an unculled frame draws in), so the culled frame draws the survivors in the same order
// and ties between coplanar surfaces resolve the same way. ~0u for blended instances.
layout(set = 1, binding = 7, std430) readonly buffer Order { uint order[]; };

// Per mesh, MAX_LODS coarser levels (cull.lod_info.y meshes; a mesh past them has none).
layout(set = 1, binding = 13, std430) readonly buffer Lods { Lod lods[]; };

// The level of detail of `inst`: the coarsest of its levels whose error, projected, stays
// within cull.lod.x pixels (0: the mesh itself) — but no coarser than `last` (the level drawn
// last frame) unless that coarser level's error stays within cull.lod.x * (1 - cull.lod.w) (the
// switching band). A level is never kept past the bound: the finer switch is immediate. The
// choice is idempotent (choosing again from its own result gives it back), so both phases of a
// frame choose the same. The error is scaled by the model matrix's largest stretch (its
// longest column where the columns are orthogonal, else their Frobenius norm, a bound) and
// projected at the nearest point of the instance's bounding sphere: exact on the view axis,
// under by up to the secant of the angle off it at the edge of the view. An eye inside the
// sphere draws the mesh itself.
uint lod_level(Instance inst, uint last) {
    if (cull.lod.x <= 0.0 || inst.mesh >= cull.lod_info.y) {
        return 0u;
    }
    vec3 c0 = vec3(inst.model_rows[0].x, inst.model_rows[1].x, inst.model_rows[2].x);
    vec3 c1 = vec3(inst.model_rows[0].y, inst.model_rows[1].y, inst.model_rows[2].y);
    vec3 c2 = vec3(inst.model_rows[0].z, inst.model_rows[1].z, inst.model_rows[2].z);
    vec3 sq = vec3(dot(c0, c0), dot(c1, c1), dot(c2, c2));
    float largest = max(sq.x, max(sq.y, sq.z));
    float skew = max(abs(dot(c0, c1)), max(abs(dot(c1, c2)), abs(dot(c0, c2))));
    float stretch = sqrt(skew <= 1e-6 * largest ? largest : sq.x + sq.y + sq.z);
    float per_unit = cull.lod.y;
    if (cull.lod.z == 1.0) {
        float distance = length(inst.center) - inst.radius;
        if (!(distance > 0.0)) {
            return 0u;
        }
        per_unit /= distance;
    }
    // level: the coarsest within the bound; banded: the coarsest within the band.
    float banded_px = cull.lod_info.z == 1u ? cull.lod.x * (1.0 - cull.lod.w) : cull.lod.x;
    uint level = 0u;
    uint banded = 0u;
    for (uint k = 0u; k < MAX_LODS; ++k) {
        Lod l = lods[inst.mesh * MAX_LODS + k];
        float px = l.error * stretch * per_unit;
        if (l.index_count == 0u || px > cull.lod.x) {
            break;
        }
        level = k + 1u;
        if (px <= banded_px) {
            banded = k + 1u;
        }
    }
    return level > last ? max(last, banded) : level;
}

// The level instance `id` was drawn with last frame (0 without history: after a cut, in the
// first frame, or with levels off).
uint last_level(uint id) {
    return cull.lod_info.z == 1u ? (visible_last[id] >> LEVEL_HISTORY_SHIFT) & 7u : 0u;
}

// Keeps `level` in instance `id`'s visibility word for the next frame (levels on only).
void keep_level(uint id, uint visible_bit, uint level) {
    if (cull.lod.x > 0.0) {
        visible_last[id] = visible_bit | (level << LEVEL_HISTORY_SHIFT);
    } else {
        visible_last[id] = visible_bit;
    }
}

#ifdef CLUSTER_WORK
// Cluster techniques (cull_clusters.comp): the chunks of the instances whose clusters the phase
// tests, appended to the phase's work list (cluster.glsl's Work) for the cluster dispatches,
// which run indirectly over the drawn instances' chunks only.
layout(set = 1, binding = 11, std430) readonly buffer ClusterBase { uint cluster_base[]; };
layout(set = 1, binding = 12, std430) buffer Work { uint work[]; };

// Appends instance `id`'s chunks to the work list of region `p` (0 early or only, 1 late): the
// chunk count, the dispatch's workgroups (at most 65,535: a workgroup then takes several) and
// the chunks' ids, in whatever order the threads come (each chunk's results have their place).
void append_chunks(uint p, uint id) {
    uint first = cluster_base[cull.commands.y + id];
    uint n = cluster_base[cull.commands.y + id + 1u] - first;
    if (n == 0u) {
        return;
    }
    uint at = atomicAdd(work[4u * p + 3u], n);
    atomicMax(work[4u * p], min(at + n, 65535u));
    for (uint i = 0u; i < n; ++i) {
        work[WORK_CHUNKS + p * cull.commands.w + at + i] = first + i;
    }
}

// Two-phase culling empties each phase's work in the other phase's instance test, so no
// transfer (and barrier) opens the frame: the early test empties the late phase's chunk list
// and placed-group counters, the late test the early phase's for the next frame (made empty
// at creation for the first). Neither phase's test touches the part it empties.
void reset_other_work(uint phase) {
    if (gl_GlobalInvocationID.x != 0u || (phase != 2u && phase != 3u)) {
        return;
    }
    uint other = phase == 2u ? 1u : 0u;
    work[4u * other] = 0u;
    work[4u * other + 1u] = 1u;
    work[4u * other + 2u] = 1u;
    work[4u * other + 3u] = 0u;
    for (uint list = 0u; list < 8u; ++list) {
        work[8u + 8u * other + list] = 0u;
    }
}
#endif

// Marks the instance's entry of list `list`: drawn or not. Entries never move, so the frame is
// deterministic (no atomic append order); the compaction packs them in entry order.
// With levels of detail (cull.lod_info.x > 1) the entry carries the level drawn.
void mark(uint list, uint id, bool draw, uint level) {
    entries[list * cull.screen.z + order[id] % cull.screen.z] =
        draw ? (id + 1u) | (level << ENTRY_LEVEL_SHIFT) : 0u;
}

void main() {
    uint id = gl_GlobalInvocationID.x;
#ifdef CLUSTER_WORK
    reset_other_work(cull.info.y);
#endif
    if (id >= cull.info.x) {
        return;
    }
    Instance inst = instance_at(id);
    if (order[id] == 0xFFFFFFFFu) {
        return;
    }
    uint list = order[id] / cull.screen.z;
    uint phase = cull.info.y;
    uint level = lod_level(inst, last_level(id));
    bool in_frustum = frustum_visible(inst);
    if (phase == 0u) {
        mark(list, id, in_frustum, level);
        if (cull.lod.x > 0.0) {
            keep_level(id, 0u, level);
        }
#ifdef CLUSTER_WORK
        if (in_frustum) {
            append_chunks(0u, id);
        }
#endif
    } else if (phase == 1u) {
        mark(list, id, in_frustum && hiz_visible(inst), level);
        if (cull.lod.x > 0.0) {
            keep_level(id, 0u, level);
        }
    } else if (phase == 2u && cull.groups.w != 0u) {
        // Raster occlusion (cull.groups.w: the packed recheck): a box fragment passed, or the
        // instance was drawn last frame and its box was not tested (recheck.glsl). The word
        // becomes next frame's: drawn or not, this frame's pass flag cleared.
        // A box at the near plane was not drawn (its proxy would be clipped): visible. The
        // test is the vertex shader's, widened so that rounding never makes it disagree.
        uint word = visible_last[id];
        bool near = proxy_crosses_near(inst.center, raster_proxy_half_size(inst.half_extents), 1e-5);
        bool draw = in_frustum && ((word & FLAG_PASSED) != 0u || near
                                   || raster_carried(word, cull.groups.w, id));
        mark(list, id, draw, level);
        visible_last[id] = draw ? FLAG_DRAWN : 0u;
    } else if (phase == 2u) {
        bool was_visible = (visible_last[id] & 1u) != 0u;
        mark(list, id, in_frustum && was_visible, level);
#ifdef CLUSTER_WORK
        // cluster_early = "instances" (cull.clusters.y bit 1): the early phase draws whole
        // instances, no cluster stage runs early.
        if (in_frustum && was_visible && (cull.clusters.y & 2u) == 0u) {
            append_chunks(0u, id);
        }
#endif
    } else {
        bool visible = in_frustum && hiz_visible(inst);
        bool late = visible && (visible_last[id] & 1u) == 0u;
        mark(4u + list, id, late, level);
        if (late) {
            // The colour pass draws the early lists completed with the newly visible: the union,
            // in the unculled order (the late compaction packs the early lists again).
            mark(list, id, true, level);
        }
        keep_level(id, visible ? 1u : 0u, level);
#ifdef CLUSTER_WORK
        // Every cluster of an instance visible now is tested against the pyramid.
        if (visible) {
            append_chunks(1u, id);
        }
#endif
    }
}
