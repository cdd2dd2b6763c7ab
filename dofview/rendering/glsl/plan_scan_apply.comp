#version 430
// Second half of a multi-block running maximum (plan_scan.comp): each block of 1024 takes in the
// maximum of the blocks before it.
layout(local_size_x = 256) in;
layout(std430, binding = 0) buffer Data { uint data[]; };
layout(std430, binding = 1) readonly buffer Maxima { uint maxima[]; };
uniform uint u_n;

#include "dispatch.glsl"

void main() {
    uint block = group_index();
    if (block == 0u) return;
    uint base = block * 1024u + gl_LocalInvocationID.x * 4u;
    uint before = maxima[block - 1u];
    for (uint j = 0u; j < 4u; ++j)
        if (base + j < u_n) data[base + j] = max(data[base + j], before);
}
