#version 450
// Shadow casters into one cascade of the light's atlas: positions only (opaque casters, no
// fragment shader), instanced through the caster list shadow_cull.comp wrote.
#include "shadow_caster.glsl"

void main() {
    gl_Position = caster_position();
}
