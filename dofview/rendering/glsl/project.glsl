// One Gaussian to its screen footprint with depth of field (EWA, low-pass, CoC, opacity
// normalisation, tau-tight support, viewport cull): shared by the instanced-quad vertex shader
// and the compute preprocess. Include after FETCH, sh.glsl and lens.glsl.

uniform vec3 u_R0;          // rows of the world → camera rotation
uniform vec3 u_R1;
uniform vec3 u_R2;
uniform vec3 u_T;
uniform vec3 u_eye;         // camera centre, world
uniform vec2 u_focal;       // fx, fy (pixels)
uniform vec2 u_principal;   // cx, cy (pixels)
uniform vec2 u_viewport;    // width, height (pixels)
uniform vec4 u_frustum;     // x/z, y/z limits of the EWA clamp (lo.xy, hi.xy): Camera.frustum_limits
uniform float u_near;
uniform float u_tau;
uniform float u_aperture;   // A, px * scene unit
uniform float u_inv_focus;  // 1 / d_f
uniform float u_k;          // aperture covariance scale
uniform int u_opacity_norm; // 0 none, 1 energy (beta), 2 optical depth
uniform bool u_blend_linear;
uniform int u_cut;          // the tau cut: 0 drop, 1 conserve (lens.glsl: cut_splat)
uniform int u_kernel;       // 0 Gaussian, 1 disk (lens.glsl: kernel_shape; never with conserve)

struct Footprint {
    vec2 centre;   // projected mean, pixels (y down)
    float sxx;     // blurred 2D covariance, px^2
    float sxy;
    float syy;
    float det;
    float r2;      // support bound on d^T Sigma'^-1 d
    float opacity; // o'
    float depth;   // camera z
    vec3 colour;   // view-dependent colour (decoded to linear light when blending linearly)
    float shape;   // kernel shape s (1: Gaussian; < 1: disk, and opacity is o' / F(0))
};

mat3 rotation(vec4 q) {  // unit quaternion (w, x, y, z) -> rotation matrix (columns)
    float w = q.x, x = q.y, y = q.z, z = q.w;
    return mat3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
                2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
                2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
}

// Camera z of Gaussian g's mean (the sort key's source): each step rounded, in this order, as
// depth_order.camera_depths computes it on the CPU, so that both give the same bits (an order
// sorted on the CPU is sorted by these keys: the sliced mode's plan, layer_plan.py, relies on it).
float camera_depth(vec3 mean) {
    precise float z = ((u_R2.x * mean.x + u_R2.y * mean.y) + u_R2.z * mean.z) + u_T.z;
    return z;
}

// The footprint of Gaussian g whose mean lies at t (camera space, t.z > u_near): its centre p
// (pixels, y down), blurred 2D covariance (sxx, sxy, syy) px², det, support bound r2 on
// dᵀΣ⁻¹d, opacity o' and kernel shape; false when it is degenerate or below tau everywhere.
// (layer_plan's plan_stats.comp measures the sliced mode's boxes with it.)
bool footprint(uint g, vec3 t, out vec2 p, out vec3 cov, out float det, out float r2, out float o,
               out float shape) {
    // EWA: Sigma2 = J W Sigma W^T J^T with Sigma = M M^T, M = R(q) S, so Sigma2 = P P^T with the
    // 2x3 P = J W M. Keeping the factor makes det(Sigma2) = |p0 x p1|^2: no cancellation even for
    // needle-like or vanishing Gaussians. t.xy/t.z is clamped to 1.3x the frame's frustum (the
    // frame's, not a guard band's: a guarded image keeps every footprint).
    float iz = 1.0 / t.z;
    vec2 txy = clamp(t.xy * iz, u_frustum.xy, u_frustum.zw);
    vec3 a = u_focal.x * iz * (u_R0 - txy.x * u_R2);
    vec3 c = u_focal.y * iz * (u_R1 - txy.y * u_R2);
    mat3 M = rotation(load_quat(g));
    vec3 scale = load_scale(g);
    M[0] *= scale.x;
    M[1] *= scale.y;
    M[2] *= scale.z;
    vec3 p0 = a * M;  // row vector a^T M
    vec3 p1 = c * M;
    float sxx = dot(p0, p0);
    float syy = dot(p1, p1);
    float sxy = dot(p0, p1);
    vec3 cr = cross(p0, p1);
    float beta;
    float radius = coc(iz, u_aperture, u_inv_focus);
    if (!blur_footprint(sxx, syy, dot(cr, cr), radius, u_k, det, beta)) return false;
    shape = u_kernel == 1 ? kernel_shape(beta, det, radius, u_k) : 1.0;
    float f0 = 1.0, area = 1.0;
    if (shape < 1.0) disk_peak_and_area(shape, f0, area);
    o = normalise_opacity(load_opacity(g), beta * area, u_opacity_norm);
    if (!cut_splat(o, u_tau, u_cut, r2)) return false;
    if (shape < 1.0) {
        r2 = disk_support(o, u_tau, shape, f0);
        o /= f0;
    }
    p = u_focal * t.xy * iz + u_principal;
    cov = vec3(sxx, sxy, syy);
    return true;
}

// False when Gaussian g is culled: behind the near plane, degenerate, below tau everywhere or
// off screen.
bool project_gaussian(uint g, out Footprint f) {
    vec3 mean = load_mean(g);
    vec3 t = vec3(dot(u_R0, mean), dot(u_R1, mean), dot(u_R2, mean)) + u_T;
    if (!(t.z > u_near)) return false;
    vec2 p;
    vec3 cov;
    float det, r2, o, shape;
    if (!footprint(g, t, p, cov, det, r2, o, shape)) return false;
    vec2 ext = sqrt(r2 * cov.xz);  // the ellipse's axis-aligned half extent
    if (p.x + ext.x < 0.0 || p.x - ext.x > u_viewport.x || p.y + ext.y < 0.0 || p.y - ext.y > u_viewport.y)
        return false;

    vec3 colour = load_base(g);
#if SH_DEGREE > 0
    colour += sh_view_terms(g, normalize(mean - u_eye));
#endif
    colour = max(colour, 0.0);
    if (u_blend_linear) colour = pow(colour, vec3(2.2));
    f = Footprint(p, cov.x, cov.y, cov.z, det, r2, o, t.z, colour, shape);
    return true;
}
