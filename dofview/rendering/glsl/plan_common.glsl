// The sliced mode's plan of a frame on the GPU (layer_plan.py, the twin of slices.measure_layers
// and slices.screen_boxes): what the plan_*.comp kernels share. Include after FETCH, sh.glsl,
// lens.glsl, project.glsl (camera_depth, the projection's uniforms), sort_key.glsl and
// dispatch.glsl. MAX_EDGES is #defined by the loader.
//
// The draw order is read from its buffer (nearest first, or farthest first for the quad backend)
// and each Gaussian's depth key made again from its mean, bit for bit the key it was sorted by
// (project.glsl: camera_depth is ``precise``). The signed CoC c = ½·A·(1/z − 1/d_f) falls as the
// key grows, so every comparison of a Gaussian's c with a value is a comparison of its key with
// that value's threshold key (coc_threshold), made once; c itself is computed in double precision
// exactly as numpy computes it (slices.signed_coc) wherever its value matters (the lattice, the
// snapped edges).

layout(std430, binding = 3) readonly buffer Order { uint order[]; };
layout(std430, binding = 4) coherent buffer Plan {
    double lattice[MAX_EDGES + 1];  // the slices' edges over the live Gaussians' range, descending
    double cuts[MAX_EDGES + 1];     // the same, snapped (plan_snap.comp): the edges the slots use
    uint k;                         // slices (edges − 1); 0: no Gaussian beyond the near plane
    uint overflow;                  // 1: the lattice would need more than MAX_EDGES + 1 edges
    uint first_live;                // the first live place (sorted orders)
    uint min_key;                   // the live Gaussians' smallest and largest depth keys
    uint max_key;
    uint snap_groups[3];            // plan_snap.comp's workgroups: K + 1 (dispatched indirectly)
    uint thresh[MAX_EDGES + 1];     // per cut: the first depth key whose c ≤ it
    uint bounds[MAX_EDGES + 3];     // slot v's first place at bounds[v + 1] (slices.LayerStats)
    uint keys[4 * MAX_EDGES];       // per slice, its live keys: in front of focus min, max; behind min, max
    int boxes[4 * MAX_EDGES];       // per slice: x0, y0, x1, y1 (slices.screen_boxes)
};

uniform uint u_n;               // Gaussians in the order
uniform bool u_back_to_front;   // the order buffer holds the farthest first
uniform bool u_sorted;          // the order is sorted for these depths (else an earlier view's)
uniform double u_half_a;        // ½·A, px·scene unit
uniform double u_inv_f;         // 1/d_f
uniform uint u_key_near;        // the first key beyond the near plane (live)
uniform uint u_key_front;       // the first key whose c ≤ huge (slot ≥ 0)
uniform uint u_key_back;        // the first key whose c < −huge (slot K; NO_KEY: none)
uniform uint u_key_focus;       // the first key whose c < 0 (behind focus)

const uint NO_KEY = 0xff800001u;  // beyond every key of a positive depth (+inf is 0xff800000)

uint gaussian_at(uint p) { return order[u_back_to_front ? u_n - 1u - p : p]; }

uint key_at(uint p) { return depth_key(camera_depth(load_mean(gaussian_at(p)))); }

// c of a positive depth's key, float64 from the float32 depth as slices.signed_coc computes it.
double coc_of_key(uint key) {
    double z = double(uintBitsToFloat(key & 0x7fffffffu));
    return u_half_a * (1.0lf / z - u_inv_f);
}

// The first key of a positive depth whose c ≤ e (c < e when strict), NO_KEY if none: c falls as
// the key grows (layer_plan.key_threshold is the CPU's).
uint coc_threshold(double e, bool strict) {
    uint lo = 0x80000000u, hi = NO_KEY;
    while (lo < hi) {
        uint mid = lo + (hi - lo) / 2u;
        double c = coc_of_key(mid);
        if (strict ? c < e : c <= e) hi = mid; else lo = mid + 1u;
    }
    return lo;
}

// The first place p in [lo, hi) of a sorted order with key_at(p) ≥ key (hi if none).
uint first_place(uint lo, uint hi, uint key) {
    while (lo < hi) {
        uint mid = lo + (hi - lo) / 2u;
        if (key_at(mid) >= key) hi = mid; else lo = mid + 1u;
    }
    return lo;
}
