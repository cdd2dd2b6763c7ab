#version 430
// Depth-sort keys of every Gaussian for the current view (sort_key.glsl), values = indices.
layout(local_size_x = 256) in;

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "sort_key.glsl"
#include "dispatch.glsl"

layout(std430, binding = 3) writeonly buffer Keys { uint keys[]; };
layout(std430, binding = 4) writeonly buffer Vals { uint vals[]; };
uniform uint u_n;

void main() {
    uint g = group_index() * 256u + gl_LocalInvocationID.x;
    if (g >= u_n) return;
    keys[g] = depth_key(camera_depth(load_mean(g)));
    vals[g] = g;
}
