// aces: ACES 2.0 SDR output transform; the GENERATED text is OpenColorIO's GPU shader (defining
// ocio_aces, tonemap/aces.py:gpu_shader), put in by rendering/display.py. Its output is encoded
// for a γ 2.2 display: decoded here to display-linear. Twin: tonemap/aces.py.
#include GENERATED

vec3 tone_map(vec3 lin) {
    vec3 encoded = max(ocio_aces(vec4(max(lin, 0.0), 1.0)).rgb, 0.0);
    return clamp(pow(encoded, vec3(2.2)), 0.0, 1.0);
}
