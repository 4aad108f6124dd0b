#version 450
// Cluster culling (seed 000's cluster and cone culling): a workgroup per chunk of 64 clusters
// of an instance (common/cluster.glsl), run indirectly after the instance test of a phase over
// the chunks of the instances it kept (cull_clusters.comp lists them) — an instance of many
// clusters (a level baked into one mesh) is culled by as many workgroups as it has chunks. For every cluster of a drawn instance: the frustum test of its box, the
// back-facing cone test, and in two-phase culling's late phase the HiZ test against the pyramid
// of the early depth. Writes each cluster's flags and the chunk's number of runs of consecutive
// drawn clusters (a run ends at the chunk's end: chunks are independent, and a run split in two
// draws the same triangles in the same order), added to its entry's (cluster_place.comp places
// the entries' and their groups', cluster_emit.comp writes one command per run and zeroes the
// entries').
//
// Phases (cull.info.y, as cull.comp): 0 frustum; 2 early (knob cluster_early = "clusters"
// only: with "instances" the early phase is hiz-2phase's, whole instances): of the instances
// the early phase draws, the clusters in the frustum and not back-facing that were not found
// occluded last frame; 3 late: every cluster of an instance visible now, tested against the pyramid: what
// passes is the colour pass's (region 0), what of it the early phase did not draw goes to
// region 1 (the late depth pass). An instance not visible now draws nothing in colour: it won
// no pixel in the early depth, or its box would not lie behind that depth's pyramid.
//
// Next frame's cluster visibility: 0 only for a cluster the pyramid found occluded. One outside
// the frustum or back-facing now was not tested against depth, so it is drawn early when it
// comes into view (the early depth then follows a turning camera, though after a cut it can be
// thinner than instance culling's, which draws the whole of each instance visible last frame).
#include "scene.glsl"
#include "cull.glsl"
#include "cull_tests.glsl"
#include "cluster.glsl"

layout(local_size_x = 64) in;

layout(set = 1, binding = 4, std430) readonly buffer Visibility { uint visible_last[]; };
layout(set = 1, binding = 7, std430) readonly buffer Order { uint order[]; };
layout(set = 1, binding = 8, std430) readonly buffer Entries { uint entries[]; };
layout(set = 1, binding = 13, std430) buffer ClusterVisibility { uint cluster_visible[]; };

// How far inside the cone the eye must be beyond what snapping and rounding need: the cone's own
// f32 rounding and the eye's local position (tilegraph_scene::cone::CONE_MARGIN).
const float CONE_MARGIN = 1e-3;

// Previous flag of each region (index 0: none, a run starts at the chunk's first cluster) for
// counting runs.
shared uint prev0[65];
shared uint prev1[65];
shared uint starts0;
shared uint starts1;
// Each region's flags as the tests left them, before gaps are bridged.
shared uint raw[2][64];

// Cluster t's flag in region r once gaps of at most `gap` clusters (knob cluster_gap) between
// two drawn clusters of the chunk are drawn through: one command instead of two, the gap's
// triangles drawn in their place in the unculled order (culled for nothing but cost: the image
// stays equal, and the instance is drawn anyway).
uint bridged(uint r, uint t, uint gap) {
    if (raw[r][t] != 0u) {
        return 1u;
    }
    uint left = 64u;
    for (uint d = 1u; d <= gap && d <= t; ++d) {
        if (raw[r][t - d] != 0u) {
            left = t - d;
            break;
        }
    }
    if (left == 64u) {
        return 0u;
    }
    for (uint d = 1u; d <= gap && t + d < 64u; ++d) {
        if (raw[r][t + d] != 0u) {
            return t + d - left - 1u <= gap ? 1u : 0u;
        }
    }
    return 0u;
}

