// Whether a splat's support (q <= r2) reaches a pixel centre of a tile: the exact minimum of the
// convex q = d^T Q d over the rectangle of the tile's pixel centres (at the centre if inside, else
// on an edge, where it is a 1D quadratic). Dropping the tiles of a support box that the ellipse
// misses removes about a fifth of the (tile, Gaussian) pairs. Rectangles of more than TEST_MAX
// tiles keep every tile, so that no loop over them runs past llvmpipe's 65535 iterations. Needs
// splat_record.glsl and TILE.
const uint TEST_MAX = 1024u;

float min_q_on_rect(vec2 c, vec3 Q, vec2 lo, vec2 hi) {  // Q = (xx, xy, yy)
    if (all(greaterThanEqual(c, lo)) && all(lessThanEqual(c, hi))) return 0.0;
    vec2 dlo = lo - c, dhi = hi - c;
    float m = 3.0e38;
    for (int side = 0; side < 2; ++side) {
        float dx = side == 0 ? dlo.x : dhi.x;
        float dy = clamp(-Q.y * dx / Q.z, dlo.y, dhi.y);
        m = min(m, Q.x * dx * dx + 2.0 * Q.y * dx * dy + Q.z * dy * dy);
        dy = side == 0 ? dlo.y : dhi.y;
        dx = clamp(-Q.y * dy / Q.x, dlo.x, dhi.x);
        m = min(m, Q.x * dx * dx + 2.0 * Q.y * dx * dy + Q.z * dy * dy);
    }
    return m;
}

bool splat_touches_tile(Splat s, uvec2 tile) {
    vec2 a1 = s.a.zw, a2 = splat_axis2(s.a, s.b);
    vec3 Q = vec3(a1.x * a1.x + a2.x * a2.x, a1.x * a1.y + a2.x * a2.y, a1.y * a1.y + a2.y * a2.y);
    vec2 lo = vec2(tile * TILE) + 0.5;
    return min_q_on_rect(s.a.xy, Q, lo, lo + float(TILE - 1u)) <= s.c.w * 1.001;  // c.w = r2
}
