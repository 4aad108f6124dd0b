#version 450
// Occlusion-query proxy: the camera-relative bounding box of one instance (or one group of
// instances) as a unit cube of 36 vertices, no vertex buffer. Depth tested against the frame's
// depth, nothing written: the query counts the samples that pass.
#include "scene.glsl"

layout(push_constant) uniform Box {
    vec4 center;       // xyz: camera-relative centre
    vec4 half_extents; // xyz: half size
} box;

// Two triangles per face, 6 faces.
const uint CORNERS[36] = uint[36](
    0u, 2u, 1u, 1u, 2u, 3u,  // -z
    4u, 5u, 6u, 5u, 7u, 6u,  // +z
    0u, 1u, 4u, 1u, 5u, 4u,  // -y
    2u, 6u, 3u, 3u, 6u, 7u,  // +y
    0u, 4u, 2u, 2u, 4u, 6u,  // -x
    1u, 3u, 5u, 3u, 7u, 5u   // +x
);

void main() {
    uint c = CORNERS[gl_VertexIndex];
    vec3 corner = vec3(float(c & 1u), float((c >> 1u) & 1u), float((c >> 2u) & 1u)) * 2.0 - 1.0;
    gl_Position = frame.view_proj * vec4(proxy_corner(box.center.xyz, box.half_extents.xyz, corner), 1.0);
}
