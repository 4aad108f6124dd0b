// The culling tests of an instance's (or a cluster's) bounds, shared by cull.comp and
// cluster_cull.comp: frustum planes, and the conservative HiZ test of the box or the sphere
// against the pyramid (docs/CULLING.md). Needs scene.glsl and cull.glsl first.
#ifndef TILEGRAPH_CULL_TESTS_GLSL
#define TILEGRAPH_CULL_TESTS_GLSL

#include "hiz.glsl"

// A D16 attachment holds a fragment at its rounded code, up to half a step nearer than the float
// depth: the test compares the code on the near side (tilegraph_cull::DepthFormat::toward_near).
// The f32 product is within 0.004 of the exact one, so a fraction that close to a whole code
// goes one code further toward the near plane.
float toward_near_d16(float d, bool reverse) {
    float scaled = clamp(d, 0.0, 1.0) * 65535.0;
    uint k = reverse ? uint(ceil(scaled + 0.01)) : uint(max(floor(scaled - 0.01), 0.0));
    return hiz_d16_exact(min(k, 65535u));
}

layout(set = 1, binding = 5, std430) readonly buffer Pyramid { float pyramid[]; };
// Per stored level (the finest may be level 1 or 2: knob hiz_resolution): (offset, width, height,
// 0), then (texels_x, pixels_x, texels_y, pixels_y): depth pixel p maps to texel
// min(p * texels / pixels, size - 1) (docs/CULLING.md).
layout(set = 1, binding = 6, std430) readonly buffer Levels { uvec4 levels[]; };
bool frustum_visible_box(Instance inst) {
    for (int i = 0; i < 6; ++i) {
        vec4 pl = cull.planes[i];
        float s = dot(pl.xyz, inst.center) + dot(abs(pl.xyz), inst.half_extents) + pl.w;
        // Relative slack: an f32 evaluation must never reject a box that touches the frustum.
        float slack = 1e-5 * (abs(dot(pl.xyz, inst.center)) + dot(abs(pl.xyz), inst.half_extents) + abs(pl.w));
        if (s < -slack) {
            return false;
        }
    }
    return true;
}

bool frustum_visible_sphere(Instance inst) {
    for (int i = 0; i < 6; ++i) {
        vec4 pl = cull.planes[i];
        float reach = inst.radius * length(pl.xyz);
        float s = dot(pl.xyz, inst.center) + reach + pl.w;
        float slack = 1e-5 * (abs(dot(pl.xyz, inst.center)) + reach + abs(pl.w));
        if (s < -slack) {
            return false;
        }
    }
    return true;
}

bool spheres() { return cull.screen.w == 1u; }

bool frustum_visible(Instance inst) {
    return spheres() ? frustum_visible_sphere(inst) : frustum_visible_box(inst);
}

bool farther(float a, float b) { return cull.info.w == 1u ? a < b : a > b; }

// What a bounding volume projects to: an NDC rect and the depth of its nearest point; false
// when it has no rect (it touches or crosses the near plane, or contains the eye): visible.
struct Projected {
    vec2 lo;
    vec2 hi;
    float nearest;
};

// The hull of the AABB's 8 projected corners.
bool project_box(Instance inst, out Projected p) {
    bool reverse = cull.info.w == 1u;
    p.lo = vec2(1e30);
    p.hi = vec2(-1e30);
    p.nearest = reverse ? 0.0 : 1.0;
    for (uint i = 0u; i < 8u; ++i) {
        vec3 s = vec3((i & 1u) != 0u ? 1.0 : -1.0, (i & 2u) != 0u ? 1.0 : -1.0, (i & 4u) != 0u ? 1.0 : -1.0);
        vec4 clip = cull.hiz_view_proj * vec4(inst.center + s * inst.half_extents, 1.0);
        if (clip.w <= 1e-6) {
            return false; // touches or crosses the near plane, or the camera is inside: visible
        }
        vec3 ndc = clip.xyz / clip.w;
        if (reverse ? ndc.z >= 1.0 : ndc.z <= 0.0) {
            return false; // at or in front of the near plane
        }
        p.lo = min(p.lo, ndc.xy);
        p.hi = max(p.hi, ndc.xy);
        p.nearest = reverse ? max(p.nearest, ndc.z) : min(p.nearest, ndc.z);
    }
    return true;
}

// NDC range of a sphere along one axis (tilegraph_cull::project_sphere_view): `a` the centre's
// coordinate, `z` its view z (the sphere beyond the near plane, so |z| > r and the denominators
// are positive), `s` the NDC scale. The extremes are the two planes through the eye tangent to
// the sphere (Mara & McGuire 2013).
vec2 tangent_range(float a, float z, float r, float s) {
    float t = sqrt(max(a * a + z * z - r * r, 0.0));
    float p = s * (t * a - r * z) / -(r * a + t * z);
    float q = s * (t * a + r * z) / -(t * z - r * a);
    return vec2(min(p, q), max(p, q));
}

