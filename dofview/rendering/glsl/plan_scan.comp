#version 430
// Inclusive running maximum of uint data, in place, per block of 1024 (256 threads × 4
// contiguous elements); each block's maximum goes to maxima[] for the next level, and
// plan_scan_apply.comp brings in the blocks before (layer_plan.py: the slots of an earlier view's
// order made contiguous).
layout(local_size_x = 256) in;
layout(std430, binding = 0) buffer Data { uint data[]; };
layout(std430, binding = 1) writeonly buffer Maxima { uint maxima[]; };
uniform uint u_n;
shared uint s_max[256];

#include "dispatch.glsl"

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint block = group_index();
    uint base = block * 1024u + lid * 4u;
    uint v[4];
    uint own = 0u;
    for (uint j = 0u; j < 4u; ++j) {
        own = max(own, base + j < u_n ? data[base + j] : 0u);
        v[j] = own;
    }
    s_max[lid] = own;
    barrier();
    for (uint off = 1u; off < 256u; off <<= 1) {  // inclusive Hillis-Steele scan of the thread maxima
        uint t = lid >= off ? s_max[lid - off] : 0u;
        barrier();
        s_max[lid] = max(s_max[lid], t);
        barrier();
    }
    uint before = lid > 0u ? s_max[lid - 1u] : 0u;
    for (uint j = 0u; j < 4u; ++j)
        if (base + j < u_n) data[base + j] = max(before, v[j]);
    if (lid == 255u) maxima[block] = s_max[255];
}
