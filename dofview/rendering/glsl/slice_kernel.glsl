// Sliced depth of field: the aperture kernel (slices.LensCell is the twin). A lens cell (the whole
// disk or polygon, or a cell of a partition of the lens for progressive refinement), in lens radii,
// GL orientation: the unit disk (u_disk) cut by the half-planes u·n ≤ h of u_plane, seen from
// u_point. A source of signed CoC ρ (level px, positive in front of focus) spreads over the
// offsets d = −ρ·(u − u_point), u in the cell; w(d, ρ) = clamp(½ − sd, 0, 1) with sd the signed
// distance in px (the largest of the disk's and the planes'), so ρ = 0 is the identity. The taps:
// u_tap holds two offsets a vector (slices.LensCell.taps).

uniform vec4 u_tap[MAX_TAPS / 2];
uniform int u_taps;
uniform vec2 u_point;
uniform bool u_disk;
uniform int u_planes;
uniform vec4 u_plane[MAX_PLANES];  // (nx, ny, h, -)

vec2 tap(int i) {
    vec4 t = u_tap[i >> 1];
    return (i & 1) == 0 ? t.xy : t.zw;
}

float kernel_weight(vec2 d, float rho) {
    float a = abs(rho);
    vec2 v = a * u_point - (rho < 0.0 ? -d : d);  // |ρ|·u px, u = u_point − d/ρ
    float sd = u_disk ? length(v) - a : -1e30;
    for (int i = 0; i < u_planes; ++i) sd = max(sd, dot(v, u_plane[i].xy) - a * u_plane[i].z);
    return clamp(0.5 - sd, 0.0, 1.0);
}

// The v.x where sd ≤ t on the row of taps whose v has this v.y (an interval; lo > hi: none).
vec2 kernel_row(float vy, float a, float t) {
    vec2 span = vec2(-1e30, 1e30);
    if (u_disk) {
        float r2 = (a + t) * (a + t) - vy * vy;
        if (a + t < 0.0 || r2 < 0.0) return vec2(1.0, -1.0);
        span = vec2(-sqrt(r2), sqrt(r2));
    }
    for (int i = 0; i < u_planes; ++i) {
        vec3 pl = u_plane[i].xyz;
        float bound = a * pl.z + t - pl.y * vy;  // n.x·v.x ≤ bound
        if (pl.x > 1e-6) span.y = min(span.y, bound / pl.x);
        else if (pl.x < -1e-6) span.x = max(span.x, bound / pl.x);
        else if (bound < 0.0) return vec2(1.0, -1.0);
    }
    return span;
}

// N(ρ) = Σ_d w(d, ρ) over every integer offset, exactly and in O(|ρ|): on each row of taps those
// with sd ≤ −½ (weight 1) are counted as an interval, and only the anti-aliased rim in between
// (|sd| < ½) is summed tap by tap. u_reach bounds the rows: the cell's reach from u_point, in
// lens radii (slices.LensCell; the twin is the sum of LensCell.weights over all taps).
uniform float u_reach;

float kernel_sum(float rho) {
    float a = abs(rho);
    float s = rho < 0.0 ? -1.0 : 1.0;  // v = a·u_point − s·d, so a tap x of a row has v.x = a·u_point.x − s·x
    int n = int(ceil(a * u_reach + 1.5));
    float sum = 0.0;
    for (int j = -n; j <= n; ++j) {
        float vy = a * u_point.y - s * float(j);
        vec2 outer = kernel_row(vy, a, 0.5);
        if (outer.x > outer.y) continue;
        vec2 xo = s > 0.0 ? a * u_point.x - outer.yx : outer - a * u_point.x;
        int o0 = int(ceil(xo.x)), o1 = int(floor(xo.y));
        int i0 = o1 + 1, i1 = o1;  // the taps of weight 1 (none unless the inner interval holds some)
        vec2 inner = kernel_row(vy, a, -0.5);
        if (inner.x <= inner.y) {
            vec2 xi = s > 0.0 ? a * u_point.x - inner.yx : inner - a * u_point.x;
            int lo = max(int(ceil(xi.x)), o0), hi = min(int(floor(xi.y)), o1);
            if (lo <= hi) {
                i0 = lo;
                i1 = hi;
                sum += float(hi - lo + 1);
            }
        }
        for (int x = o0; x < i0; ++x) sum += kernel_weight(vec2(x, j), rho);
        for (int x = i1 + 1; x <= o1; ++x) sum += kernel_weight(vec2(x, j), rho);
    }
    return sum;
}
