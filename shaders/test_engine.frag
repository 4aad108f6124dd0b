#version 450
// An engine's own material (tests): a banded toon shade of the instance's hue, tinted by the
// engine's own uniform at set 1 (what its bind callback binds).
#include "include/tilegraph_instance.glsl"

layout(set = 1, binding = 0, std140) uniform EngineTint { vec4 tint; } engine;

layout(location = 0) in vec3 v_normal;
layout(location = 1) in vec2 v_uv;
layout(location = 2) flat in uint v_instance;
layout(location = 0) out vec4 o_color;

void main() {
    float h = fract(float(v_instance) * 0.618034);
    vec3 hue = clamp(abs(fract(h + vec3(0.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
    vec3 n = normalize(gl_FrontFacing ? v_normal : -v_normal);
    float band = dot(n, tilegraph_light().xyz) > 0.3 ? 1.0 : 0.55;
    float stripe = fract(v_uv.x * 4.0) < 0.5 ? 1.0 : 0.9;
    o_color = vec4(hue * band * stripe * engine.tint.rgb, 1.0);
}
