#version 450
// Ordered compaction, second half: one workgroup per list writes one instanced
// VkDrawIndexedIndirectCommand per group of the list that kept an instance, in group order
// (with levels of detail, one per group and level, the level's index range; level by level),
// and the list's draw count (vkCmdDrawIndexedIndirectCount). With a fixed draw count
// (cull.groups.y = 1: the device or the profile does without drawIndirectCount), every group
// keeps its command, empty ones with instanceCount 0, and the CPU draws the list's group count.
// Workgroup w is list w: the early (or only) dispatch runs lists 0-3, the late one 0-7.
#include "cull_commands_body.glsl"
