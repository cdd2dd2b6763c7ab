// bilateral: Durand–Dorsey base/detail compression, the base layer from bilateral.frag's two
// passes (an R32F texture of log2 L); twin of tonemap/bilateral.py
uniform sampler2D u_base;
uniform float u_compression;  // 1: the frame fits, shown unchanged
uniform float u_hi;           // log2, display-relative
uniform float u_out_hi;       // where hi is shown: min(hi, 0)
uniform float u_gain_log2;    // log2 of exposed radiance → display-relative units
uniform float u_saturation;

vec3 tone_map(vec3 lin) {
    vec3 rgb = max(lin, 0.0);
    float l = dot(rgb, LUMINANCE);
    float log_l = log2(max(l, 1e-30));
    float base = texture(u_base, v_uv).r;
    float log_out = u_out_hi + u_compression * (base + u_gain_log2 - u_hi) + (log_l - base);
    float l_out = l > 0.0 ? exp2(min(log_out, 64.0)) : 0.0;
    return clamp(by_ratio(rgb, l, l_out, u_saturation), 0.0, 1.0);
}
