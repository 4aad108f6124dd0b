#version 450
// Indirect commands with levels of detail: cull_commands.comp's, one per group and level, the
// level's index range (common/cull_commands_body.glsl).
#define LOD_LEVELS (1u + MAX_LODS)
#include "cull_commands_body.glsl"
