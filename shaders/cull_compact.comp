#version 450
// Ordered compaction, first half: one workgroup per draw group (a mesh's run of consecutive
// entries, common/cull.glsl) packs the ids of the group's surviving entries to the front of the
// group's range of the draw list, in entry order, and writes how many survived. Workgroup w
// handles group w % groups of phase w / groups: the early (or only) dispatch runs one phase,
// the late dispatch both (the early lists again, now the union of both phases, then the late).
// With levels of detail (cull_compact_lod.comp), survivors are counted per group and level.
#include "cull_compact_body.glsl"
