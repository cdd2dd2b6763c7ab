// The display pass's input: the blend composited over the background in its own space, taken to
// linear light and exposed (dofview/tonemap/base.py:display up to the operator).
uniform sampler2D u_colour;   // blended RGBA (colour premultiplied)
uniform bool u_encoded;       // blended values are display-encoded (standard sRGB 3DGS)
uniform vec3 u_background;    // display-encoded
uniform float u_exposure;

const float SCENE_GAMMA = 2.2;
const vec3 LUMINANCE = vec3(0.2126, 0.7152, 0.0722);

vec3 exposed_linear(vec4 c) {
    float t = 1.0 - c.a;
    vec3 lin = u_encoded ? pow(max(c.rgb + t * u_background, 0.0), vec3(SCENE_GAMMA))
                         : c.rgb + t * pow(max(u_background, 0.0), vec3(SCENE_GAMMA));
    lin *= u_exposure;
    if (any(isnan(lin))) lin = vec3(0.0);
    return lin;
}

// (C/L)^s · L_out: colour restored from a new luminance (tonemap/operator.py:by_ratio)
vec3 by_ratio(vec3 rgb, float lum, float lum_out, float s) {
    if (lum <= 0.0) return vec3(0.0);
    return pow(max(rgb, 0.0) / lum, vec3(s)) * lum_out;
}
