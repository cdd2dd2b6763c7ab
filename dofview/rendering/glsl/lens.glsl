// The per-Gaussian lens math and the per-pixel alpha: the GLSL twin of dofview/lens.py (coc,
// blur_footprint, normalise_opacity) and of the CPU reference's compositing rule. Every GPU
// backend includes this file, so a change to the splat kernel is made here once.

const float LOW_PASS = 0.3;   // px², the reference rasteriser's screen-space low-pass filter
const float ALPHA_MAX = 0.99;
const float SUPPORT_MAX = 9.0;  // d^T Sigma^-1 d at 3 sigma: the support cut whatever tau

// CoC radius in pixels, R = A/2 |1/z - 1/d_f|, from the inverse depth.
float coc(float inv_z, float aperture, float inv_focus) {
    return 0.5 * aperture * abs(inv_z - inv_focus);
}

// Add the low-pass and the aperture Gaussian k R^2 I to the projected covariance P P^T
// (sxx, sxy, syy; det_p = |p0 x p1|^2). Both additions are isotropic, so
// det(Sigma2 + s I) = det_p + s (sxx + syy) + s^2 stays a sum of positives. Returns false for a
// degenerate footprint (cull); otherwise det is the blurred determinant and beta =
// sqrt(det Sigma2 / det Sigma2'), Sigma2 being the pinhole footprint with its low-pass.
bool blur_footprint(inout float sxx, inout float syy, float det_p, float radius, float k,
                    out float det, out float beta) {
    float add = LOW_PASS + k * radius * radius;
    float det0 = det_p + LOW_PASS * (sxx + syy) + LOW_PASS * LOW_PASS;
    det = det_p + add * (sxx + syy) + add * add;
    sxx += add;
    syy += add;
    beta = 0.0;
    if (!(det0 > 0.0) || !(det > 0.0) || isinf(det)) return false;
    beta = sqrt(det0 / det);
    return true;
}

// Opacity o' of a blurred Gaussian: mode 0 none, 1 energy o beta (Eq. 5), 2 optical depth
// 1 - (1 - o)^beta (the index in dofview.frame.OPACITY_NORMS).
float normalise_opacity(float opacity, float beta, int mode) {
    if (mode == 1) return opacity * beta;
    if (mode == 2) return 1.0 - exp(beta * log(1.0 - min(opacity, ALPHA_MAX)));
    return opacity;
}

// The tau cut of a splat of opacity o' (mode: the index in dofview.frame.CUT_MODES). False when
// it is culled; else o is the opacity drawn and r2 the support as a bound on q = d^T Sigma'^-1 d,
// never beyond 3 sigma (the tau = 0 cut).
// "drop" (0): draw o' where alpha >= tau, i.e. inside q <= 2 ln(o'/tau); a splat below tau
//   everywhere is culled. Blur spreads a splat's light thin, so this loses the light of wide, faint
//   splats: the blurred image darkens and loses its halos.
// "conserve" (1): draw o' + tau inside q <= 2 ln(1 + o'/tau), where alpha falls to exactly tau. The
//   truncated splat then carries the whole mass of the untruncated one, (o' + tau)(1 - e^(-r2/2))
//   = o' (times 2 pi sqrt(det)), and no splat is culled for being faint: it shrinks instead.
bool cut_splat(inout float o, float tau, int mode, out float r2) {
    r2 = SUPPORT_MAX;
    if (!(o > 0.0)) return false;
    if (tau > 0.0 && mode == 1) {
        r2 = min(SUPPORT_MAX, 2.0 * log(1.0 + o / tau));
        o += tau;
        return true;
    }
    if (min(o, ALPHA_MAX) < tau) return false;
    if (tau > 0.0) r2 = min(SUPPORT_MAX, 2.0 * log(o / tau));
    return true;
}

// Eigen-axes of the blurred footprint without cancellation: l1 is a sum of positives,
// l2 = det / l1, and e1 is built from the larger diagonal entry. e2 = (-e1.y, e1.x).
void footprint_axes(float sxx, float sxy, float syy, float det, out vec2 e1, out float l1, out float l2) {
    float half_diff = 0.5 * (sxx - syy);
    l1 = 0.5 * (sxx + syy) + sqrt(half_diff * half_diff + sxy * sxy);
    l2 = det / l1;
    e1 = half_diff >= 0.0 ? vec2(l1 - syy, sxy) : vec2(sxy, l1 - sxx);
    e1 = dot(e1, e1) > 0.0 ? normalize(e1) : vec2(1.0, 0.0);
}

