#version 430
// The sliced mode's plan, step 1 for an order sorted for an earlier view (the quad backend's
// background sort still running), one thread per place: the live Gaussians' smallest and largest
// depth keys (a sorted order has them at its ends: plan_lattice.comp).
layout(local_size_x = 256) in;

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "sort_key.glsl"
#include "dispatch.glsl"
#include "plan_common.glsl"

shared uint s_min, s_max;

void main() {
    uint tid = gl_LocalInvocationID.x, p = group_index() * 256u + tid;
    if (tid == 0u) {
        s_min = 0xffffffffu;
        s_max = 0u;
    }
    barrier();
    uint key = p < u_n ? key_at(p) : 0u;
    if (p < u_n && key >= u_key_near) {
        atomicMin(s_min, key);
        atomicMax(s_max, key);
    }
    barrier();
    if (tid == 0u && s_min <= s_max) {
        atomicMin(min_key, s_min);
        atomicMax(max_key, s_max);
    }
}
