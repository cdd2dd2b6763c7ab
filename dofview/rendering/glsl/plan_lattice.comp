#version 430
// The sliced mode's plan, step 2 (one invocation): the live Gaussians' CoC range (a sorted order:
// its first live and its last Gaussian; otherwise plan_extent.comp's atomics) and the lattice of
// slice edges over it, slices.slice_edges in double precision op for op; plan_snap.comp's
// workgroups (one per edge) for its indirect dispatch.
layout(local_size_x = 1) in;

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "sort_key.glsl"
#include "dispatch.glsl"
#include "plan_common.glsl"

uniform double u_width;        // SliceRule.width, px
uniform double u_growth;       // SliceRule.growth
uniform double u_huge;         // SliceRule.huge (may be inf)

// The edges of one side beyond the focus slice up to limit (slices.slice_edges: side), written
// from place at (ascending) or, reversed, ending at place at; returns how many (MAX_EDGES + 2: too
// many).
uint side(double limit, bool write, bool reversed, uint at) {
    double e = u_width / 2.0lf, w = u_width;
    uint n = 0u;
    while (e < limit && n <= MAX_EDGES) {
        w *= u_growth;
        e = min(e + w, u_huge);
        if (write) {
            if (reversed) lattice[at - n] = e; else lattice[at + n] = -e;
        }
        ++n;
    }
    return e < limit ? MAX_EDGES + 2u : n;
}

void empty() {
    k = 0u;
    snap_groups[0] = 0u;
    snap_groups[1] = 1u;
    snap_groups[2] = 1u;
}

void main() {
    uint lo_key = min_key, hi_key = max_key;
    if (u_sorted) {
        uint p0 = first_place(0u, u_n, u_key_near);
        first_live = p0;
        if (p0 >= u_n) { empty(); return; }
        lo_key = key_at(p0);
        hi_key = key_at(u_n - 1u);
    } else if (lo_key > hi_key) {
        empty();
        return;
    }
    double lo = max(coc_of_key(hi_key), -u_huge), hi = min(coc_of_key(lo_key), u_huge);
    uint up = side(hi, false, false, 0u), down = side(-lo, false, false, 0u);
    if (up + down + 2u > MAX_EDGES + 1u) {
        overflow = 1u;
        empty();
        return;
    }
    if (up > 0u) side(hi, true, true, up - 1u);
    lattice[up] = u_width / 2.0lf;
    lattice[up + 1u] = -(u_width / 2.0lf);
    side(-lo, true, false, up + 2u);
    k = up + down + 1u;
    snap_groups[0] = k + 1u;
    snap_groups[1] = 1u;
    snap_groups[2] = 1u;
}
