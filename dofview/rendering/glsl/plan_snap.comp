#version 430
// The sliced mode's plan, step 3, one workgroup per lattice edge (dispatched indirectly): each
// inner edge of a sorted order moved into the widest gap between the live Gaussians' CoCs within
// SliceRule.snap of its narrower layer (slices.snap_edges: the same points, gaps and tie-break),
// and every edge's threshold key.
layout(local_size_x = 64) in;  // 64: the reduction below

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "sort_key.glsl"
#include "dispatch.glsl"
#include "plan_common.glsl"

uniform double u_snap;  // SliceRule.snap

shared double s_lo, s_hi, s_gap[64];
shared uint s_a, s_n, s_at[64];

// Point t of the window in ascending c: lo, c(a + n − 1), …, c(a), hi (the Gaussians at places
// [a, a + n), nearest first, so descending c).
double point(uint t) { return t == 0u ? s_lo : t > s_n ? s_hi : coc_of_key(key_at(s_a + s_n - t)); }

void main() {
    uint i = gl_WorkGroupID.x, tid = gl_LocalInvocationID.x;
    double cut = lattice[i];
    bool inner = u_sorted && u_snap > 0.0lf && i >= 1u && i + 1u <= k;
    if (tid == 0u && inner) {
        double d = u_snap * min(lattice[i - 1u] - cut, cut - lattice[i + 1u]);
        s_hi = cut + d;
        s_lo = cut - d;
        // the live Gaussians with lo < c < hi
        uint a = first_place(first_live, u_n, max(coc_threshold(s_hi, true), u_key_near));
        s_a = a;
        s_n = first_place(a, u_n, max(coc_threshold(s_lo, false), u_key_near)) - a;
    }
    barrier();
    double best = -1.0lf;
    uint at = 0xffffffffu;
    if (inner) {  // gaps t ∈ [t0, t1) of this thread, ascending: a tie keeps the first, as np.argmax
        uint chunk = (s_n + 64u) / 64u, t0 = tid * chunk, t1 = min(t0 + chunk, s_n + 1u);
        double below = t0 < t1 ? point(t0) : 0.0lf;
        for (uint t = t0; t < t1; ++t) {
            double above = point(t + 1u), g = above - below;
            if (g > best) {
                best = g;
                at = t;
            }
            below = above;
        }
    }
    s_gap[tid] = best;
    s_at[tid] = at;
    barrier();
    for (uint step = 32u; step > 0u; step >>= 1) {
        if (tid < step) {
            double g = s_gap[tid + step];
            uint t = s_at[tid + step];
            if (g > s_gap[tid] || (g == s_gap[tid] && t < s_at[tid])) {
                s_gap[tid] = g;
                s_at[tid] = t;
            }
        }
        barrier();
    }
    if (tid == 0u) {
        if (inner) cut = 0.5lf * (point(s_at[0]) + point(s_at[0] + 1u));
        cuts[i] = cut;
        thresh[i] = coc_threshold(cut, false);
    }
}
