// histogram: Ward Larson histogram adjustment through the CDF table (a (N+1)×1 R32F texture,
// piecewise linear in log2 L); twin of tonemap/histogram.py
uniform sampler2D u_cdf;
uniform int u_cdf_n;
uniform float u_cdf_lo;
uniform float u_cdf_hi;
uniform bool u_linear;     // the scene fits the display: map linearly
uniform float u_hi;
uniform float u_contrast;  // L_dmin / L_dmax
uniform float u_saturation;

vec3 tone_map(vec3 lin) {
    vec3 rgb = max(lin, 0.0);
    float l = dot(rgb, LUMINANCE);
    float l_out;
    if (u_linear) {
        l_out = min(l / exp2(u_hi), 1.0);
    } else {
        float pos = clamp((log2(max(l, 1e-30)) - u_cdf_lo) / (u_cdf_hi - u_cdf_lo), 0.0, 1.0) * float(u_cdf_n);
        int i = min(int(floor(pos)), u_cdf_n - 1);
        float f = pos - float(i);
        float p = texelFetch(u_cdf, ivec2(i, 0), 0).r * (1.0 - f) + texelFetch(u_cdf, ivec2(i + 1, 0), 0).r * f;
        l_out = pow(u_contrast, 1.0 - p);
    }
    return clamp(by_ratio(rgb, l, l_out, u_saturation), 0.0, 1.0);
}
