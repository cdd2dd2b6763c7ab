#version 430
// The most splats any one tile holds (atomicMax into longest; cleared by the caller), so that a
// GL which limits loop iterations (llvmpipe: 65535 per invocation) blends long tiles in passes.
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Ranges { uvec2 ranges[]; };
layout(std430, binding = 1) buffer Longest { uint longest; };
uniform uint u_n;

#include "dispatch.glsl"

void main() {
    uint t = group_index() * 256u + gl_LocalInvocationID.x;
    if (t < u_n) atomicMax(longest, ranges[t].y - ranges[t].x);
}
