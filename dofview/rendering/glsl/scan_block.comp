#version 430
// Exclusive prefix sum of uint data, in place, per block of 1024 (256 threads x 4 contiguous
// elements); each block's total goes to sums[] for the next level (gpusort.py: GpuScan).
layout(local_size_x = 256) in;
layout(std430, binding = 0) buffer Data { uint data[]; };
layout(std430, binding = 1) writeonly buffer Sums { uint sums[]; };
uniform uint u_n;
shared uint s_sum[256];

#include "dispatch.glsl"

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint block = group_index();
    uint base = block * 1024u + lid * 4u;
    uint v[4];
    uint own = 0u;
    for (uint j = 0u; j < 4u; ++j) {
        uint x = base + j < u_n ? data[base + j] : 0u;
        v[j] = own;
        own += x;
    }
    s_sum[lid] = own;
    barrier();
    for (uint off = 1u; off < 256u; off <<= 1) {  // inclusive Hillis-Steele scan of the thread totals
        uint t = lid >= off ? s_sum[lid - off] : 0u;
        barrier();
        s_sum[lid] += t;
        barrier();
    }
    uint before = s_sum[lid] - own;
    for (uint j = 0u; j < 4u; ++j)
        if (base + j < u_n) data[base + j] = before + v[j];
    if (lid == 255u) sums[block] = s_sum[255];
}
