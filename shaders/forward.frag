#version 450
// Forward colour: Lambert + ambient, optional heavy ALU loop. MATERIAL_CLASS selects the
// variant: 0 opaque (with a depth pre-pass the depth test is EQUAL and writes are off),
// 1 alpha-tested (discard with the same leaf mask as the pre-pass), 2 blended (alpha out).
// This variant lets the hardware choose when to test depth: required when the shader may
// discard while depth writes are on (alpha-tested without a pre-pass).
#include "forward_body.glsl"
