#version 430
// Compute rasteriser, step 2: tiles touched by each Gaussian, in depth order (counts[n] = 0, so
// that the exclusive scan of counts[0..n] ends with the total).
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Order { uint order[]; };
layout(std430, binding = 1) readonly buffer Rects { uvec2 rects[]; };
layout(std430, binding = 2) writeonly buffer Counts { uint counts[]; };
uniform uint u_n;

#include "dispatch.glsl"

void main() {
    uint i = group_index() * 256u + gl_LocalInvocationID.x;
    if (i > u_n) return;
    if (i == u_n) { counts[i] = 0u; return; }
    uvec2 r = rects[order[i]];
    counts[i] = ((r.y & 0xffffu) - (r.x & 0xffffu)) * ((r.y >> 16) - (r.x >> 16));
}
