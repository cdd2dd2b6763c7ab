#version 430
// Compute rasteriser, step 2: tiles touched by each Gaussian, in depth order (counts[n] = 0, so
// that the exclusive scan of counts[0..n] ends with the total), and each workgroup's total
// (cleared by the caller), from which the CPU adds up the exact total in 64 bits: a uint32 scan
// of more than 2^32 pairs would wrap.
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Order { uint order[]; };
layout(std430, binding = 1) readonly buffer Rects { uvec2 rects[]; };
layout(std430, binding = 2) writeonly buffer Counts { uint counts[]; };
layout(std430, binding = 3) buffer GroupTotals { uint group_totals[]; };
uniform uint u_n;

#include "dispatch.glsl"

void main() {
    uint group = group_index();
    uint i = group * 256u + gl_LocalInvocationID.x;
    if (i > u_n) return;
    if (i == u_n) { counts[i] = 0u; return; }
    uvec2 r = rects[order[i]];
    uint count = ((r.y & 0xffffu) - (r.x & 0xffffu)) * ((r.y >> 16) - (r.x >> 16));
    counts[i] = count;
    if (count > 0u) atomicAdd(group_totals[group], count);
}
