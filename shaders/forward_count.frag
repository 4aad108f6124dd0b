#version 450
// Forward colour with early fragment tests that also counts the fragments it shades, per
// material class: an exact "fragments shaded" measure on any device (lavapipe's pipeline
// statistics count rasterized fragments, before the depth test). Needs
// fragmentStoresAndAtomics; used only when a run asks for fragment counts.
layout(early_fragment_tests) in;
#define COUNT_FRAGMENTS 1
#include "forward_body.glsl"
