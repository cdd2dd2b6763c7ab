// reinhard05: Reinhard–Devlin photoreceptor per channel in display-relative units, compressing only
// what lies beyond display white; twin of tonemap/reinhard05.py (the statistics arrive as uniforms)
uniform float u_gain;       // exposed radiance → display-relative units
uniform bool u_identity;    // the frame fits under white: shown unchanged
uniform float u_c_a;
uniform float u_l_a;
uniform vec3 u_c_av;        // channel log-averages, display-relative
uniform float u_l_av;
uniform float u_sigma0;     // W/(W − 1)
uniform float u_power;      // m·ν
uniform float u_adapt;      // e^(−b) / L_av
uniform float u_white_v;    // the curve at the white

vec3 tone_map(vec3 lin) {
    vec3 x = max(lin, 0.0) * u_gain;
    if (u_identity) return clamp(x, 0.0, 1.0);
    float l = dot(x, LUMINANCE);
    vec3 i_local = u_c_a * x + (1.0 - u_c_a) * vec3(l);
    vec3 i_global = u_c_a * u_c_av + (1.0 - u_c_a) * vec3(u_l_av);
    vec3 ia = u_l_a * i_local + (1.0 - u_l_a) * i_global;
    vec3 sigma = u_sigma0 * pow(u_adapt * ia, vec3(u_power));
    vec3 den = x + sigma;  // 0 only for a black channel adapted to itself (l_a = 1)
    vec3 v = vec3(den.r > 0.0 ? x.r / den.r : 0.0, den.g > 0.0 ? x.g / den.g : 0.0, den.b > 0.0 ? x.b / den.b : 0.0);
    return clamp(v / u_white_v, 0.0, 1.0);
}
