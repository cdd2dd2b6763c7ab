#version 430
// Radix sort, pass step 1: the 256-bin histogram of one 8-bit digit per block of BLOCK keys,
// stored digit-major (hist[digit * blocks + block]) so that one exclusive scan of hist gives every
// (digit, block) its first output slot. THREADS and ITEMS (BLOCK = THREADS * ITEMS) are #defined.
layout(local_size_x = THREADS) in;
layout(std430, binding = 0) readonly buffer Keys { uint keys[]; };
layout(std430, binding = 1) writeonly buffer Hist { uint hist[]; };
uniform uint u_n;
uniform uint u_shift;
uniform uint u_blocks;
shared uint s_count[256];

#include "dispatch.glsl"

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint block = group_index();
    for (uint d = lid; d < 256u; d += THREADS) s_count[d] = 0u;
    barrier();
    uint base = block * (THREADS * ITEMS);
    for (uint j = 0u; j < ITEMS; ++j) {  // strided: the order does not matter to a histogram
        uint i = base + j * THREADS + lid;
        if (i < u_n) atomicAdd(s_count[(keys[i] >> u_shift) & 255u], 1u);
    }
    barrier();
    for (uint d = lid; d < 256u; d += THREADS) hist[d * u_blocks + block] = s_count[d];
}
