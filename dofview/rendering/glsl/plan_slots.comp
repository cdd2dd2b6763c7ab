#version 430
// The sliced mode's plan for an order sorted for an earlier view, one thread per place: each
// Gaussian's slot (slices.measure_layers: −2 culled, −1 the huge-CoC front layer, 0 … K − 1 the
// slices, K the huge-CoC back layer), stored + 2; plan_scan.comp then gives each place the
// farthest slot of those before it, so that the slots' ranges are contiguous.
layout(local_size_x = 256) in;

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "sort_key.glsl"
#include "dispatch.glsl"
#include "plan_common.glsl"

layout(std430, binding = 6) writeonly buffer Running { uint running[]; };

void main() {
    uint p = group_index() * 256u + gl_LocalInvocationID.x;
    if (p >= u_n) return;
    uint key = key_at(p), slot;
    if (key < u_key_near) slot = 0u;
    else if (key < u_key_front) slot = 1u;
    else if (key >= u_key_back) slot = k + 2u;
    else {  // the cuts at or before the key, less one, within the slices (np.clip in measure_layers)
        uint lo = 0u, hi = k + 1u;
        while (lo < hi) {
            uint mid = (lo + hi) / 2u;
            if (thresh[mid] <= key) lo = mid + 1u; else hi = mid;
        }
        slot = clamp(lo, 1u, k) + 1u;
    }
    running[p] = slot;
}