// The disk kernel (dofview/lens.py: kernel_shape ... disk_profile, where the model is written
// down): the blurred ellipse keeps its shape and, in its whitened units, its radial profile is a
// Gaussian of std sqrt(s) spread over a disk of radius 2 sqrt(1 - s); s = 1 is the Gaussian kernel.
const float DISK_MIN_RATIO = 6.25e-4;

float erf_as(float x) {  // Abramowitz-Stegun 7.1.26, |error| < 1.5e-7
    float a = abs(x);
    float t = 1.0 / (1.0 + 0.3275911 * a);
    float y = 1.0 - t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))))
                    * exp(-a * a);
    return x < 0.0 ? -y : y;
}

// s = sigma^2 / (sigma^2 + k R^2), sigma^2 = sqrt(det Sigma2) = beta sqrt(det).
float kernel_shape(float beta, float det, float radius, float k) {
    float ratio = k * radius * radius / (beta * sqrt(det));
    return ratio < DISK_MIN_RATIO ? 1.0 : 1.0 / (1.0 + ratio);
}

// Peak F(0) and area ratio m (Gaussian over disk profile) of shape s < 1.
void disk_peak_and_area(float s, out float f0, out float m) {
    float sig = sqrt(s);
    float rad = 2.0 * sqrt(max(1.0 - s, 0.0));
    float b = rad / sig;
    f0 = erf_as(0.7071067811865476 * b);
    m = f0 / (0.5 * (rad * rad + s) * f0 + sig * rad * 0.3989422804014327 * exp(-0.5 * b * b));
}

// Support bound on q of a disk splat of peak opacity o (lens.py: disk_support).
float disk_support(float o, float tau, float s, float f0) {
    float sig = sqrt(s);
    float rad = 2.0 * sqrt(max(1.0 - s, 0.0));
    float n = SUPPORT_MAX;
    if (tau > 0.0) n = min(n, max(2.0 * log(max(o * min(0.5, 0.7978845608028654 * rad / sig) / f0, 1e-30) / tau), 0.0));
    float r = rad + sig * sqrt(n);
    return r * r;
}

// F(r) of a disk splat (lens.py: disk_profile), R = rad, inv = 1 / (sqrt(2) sigma).
float disk_spread(float r, float rad, float inv) {
    return 0.5 * (erf_as((rad + r) * inv) + erf_as((rad - r) * inv));
}

// Alpha of a splat at offset d from its centre, axis1/2 = e1/2 / sqrt(l1/2) (so dot(d, axis) is in
// std-devs of the blurred footprint), shape s: for s = 1 min(0.99, o' exp(-q/2)), 0 beyond q = 9;
// for s < 1 min(0.99, o F(sqrt q)) (o is then o'/F(0)), 0 beyond r = R + 3 sigma; 0 below tau.
float splat_alpha(vec2 d, vec2 axis1, vec2 axis2, float o, float tau, float s) {
    vec2 u = vec2(dot(d, axis1), dot(d, axis2));
    float q = dot(u, u);  // d^T Sigma'^-1 d
    float alpha;
#ifndef KERNEL_SELECT
    if (s >= 1.0) {  // the Gaussian kernel skips the erf
        if (q > SUPPORT_MAX) return 0.0;
        alpha = min(ALPHA_MAX, o * exp(-0.5 * q));
        return alpha < tau || !(alpha > 0.0) ? 0.0 : alpha;
    }
#endif
    // The compute blend loop on llvmpipe (KERNEL_SELECT) has no branch: with one, llvmpipe counts
    // more loop iterations per splat than the blend pass length allows (tests/test_compute.py:
    // 70 000 splats in one tile). It evaluates both profiles and selects.
    bool disk = s < 1.0;
    float r = sqrt(q);
    float sig = sqrt(s);
    float rad = 2.0 * sqrt(max(1.0 - s, 0.0));
    float spread = disk_spread(r, rad, 0.7071067811865476 / sig);
    float profile = disk ? spread : exp(-0.5 * q);
    float support = disk ? rad + 3.0 * sig : 3.0;  // sqrt(SUPPORT_MAX) for the Gaussian
    alpha = r > support ? 0.0 : min(ALPHA_MAX, o * profile);
    return (alpha < tau || !(alpha > 0.0)) ? 0.0 : alpha;
}
