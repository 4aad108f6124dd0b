#version 450
// An engine's own material (tests), its visibility-buffer resolve: the toon of
// test_engine.frag from the surface tilegraph rebuilds, tinted by the engine's own uniform,
// here at set 2 (set 1 is tilegraph's in a resolve).
#include "include/tilegraph_instance.glsl"
#include "include/tilegraph_visbuf.glsl"

layout(set = 2, binding = 0, std140) uniform EngineTint { vec4 tint; } engine;

layout(location = 0) out vec4 o_color;

void main() {
    TilegraphSurface s;
    if (!tilegraph_surface(s)) {
        discard;
    }
    float h = fract(float(s.instance) * 0.618034);
    vec3 hue = clamp(abs(fract(h + vec3(0.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
    vec3 n = normalize(s.normal);
    float band = dot(n, tilegraph_light().xyz) > 0.3 ? 1.0 : 0.55;
    float stripe = fract(s.uv.x * 4.0) < 0.5 ? 1.0 : 0.9;
    o_color = vec4(hue * band * stripe * engine.tint.rgb, 1.0);
}
