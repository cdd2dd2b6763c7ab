// reinhard05: Reinhard–Devlin photoreceptor per channel on key-normalised input; twin of
// tonemap/reinhard05.py (the statistics arrive as uniforms)
uniform float u_inv_key;   // 2^−key
uniform float u_m;
uniform float u_b;
uniform float u_c_a;
uniform float u_l_a;
uniform vec3 u_c_av;       // channel log-averages, key-normalised and exposed
uniform float u_l_av;
uniform float u_v_lo;      // the grey curve at the 1st / 99th percentile
uniform float u_v_hi;

vec3 tone_map(vec3 lin) {
    vec3 c = max(lin, 0.0) * u_inv_key;
    float l = dot(c, LUMINANCE);
    vec3 i_local = u_c_a * c + (1.0 - u_c_a) * vec3(l);
    vec3 i_global = u_c_a * u_c_av + (1.0 - u_c_a) * vec3(u_l_av);
    vec3 ia = u_l_a * i_local + (1.0 - u_l_a) * i_global;
    vec3 den = c + pow(exp(-u_b) * ia, vec3(u_m));
    vec3 out_c = vec3(den.r > 0.0 ? c.r / den.r : 0.0, den.g > 0.0 ? c.g / den.g : 0.0, den.b > 0.0 ? c.b / den.b : 0.0);
    return clamp((out_c - u_v_lo) / (u_v_hi - u_v_lo), 0.0, 1.0);
}