// The cluster's box in the instance's camera-relative frame (as cull.comp's instance bounds),
// grown by the f32 transform's rounding: relative to the camera-relative result, to the
// instance's translation and to the local coordinates (a one-mesh level's clusters lie far
// from the mesh's origin, while the camera may stand beside them).
Instance cluster_bounds(Instance inst, Cluster cl) {
    Instance b = inst;
    b.center = instance_transform(inst, cl.center);
    vec3 h = cl.half_extents;
    vec3 t = vec3(inst.model_rows[0].w, inst.model_rows[1].w, inst.model_rows[2].w);
    vec3 rows = vec3(length(inst.model_rows[0].xyz), length(inst.model_rows[1].xyz), length(inst.model_rows[2].xyz));
    b.half_extents = vec3(dot(abs(inst.model_rows[0].xyz), h), dot(abs(inst.model_rows[1].xyz), h),
                          dot(abs(inst.model_rows[2].xyz), h));
    b.half_extents += 1e-6 * (length(b.center) + length(b.half_extents) + length(t))
        + 1e-6 * rows * (length(cl.center) + length(h));
    b.radius = length(b.half_extents);
    return b;
}

// Whether every triangle of the cluster faces away from the camera (at the origin of the
// camera-relative frame), whatever the snapping to the sub-pixel grid and the f32 transform do
// to its vertices: the f32 twin of tilegraph_scene::cone::back_facing (its doc derives it), in
// the mesh's local space. `steps`: sub-pixel steps per unit of lateral offset at distance 1.
bool back_facing(Instance inst, Cluster cl, mat3 linear_inverse, float steps) {
    if (cl.cone_cutoff >= 1.0) {
        return false;
    }
    vec3 t = vec3(inst.model_rows[0].w, inst.model_rows[1].w, inst.model_rows[2].w);
    vec3 eye = linear_inverse * -t;
    vec3 d = cl.cone_apex - eye;
    float len = length(d);
    if (!(len > cl.cone_reach)) {
        return false;
    }
    float far = len + cl.cone_reach;
    float rounding = 1e-6 * (length(cl.cone_apex) + cl.cone_reach + length(eye));
    float nu = 1.5 * far / steps + rounding;
    float sin_gamma = nu * (2.2 * cl.cone_thinness * far + 1.0) / len + CONE_MARGIN;
    // The eye must lie within 90° - alpha - gamma of the axis: none left when gamma >= 90° - alpha.
    float cos_alpha = sqrt(max(1.0 - cl.cone_cutoff * cl.cone_cutoff, 0.0));
    if (!(sin_gamma < cos_alpha)) {
        return false;
    }
    float threshold = cl.cone_cutoff * sqrt(1.0 - sin_gamma * sin_gamma) + cos_alpha * sin_gamma;
    return dot(d, cl.cone_axis) >= threshold * len;
}

// Whether the instance's scale is uniform (a rotation times one scale, within rounding): the
// cone test works in local space, where only then angles and the snapping margin carry over.
bool uniform_scale(mat3 linear) {
    mat3 g = transpose(linear) * linear;
    float s = (g[0][0] + g[1][1] + g[2][2]) / 3.0;
    float tol = 1e-4 * s;
    return abs(g[0][0] - s) <= tol && abs(g[1][1] - s) <= tol && abs(g[2][2] - s) <= tol
        && abs(g[0][1]) <= tol && abs(g[0][2]) <= tol && abs(g[1][2]) <= tol;
}

