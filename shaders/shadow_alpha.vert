#version 450
// Alpha-tested shadow casters: position and UV, for depth_alpha.frag's discard.
#include "shadow_caster.glsl"

layout(location = 2) in vec2 in_uv;
layout(location = 0) out vec2 v_uv;
layout(location = 1) flat out uint v_material;

void main() {
    gl_Position = caster_position();
    v_uv = in_uv;
    v_material = meshes[caster_instance().mesh].material;
}
