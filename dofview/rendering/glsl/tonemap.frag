#version 430
// Display pass (Eq. 7): composite the background in the blend's own space, take the result to
// linear light, expose, clip, gamma-encode. Mirrors dofview/tonemap.py:display.

in vec2 v_uv;
uniform sampler2D u_colour;   // blended RGBA (colour premultiplied)
uniform bool u_encoded;       // blended values are display-encoded (standard sRGB 3DGS)
uniform vec3 u_background;    // display-encoded
uniform float u_exposure;
uniform float u_gamma;
uniform bool u_focus_aid;     // tint the in-focus band
uniform sampler2D u_depth;    // alpha-weighted depth (r) and alpha (a)
uniform float u_aperture;
uniform float u_inv_focus;

out vec4 out_colour;

const float SCENE_GAMMA = 2.2;

void main() {
    vec4 c = texture(u_colour, v_uv);
    float t = 1.0 - c.a;
    vec3 lin = u_encoded ? pow(max(c.rgb + t * u_background, 0.0), vec3(SCENE_GAMMA))
                         : c.rgb + t * pow(max(u_background, 0.0), vec3(SCENE_GAMMA));
    lin *= u_exposure;
    if (any(isnan(lin))) lin = vec3(0.0);
    vec3 outc = pow(clamp(lin, 0.0, 1.0), vec3(1.0 / u_gamma));
    if (u_focus_aid) {
        vec4 d = texture(u_depth, v_uv);
        if (d.a > 0.5) {
            float z = d.r / d.a;
            float R = 0.5 * u_aperture * abs(1.0 / z - u_inv_focus);
            if (R < 1.0) outc = mix(outc, vec3(0.1, 1.0, 0.3), 0.35);
        }
    }
    out_colour = vec4(outc, 1.0);
}