// Culls the clusters of chunk w (uniform over the workgroup: every return is).
void cull_chunk(uint w) {
    uint t = gl_LocalInvocationID.x;
    uint id = chunk_instance(w);
    if (id >= cull.info.x || order[id] == 0xFFFFFFFFu) {
        if (t == 0u) {
            runs[chunk_slot(0u, w)] = 0u;
            runs[chunk_slot(1u, w)] = 0u;
        }
        return;
    }
    uint e = order[id];
    uint phase = cull.info.y;
    bool late = phase == 3u;
    uint region1 = cull.clusters.z;
    // Knob cluster_early = "instances" (cull.clusters.y bit 1): the early phase was
    // hiz-2phase's own (whole instances, the instance compaction's lists; no cluster stage ran
    // early), so every cluster of an instance drawn early is in the early depth.
    bool whole_early = (cull.clusters.y & 2u) != 0u;
    // Late: how many runs the early phase drew in this chunk (0: none of its clusters, whatever
    // its flags and runs hold from older frames: an instance visible now was drawn early unless
    // its late entry is marked). Read by every thread before thread 0 rewrites it.
    bool drawn_early = late && entries[4u * cull.screen.z + e] == 0u;
    uint early_runs = drawn_early && !whole_early ? runs[chunk_slot(0u, w)] : 0u;
    bool drawn = late ? (visible_last[id] & 1u) != 0u : entries[e] != 0u;
    Instance inst = instance_at(id);
    uvec2 range = mesh_clusters[inst.mesh];
    uint first = (w - chunk_first(id)) * 64u;
    if (!drawn || first >= range.y) {
        if (t == 0u) {
            runs[chunk_slot(0u, w)] = 0u;
            runs[chunk_slot(1u, w)] = 0u;
        }
        return;
    }
    // The cone test: single-sided materials, perspective views, transforms that keep the
    // winding (a mirrored instance's front faces are the other side) and scale uniformly.
    mat3 linear = transpose(mat3(inst.model_rows[0].xyz, inst.model_rows[1].xyz, inst.model_rows[2].xyz));
    float steps = uintBitsToFloat(cull.clusters.w);
    bool cone = (cull.clusters.y & 1u) != 0u && materials[meshes[inst.mesh].material].double_sided == 0u
        && determinant(linear) > 0.0 && uniform_scale(linear) && steps > 0.0;
    mat3 linear_inverse = cone ? inverse(linear) : mat3(1.0);
    uint base = cluster_base[id];
    if (t == 0u) {
        prev0[0] = 0u;
        prev1[0] = 0u;
        starts0 = 0u;
        starts1 = 0u;
    }
    barrier();
    uint c = first + t;
    uint f0 = 0u;
    uint f1 = 0u;
    if (c < range.y) {
        uint k = base + c;
        Cluster cl = clusters[range.x + c];
        Instance b = cluster_bounds(inst, cl);
        bool visible = frustum_visible_box(b) && !(cone && back_facing(inst, cl, linear_inverse, steps));
        if (phase == 0u) {
            f0 = visible ? 1u : 0u;
        } else if (phase == 2u) {
            f0 = visible && cluster_visible[k] != 0u ? 1u : 0u;
        } else if (phase == 1u) {
            f0 = visible && hiz_visible_bounds(b, false) ? 1u : 0u;
        } else {
            bool now = visible && hiz_visible_bounds(b, false);
            // Drawn early, bridged gaps included (what the early depth holds).
            bool early = whole_early ? drawn_early : early_runs != 0u && flags[k] != 0u;
            f1 = now && !early ? 1u : 0u;
            f0 = now ? 1u : 0u;
            // Next frame's cluster history: only an early phase of clusters reads it.
            if (!whole_early) {
                cluster_visible[k] = now || !visible ? 1u : 0u;
            }
        }
    }
    raw[0][t] = f0;
    raw[1][t] = f1;
    barrier();
    uint gap = (cull.clusters.y >> 8u) & 0xFFu;
    f0 = bridged(0u, t, gap);
    f1 = bridged(1u, t, gap);
    if (c < range.y) {
        flags[base + c] = f0;
        if (late) {
            flags[region1 + base + c] = f1;
        }
    }
    prev0[t + 1u] = f0;
    prev1[t + 1u] = f1;
    barrier();
    if (f0 == 1u && prev0[t] == 0u) {
        atomicAdd(starts0, 1u);
    }
    if (f1 == 1u && prev1[t] == 0u) {
        atomicAdd(starts1, 1u);
    }
    barrier();
    if (t == 0u) {
        runs[chunk_slot(0u, w)] = starts0;
        runs[chunk_slot(1u, w)] = late ? starts1 : 0u;
        // The entry's runs, summed over its chunks (zero since the last scan).
        if (starts0 != 0u) {
            atomicAdd(runs[e], starts0);
        }
        if (late && starts1 != 0u) {
            atomicAdd(runs[4u * cull.screen.z + e], starts1);
        }
    }
}

void main() {
    uint r = work_region();
    uint n = work_count(r);
    for (uint i = gl_WorkGroupID.x; i < n; i += gl_NumWorkGroups.x) {
        cull_chunk(work_chunk(r, i));
        barrier(); // the next chunk's shared flags and counts start afresh
    }
}
