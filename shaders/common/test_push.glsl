// Push constants of the executor's test shaders: a screen rectangle at a depth, a colour, an id.
layout(push_constant) uniform TestPush {
    vec4 rect;   // x0, y0, x1, y1 in NDC (y = -1 is the top row)
    vec4 color;
    float depth;
    uint id;
} pc;
