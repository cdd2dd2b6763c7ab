// pbr-neutral: Khronos PBR Neutral; twin of tonemap/pbr_neutral.py
const float START_COMPRESSION = 0.8 - 0.04;
const float DESATURATION = 0.15;

vec3 tone_map(vec3 lin) {
    vec3 c = max(lin, 0.0);
    float x = min(c.r, min(c.g, c.b));
    float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
    c -= offset;
    float peak = max(c.r, max(c.g, c.b));
    if (peak < START_COMPRESSION) return clamp(c, 0.0, 1.0);
    float d = 1.0 - START_COMPRESSION;
    float new_peak = 1.0 - d * d / (peak + d - START_COMPRESSION);
    c *= new_peak / peak;
    float g = 1.0 - 1.0 / (DESATURATION * (peak - new_peak) + 1.0);
    return clamp(mix(c, vec3(new_peak), g), 0.0, 1.0);
}
