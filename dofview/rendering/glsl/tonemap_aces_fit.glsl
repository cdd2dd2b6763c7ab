// aces-fit: Narkowicz's fit of the ACES RRT + sRGB ODT, per channel; twin of tonemap/aces_fit.py
vec3 tone_map(vec3 lin) {
    vec3 x = max(lin, 0.0) * 0.6;
    return clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}
