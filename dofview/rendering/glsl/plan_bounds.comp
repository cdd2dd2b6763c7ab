#version 430
// The sliced mode's plan, step 4: each slot's first place in the draw order (slices.LayerStats:
// bounds), by binary search, of the depth keys of a sorted order against the slot's threshold key,
// or of an earlier view's running slots (plan_slots.comp, plan_scan.comp). In a sorted order each
// slice's smallest and largest live keys on either side of focus are then its ends' and those
// either side of the focus's threshold (an earlier view's: plan_stats.comp's atomics).
layout(local_size_x = 64) in;

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "sort_key.glsl"
#include "dispatch.glsl"
#include "plan_common.glsl"

layout(std430, binding = 6) readonly buffer Running { uint running[]; };

void main() {
    uint tid = gl_LocalInvocationID.x;
    for (uint s = tid; s < k + 3u && k > 0u; s += 64u) {  // slot v = s − 1
        uint at;
        if (u_sorted) {
            uint key = s == 0u ? u_key_near : s == 1u ? max(u_key_near, u_key_front)
                     : s <= k ? max(max(u_key_near, u_key_front), thresh[s - 1u])
                     : s == k + 1u ? max(u_key_near, u_key_back) : NO_KEY;
            at = key == NO_KEY ? u_n : first_place(0u, u_n, key);
        } else {  // the first place whose running slot (+ 2) reaches v + 2 = s + 1
            uint lo = 0u, hi = u_n;
            while (lo < hi) {
                uint mid = lo + (hi - lo) / 2u;
                if (running[mid] >= s + 1u) hi = mid; else lo = mid + 1u;
            }
            at = lo;
        }
        bounds[s] = at;
    }
    memoryBarrierBuffer();
    barrier();
    for (uint v = tid; u_sorted && v < k; v += 64u) {
        uint first = bounds[v + 1u], end = bounds[v + 2u];
        if (first >= end) continue;
        uint split = first_place(first, end, u_key_focus);
        if (split > first) {
            keys[v * 4u] = key_at(first);
            keys[v * 4u + 1u] = key_at(split - 1u);
        }
        if (split < end) {
            keys[v * 4u + 2u] = key_at(split);
            keys[v * 4u + 3u] = key_at(end - 1u);
        }
    }
}
