#version 430
// One instance per Gaussian, four vertices per instance (a triangle strip): project the
// Gaussian (EWA), add the circle of confusion to its footprint, and emit a quad that bounds
// exactly the ellipse where its alpha reaches tau. Culled Gaussians become a degenerate quad.
// SH_DEGREE, SH_REST (coefficients beyond degree 0, per channel) and FETCH (the storage layout's
// include file) are #defined by the loader.

layout(std430, binding = 3) readonly buffer Order { uint order[]; };      // back-to-front indices
layout(std430, binding = 4) buffer Counter { uint drawn; };

#include FETCH
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

// The fragment measures its offset from gl_FragCoord (exact pixel centres) rather than from an
// interpolated varying, which would inherit the rasteriser's snapping of quad corners.
flat out vec2 v_centre;     // projected mean in window coordinates (y up)
flat out vec2 v_axis1;      // e1 / sqrt(l1), window coordinates: dot(d, v_axis1) is in std-devs
flat out vec2 v_axis2;
flat out float v_opacity;
flat out vec3 v_colour;
flat out float v_depth;

const float LOW_PASS = 0.3;

void cull() {
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // outside the clip volume: nothing rasterised
    v_centre = vec2(0.0);
    v_axis1 = vec2(0.0);
    v_axis2 = vec2(0.0);
    v_opacity = 0.0;
    v_colour = vec3(0.0);
    v_depth = 0.0;
}

mat3 rotation(vec4 q) {  // unit quaternion (w, x, y, z) -> rotation matrix (columns)
    float w = q.x, x = q.y, y = q.z, z = q.w;
    return mat3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
                2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
                2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
}

void main() {
    uint g = order[gl_InstanceID];
    vec3 mean = load_mean(g);
    float opacity = load_opacity(g);
    vec4 quat = load_quat(g);
    vec3 scale = load_scale(g);
    vec3 t = vec3(dot(u_R0, mean), dot(u_R1, mean), dot(u_R2, mean)) + u_T;
    if (!(t.z > u_near)) { cull(); return; }

    // EWA: Sigma2 = J W Sigma W^T J^T with Sigma = M M^T, M = R(q) S, so Sigma2 = P P^T with the
    // 2x3 P = J W M. Keeping the factor makes det(Sigma2) = |p0 x p1|^2: no cancellation even for
    // needle-like or vanishing Gaussians. t.xy/t.z is clamped to 1.3x the frustum.
    float iz = 1.0 / t.z;
    vec2 lim_lo = (-u_principal - 0.15 * u_viewport) / u_focal;
    vec2 lim_hi = (u_viewport - u_principal + 0.15 * u_viewport) / u_focal;
    vec2 txy = clamp(t.xy * iz, lim_lo, lim_hi);
    vec3 a = u_focal.x * iz * (u_R0 - txy.x * u_R2);
    vec3 c = u_focal.y * iz * (u_R1 - txy.y * u_R2);
    mat3 M = rotation(quat);
    M[0] *= scale.x;
    M[1] *= scale.y;
    M[2] *= scale.z;
    vec3 p0 = a * M;  // row vector a^T M
    vec3 p1 = c * M;
    float sxx = dot(p0, p0);
    float syy = dot(p1, p1);
    float sxy = dot(p0, p1);
    vec3 cr = cross(p0, p1);
    float det_p = dot(cr, cr);

    // Circle of confusion (pixels); the low-pass 0.3 px^2 and the aperture Gaussian k R^2 I are
    // both isotropic, so det(Sigma2 + s I) = det_p + s (sxx + syy) + s^2 stays a sum of positives.
    float R = 0.5 * u_aperture * abs(iz - u_inv_focus);
    float add = LOW_PASS + u_k * R * R;
    float det0 = det_p + LOW_PASS * (sxx + syy) + LOW_PASS * LOW_PASS;
    float det = det_p + add * (sxx + syy) + add * add;
    sxx += add;
    syy += add;
    if (!(det0 > 0.0) || !(det > 0.0) || isinf(det)) { cull(); return; }

    float beta = sqrt(det0 / det);
    float o = opacity;
    if (u_opacity_norm == 1) {
        o = opacity * beta;
    } else if (u_opacity_norm == 2) {
        o = 1.0 - exp(beta * log(1.0 - min(opacity, 0.99)));
    }
    if (!(o > 0.0) || min(o, 0.99) < u_tau) { cull(); return; }

    // Support: alpha >= tau inside q <= 2 ln(o/tau), and never beyond 3 sigma (q <= 9, the τ = 0
    // cut): for o > 90 tau the alpha bound alone would draw quads larger than with tau = 0.
    float r2 = u_tau > 0.0 ? min(9.0, 2.0 * log(o / u_tau)) : 9.0;
    vec2 p = u_focal * t.xy * iz + u_principal;
    vec2 ext = sqrt(r2 * vec2(sxx, syy));  // the ellipse's axis-aligned half extent
    if (p.x + ext.x < 0.0 || p.x - ext.x > u_viewport.x || p.y + ext.y < 0.0 || p.y - ext.y > u_viewport.y) {
        cull();
        return;
    }

    // Eigen-axes without cancellation: l1 is a sum of positives, l2 = det / l1, and e1 is built
    // from the larger diagonal entry.
    float half_diff = 0.5 * (sxx - syy);
    float l1 = 0.5 * (sxx + syy) + sqrt(half_diff * half_diff + sxy * sxy);
    float l2 = det / l1;
    vec2 e1 = half_diff >= 0.0 ? vec2(l1 - syy, sxy) : vec2(sxy, l1 - sxx);
    e1 = dot(e1, e1) > 0.0 ? normalize(e1) : vec2(1.0, 0.0);
    vec2 e2 = vec2(-e1.y, e1.x);
    // The quad is the ellipse's bounding rectangle (r std-devs on both axes) plus half a pixel, so
    // that the rasteriser's snapping of corners never drops a pixel centre inside the ellipse.
    float r = sqrt(r2);
    vec2 corner = vec2((gl_VertexID & 1) == 0 ? -1.0 : 1.0, (gl_VertexID & 2) == 0 ? -1.0 : 1.0);
    vec2 px = p + corner.x * (r * sqrt(l1) + 0.5) * e1 + corner.y * (r * sqrt(l2) + 0.5) * e2;

    vec3 colour = load_base(g);
#if SH_DEGREE > 0
    colour += sh_view_terms(g, normalize(mean - u_eye));
#endif
    colour = max(colour, 0.0);
    if (u_blend_linear) colour = pow(colour, vec3(2.2));

    if (u_count && gl_VertexID == 0) atomicAdd(drawn, 1u);
    gl_Position = vec4(2.0 * px.x / u_viewport.x - 1.0, 1.0 - 2.0 * px.y / u_viewport.y, 0.0, 1.0);
    vec2 flip = vec2(1.0, -1.0);
    v_centre = vec2(p.x, u_viewport.y - p.y);
    v_axis1 = flip * e1 * inversesqrt(l1);
    v_axis2 = flip * e2 * inversesqrt(l2);
    v_opacity = o;
    v_colour = colour;
    v_depth = t.z;
}
