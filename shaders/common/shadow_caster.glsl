// A shadow caster's vertex (shadow.vert, shadow_alpha.vert): the instance from the caster list
// (set 1, written by shadow_cull.comp; gl_InstanceIndex includes the command's firstInstance,
// the caster's slot) into the clip space of the cascade being drawn (push constant).
#include "scene.glsl"

layout(set = 1, binding = 2, std430) readonly buffer Casters { uint caster_ids[]; };
layout(push_constant) uniform Push { uint cascade; } push;

layout(location = 0) in vec3 in_position;

Instance caster_instance() {
    return instance_at(caster_ids[gl_InstanceIndex]);
}

vec4 caster_position() {
    Instance inst = caster_instance();
    return frame.shadow_clip[push.cascade] * vec4(instance_transform(inst, in_position), 1.0);
}
