#version 450
// The counting variant of forward.frag: no forced early fragment tests, for alpha-tested
// geometry without a pre-pass (its discard decides the depth written). Counts the fragments it
// shades, per material class, like forward_count.frag; used only when a run asks for counts.
#define COUNT_FRAGMENTS 1
#include "forward_body.glsl"
