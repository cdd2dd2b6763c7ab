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

