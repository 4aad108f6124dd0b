#version 450
// GPU-driven instance culling of the cluster techniques (common/cull_body.glsl): it also
// lists the chunks of clusters each phase tests.
#define CLUSTER_WORK
#include "cull_body.glsl"
