#version 450
// Forward colour: Lambert + ambient, optional heavy ALU loop. MATERIAL_CLASS selects the
// variant: 0 opaque (with a depth pre-pass the depth test is EQUAL and writes are off),
// 1 alpha-tested (discard with the same leaf mask as the pre-pass), 2 blended (alpha out).
// This variant forces early fragment tests: hidden fragments are never shaded. Safe whenever
// the shader's discard cannot change the depth written (no discard, or depth writes off).
layout(early_fragment_tests) in;
#include "forward_body.glsl"
