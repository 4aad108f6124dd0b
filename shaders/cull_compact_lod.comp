#version 450
// Ordered compaction with levels of detail: cull_compact.comp's, survivors packed per group and
// level (the mesh itself and MAX_LODS coarser levels; common/cull_compact_body.glsl).
#define LOD_LEVELS (1u + MAX_LODS)
#include "cull_compact_body.glsl"
