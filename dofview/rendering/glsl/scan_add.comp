#version 430
// Second half of a multi-block scan: add the scanned block totals to each block of 1024.
layout(local_size_x = 256) in;
layout(std430, binding = 0) buffer Data { uint data[]; };
layout(std430, binding = 1) readonly buffer Sums { uint sums[]; };
uniform uint u_n;

#include "dispatch.glsl"

void main() {
    uint block = group_index();
    uint base = block * 1024u + gl_LocalInvocationID.x * 4u;
    uint add = sums[block];
    for (uint j = 0u; j < 4u; ++j)
        if (base + j < u_n) data[base + j] += add;
}
