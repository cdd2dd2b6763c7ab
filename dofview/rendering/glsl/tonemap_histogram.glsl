// histogram: Ward Larson histogram adjustment through its curve table (log2 display luminance at the
// bin edges, a (N+1)×1 R32F texture, piecewise linear; slope 1 outside); twin of tonemap/histogram.py
uniform sampler2D u_cdf;    // the curve table (built per exposure from the statistics' CDF)
uniform int u_cdf_n;
uniform float u_gain_log2;  // log2 of exposed radiance → display-relative units
uniform float u_dom_lo;     // the table's domain, log2 display-relative
uniform float u_dom_hi;
uniform float u_saturation;

vec3 tone_map(vec3 lin) {
    vec3 rgb = max(lin, 0.0);
    float l = dot(rgb, LUMINANCE);
    float log_l = log2(max(l, 1e-30)) + u_gain_log2;
    float pos = (log_l - u_dom_lo) / (u_dom_hi - u_dom_lo) * float(u_cdf_n);
    int i = clamp(int(floor(pos)), 0, u_cdf_n - 1);
    float f = pos - float(i);
    float t0 = texelFetch(u_cdf, ivec2(i, 0), 0).r, t1 = texelFetch(u_cdf, ivec2(i + 1, 0), 0).r;
    float slope = 1.0, log_out;
    if (pos < 0.0) {
        log_out = texelFetch(u_cdf, ivec2(0, 0), 0).r + log_l - u_dom_lo;
    } else if (pos > float(u_cdf_n)) {
        log_out = texelFetch(u_cdf, ivec2(u_cdf_n, 0), 0).r + log_l - u_dom_hi;
    } else {
        log_out = t0 * (1.0 - f) + t1 * f;
        slope = (t1 - t0) / ((u_dom_hi - u_dom_lo) / float(u_cdf_n));
    }
    float l_out = l > 0.0 ? exp2(min(log_out, 64.0)) : 0.0;
    float s = u_saturation + (1.0 - u_saturation) * clamp(slope, 0.0, 1.0);
    return clamp(by_ratio(rgb, l, l_out, s), 0.0, 1.0);
}
