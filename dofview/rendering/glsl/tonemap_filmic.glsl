// filmic: Hable's curve, per channel; twin of tonemap/filmic.py
uniform float u_white;
uniform float u_bias;

vec3 hable(vec3 x) {
    const float A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
    return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F;
}

vec3 tone_map(vec3 lin) {
    return clamp(hable(max(lin, 0.0) * u_bias) / hable(vec3(u_white)), 0.0, 1.0);
}
