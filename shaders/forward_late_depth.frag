#version 450
// forward.frag writing its own depth (the depth it would have): the depth test can only run
// after the shader, for every fragment — seed 000's "late ZS" (`tilegraph experiments`,
// StageProbe::late_depth). Never in a shipping frame.
#define WRITE_DEPTH 1
#include "forward_body.glsl"
