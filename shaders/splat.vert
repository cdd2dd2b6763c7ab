#version 430
// One instance per Gaussian, four vertices per instance (a triangle strip): project the
// Gaussian (EWA), add the circle of confusion to its footprint, and emit a quad that bounds
// exactly the ellipse where its alpha reaches tau. Culled Gaussians become a degenerate quad.
// SH_DEGREE and SH_REST (coefficients beyond degree 0, per channel) are #defined by the loader.

layout(std430, binding = 0) readonly buffer Geometry { float geom[]; };   // mean.xyz, opacity, cov xx xy xz yy yz zz
layout(std430, binding = 1) readonly buffer BaseColour { float base[]; }; // SH_C0*dc + 0.5, per channel
layout(std430, binding = 3) readonly buffer Order { uint order[]; };      // back-to-front indices
layout(std430, binding = 4) buffer Counter { uint drawn; };
#if SH_DEGREE > 0
layout(std430, binding = 2) readonly buffer ShRest { float sh_rest[]; };
#endif

#include "sh.glsl"

uniform vec3 u_R0;          // rows of the world → camera rotation
uniform vec3 u_R1;
uniform vec3 u_R2;
uniform vec3 u_T;
uniform vec3 u_eye;         // camera centre, world
uniform vec2 u_focal;       // fx, fy (pixels)
uniform vec2 u_principal;   // cx, cy (pixels)
uniform vec2 u_viewport;    // width, height (pixels)
uniform float u_near;
uniform float u_tau;
uniform float u_aperture;   // A, px * scene unit
uniform float u_inv_focus;  // 1 / d_f
uniform float u_k;          // aperture covariance scale
uniform int u_opacity_norm; // 0 none, 1 energy (beta), 2 optical depth
uniform bool u_blend_linear;
uniform bool u_count;

out vec2 v_offset;          // pixel offset from the projected mean
flat out vec3 v_conic;      // inverse 2D covariance (xx, xy, yy)
flat out float v_opacity;
flat out vec3 v_colour;
flat out float v_depth;

const float LOW_PASS = 0.3;

void cull() {
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // outside the clip volume: nothing rasterised
    v_offset = vec2(0.0);
    v_conic = vec3(0.0);
    v_opacity = 0.0;
    v_colour = vec3(0.0);
    v_depth = 0.0;
}

void main() {
    uint g = order[gl_InstanceID];
    uint b = g * 10u;
    vec3 mean = vec3(geom[b], geom[b + 1u], geom[b + 2u]);
    float opacity = geom[b + 3u];
    vec3 t = vec3(dot(u_R0, mean), dot(u_R1, mean), dot(u_R2, mean)) + u_T;
    if (!(t.z > u_near)) { cull(); return; }

    // EWA: Sigma2 = J W Sigma W^T J^T, with t.xy/t.z clamped to 1.3x the frustum.
    float iz = 1.0 / t.z;
    vec2 lim_lo = (-u_principal - 0.15 * u_viewport) / u_focal;
    vec2 lim_hi = (u_viewport - u_principal + 0.15 * u_viewport) / u_focal;
    vec2 txy = clamp(t.xy * iz, lim_lo, lim_hi);
    vec3 a = u_focal.x * iz * (u_R0 - txy.x * u_R2);
    vec3 c = u_focal.y * iz * (u_R1 - txy.y * u_R2);
    mat3 S = mat3(geom[b + 4u], geom[b + 5u], geom[b + 6u],
                  geom[b + 5u], geom[b + 7u], geom[b + 8u],
                  geom[b + 6u], geom[b + 8u], geom[b + 9u]);
    vec3 Sa = S * a;
    vec3 Sc = S * c;
    float sxx = dot(a, Sa) + LOW_PASS;
    float sxy = dot(a, Sc);
    float syy = dot(c, Sc) + LOW_PASS;
    float det0 = sxx * syy - sxy * sxy;
    if (!(det0 > 0.0)) { cull(); return; }

    // Circle of confusion (pixels) and the aperture Gaussian k R^2 I.
    float R = 0.5 * u_aperture * abs(iz - u_inv_focus);
    float add = u_k * R * R;
    sxx += add;
    syy += add;
    float det = sxx * syy - sxy * sxy;
    if (!(det > 0.0) || isinf(det)) { cull(); return; }

    float beta = sqrt(det0 / det);
    float o = opacity;
    if (u_opacity_norm == 1) {
        o = opacity * beta;
    } else if (u_opacity_norm == 2) {
        o = 1.0 - exp(beta * log(1.0 - min(opacity, 0.99)));
    }
    if (!(o > 0.0) || min(o, 0.99) < u_tau) { cull(); return; }

    // Support: alpha >= tau inside q <= 2 ln(o/tau); 3 sigma when tau = 0.
    float r2 = u_tau > 0.0 ? 2.0 * log(o / u_tau) : 9.0;
    vec2 p = u_focal * t.xy * iz + u_principal;
    vec2 ext = sqrt(r2 * vec2(sxx, syy));  // the ellipse's axis-aligned half extent
    if (p.x + ext.x < 0.0 || p.x - ext.x > u_viewport.x || p.y + ext.y < 0.0 || p.y - ext.y > u_viewport.y) {
        cull();
        return;
    }

    // Quad along the ellipse's eigen-axes, tight to the support.
    float mid = 0.5 * (sxx + syy);
    float rad = sqrt(max(0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy, 0.0));
    float l1 = mid + rad;
    float l2 = max(mid - rad, 0.0);
    vec2 e1a = vec2(sxy, l1 - sxx);
    vec2 e1b = vec2(l1 - syy, sxy);
    vec2 e1 = dot(e1a, e1a) > dot(e1b, e1b) ? e1a : e1b;
    e1 = dot(e1, e1) > 0.0 ? normalize(e1) : vec2(1.0, 0.0);
    vec2 e2 = vec2(-e1.y, e1.x);
    vec2 corner = vec2((gl_VertexID & 1) == 0 ? -1.0 : 1.0, (gl_VertexID & 2) == 0 ? -1.0 : 1.0);
    vec2 offset = corner.x * sqrt(r2 * l1) * e1 + corner.y * sqrt(r2 * l2) * e2;
    vec2 px = p + offset;

    vec3 colour = vec3(base[g * 3u], base[g * 3u + 1u], base[g * 3u + 2u]);
#if SH_DEGREE > 0
    colour += sh_view_terms(g, normalize(mean - u_eye));
#endif
    colour = max(colour, 0.0);
    if (u_blend_linear) colour = pow(colour, vec3(2.2));

    if (u_count && gl_VertexID == 0) atomicAdd(drawn, 1u);
    gl_Position = vec4(2.0 * px.x / u_viewport.x - 1.0, 1.0 - 2.0 * px.y / u_viewport.y, 0.0, 1.0);
    v_offset = offset;
    v_conic = vec3(syy, -sxy, sxx) / det;
    v_opacity = o;
    v_colour = colour;
    v_depth = t.z;
}