// The tight rect of the bounding sphere's silhouette, in the pyramid frame's view.
bool project_sphere(Instance inst, out Projected p) {
    bool reverse = cull.info.w == 1u;
    vec3 c = (cull.hiz_view * vec4(inst.center, 1.0)).xyz;
    // The f32 view transform is off by a few ulps of the distances involved: grow the radius by
    // more than that.
    float r = inst.radius + 1e-6 * (length(inst.center) + length(c));
    bool perspective = cull.hiz_proj.z > 0.5;
    if (perspective && dot(c, c) <= r * r) {
        return false; // the eye is inside
    }
    // The nearest point along the view axis (the view looks down -z); depth depends on the view
    // z alone for every projection tilegraph makes.
    float zn = c.z + r;
    float w = cull.hiz_depth.z * zn + cull.hiz_depth.w;
    if (w <= 1e-6) {
        return false;
    }
    p.nearest = (cull.hiz_depth.x * zn + cull.hiz_depth.y) / w;
    if (reverse ? p.nearest >= 1.0 : p.nearest <= 0.0) {
        return false; // touches or crosses the near plane
    }
    vec2 x, y;
    if (perspective) {
        x = tangent_range(c.x, c.z, r, cull.hiz_proj.x);
        y = tangent_range(c.y, c.z, r, cull.hiz_proj.y);
    } else {
        vec2 a = cull.hiz_proj.xy * (c.xy - r);
        vec2 b = cull.hiz_proj.xy * (c.xy + r);
        x = vec2(min(a.x, b.x), max(a.x, b.x));
        y = vec2(min(a.y, b.y), max(a.y, b.y));
    }
    // Rounding margin of the f32 tangents: a hundred-thousandth of the scale, far below a pixel.
    vec2 margin = 1e-5 * (abs(cull.hiz_proj.xy) + vec2(max(abs(x.x), abs(x.y)), max(abs(y.x), abs(y.y))));
    p.lo = vec2(x.x, y.x) - margin;
    p.hi = vec2(x.y, y.y) + margin;
    return true;
}

bool hiz_rect_visible(Projected p, uint ulps);

// Conservative HiZ test of the instance's bounds (the sphere when `sphere` and the projection
// allows, else the box) against the pyramid.
bool hiz_visible_bounds(Instance inst, bool sphere) {
    if (cull.info.z == 0u) {
        return true;
    }
    Projected p;
    bool projected = sphere && cull.hiz_proj.z > -0.5 ? project_sphere(inst, p) : project_box(inst, p);
    if (!projected) {
        return true;
    }
    // Rounding margin: move the nearest depth 4 ulps towards the camera (8 for a sphere, whose
    // depth comes from one more product).
    return hiz_rect_visible(p, sphere ? 8u : 4u);
}

// The conservative HiZ test of a projected volume: visible unless its nearest depth, moved
// `ulps` towards the camera, lies strictly behind every texel of the pyramid level its rect
// covers in 2x2 texels.
bool hiz_rect_visible(Projected p, uint ulps) {
    bool reverse = cull.info.w == 1u;
    vec2 size = vec2(cull.screen.xy);
    // Clamped to [-1, size] before the conversion: a corner just past the near plane can land
    // billions of pixels away, beyond what an int holds (the conversion is then undefined).
    // -1 and size keep "off screen" off screen.
    ivec2 pmin = ivec2(clamp(floor((p.lo * 0.5 + 0.5) * size), vec2(-1.0), size));
    ivec2 pmax = ivec2(clamp(floor((p.hi * 0.5 + 0.5) * size), vec2(-1.0), size));
    ivec2 smax = ivec2(cull.screen.xy) - 1;
    if (any(lessThan(pmax, ivec2(0))) || any(greaterThan(pmin, smax))) {
        return true; // off screen: the frustum test's business
    }
    uvec2 a = uvec2(clamp(pmin, ivec2(0), smax));
    uvec2 b = uvec2(clamp(pmax, ivec2(0), smax));
    float nearest = uintBitsToFloat(reverse ? floatBitsToUint(p.nearest) + ulps : max(floatBitsToUint(p.nearest), ulps) - ulps);
    if (cull.groups.z == 1u) {
        nearest = toward_near_d16(nearest, reverse);
    }
    for (uint k = 0u; k < cull.info.z; ++k) {
        uvec4 l = levels[2u * k];
        uvec4 sc = levels[2u * k + 1u];
        uvec2 ext = l.yz;
        uvec2 t0 = min(uvec2(a.x * sc.x / sc.y, a.y * sc.z / sc.w), ext - 1u);
        uvec2 t1 = min(uvec2(b.x * sc.x / sc.y, b.y * sc.z / sc.w), ext - 1u);
        if (t1.x - t0.x <= 1u && t1.y - t0.y <= 1u) {
            float far = reverse ? 1.0 : 0.0;
            for (uint y = t0.y; y <= t1.y; ++y) {
                for (uint x = t0.x; x <= t1.x; ++x) {
                    float d = pyramid[l.x + y * ext.x + x];
                    far = farther(d, far) ? d : far;
                }
            }
            return !farther(nearest, far); // occluded only when strictly behind every texel
        }
    }
    return true;
}

// The instance's bounds as the parameters say (knob cull_bounds).
bool hiz_visible(Instance inst) {
    return hiz_visible_bounds(inst, spheres());
}

#endif
